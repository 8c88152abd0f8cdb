"""One validation path for a machine file: what ``serve`` refuses, ``machine show`` refuses, with the
file, line and field.

``serve`` builds the machine (``Emulator``) and, with ``--opcua``, the OPC UA face's settings from the
file's ``[opcua]`` table; both checks run here for both commands. The OPC UA settings name the field
but not the line (they get the table, not the text): the line is found here in the file's text.
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path
from typing import Any

from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.machine.core import Emulator
from nckemu.emulator.machine.machine_file import Machine
from nckemu.errors import NckConfigError

BUILT_IN = "default.toml (built in)"


def machine_text(machine: Machine) -> str | None:
    """The text the machine was read from (None where the file is gone)."""
    try:
        if machine.source == BUILT_IN:
            return resources.files("nckemu.emulator.machine").joinpath("machines/default.toml").read_text("utf-8")
        return Path(machine.source).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None


def field_line(text: str, field: str) -> int | None:
    """The line of a dotted field (``opcua.security``, ``opcua.users.alice.rights``) in TOML text: the
    key under the longest table header the field starts with, else that header's line."""
    parts = field.split(".")
    lines = text.splitlines()
    for depth in range(len(parts) - 1, 0, -1):
        header = re.compile(r"^\s*\[\s*" + r"\s*\.\s*".join(re.escape(p) for p in parts[:depth]) + r"\s*\]")
        start = next((number for number, line in enumerate(lines) if header.match(line)), None)
        if start is None:
            continue
        key = parts[depth] if depth < len(parts) else None
        if key is not None:
            pattern = re.compile(r"^\s*" + re.escape(key) + r"\s*=")
            for number in range(start + 1, len(lines)):
                if lines[number].lstrip().startswith("["):
                    break
                if pattern.match(lines[number]):
                    return number + 1
        return start + 1
    return None


def _with_line(exc: NckConfigError, machine: Machine) -> NckConfigError:
    if exc.line is not None or exc.field is None:
        return exc
    text = machine_text(machine)
    line = field_line(text, exc.field) if text is not None else None
    if line is None:
        return exc
    where = ", ".join(part for part in (exc.path, f"field {exc.field!r}") if part)
    message = str(exc).removeprefix(f"{where}: ")
    return NckConfigError(message, path=exc.path, line=line, field=exc.field)


def opcua_settings(machine: Machine) -> OpcUaSettings:
    """The OPC UA face's settings from the machine's ``[opcua]`` table, as the face reads them; an error
    names the file, the line and the field."""
    try:
        return OpcUaSettings.from_machine(machine.opcua, machine.source)
    except NckConfigError as exc:
        raise _with_line(exc, machine) from None


def checked_machine(path: str | None) -> tuple[Emulator, OpcUaSettings]:
    """The machine as ``serve`` builds it, and its OPC UA settings: everything ``serve`` checks."""
    emulator = Emulator(path)
    return emulator, opcua_settings(emulator.machine)


def opcua_document(settings: OpcUaSettings) -> dict[str, Any]:
    """The OPC UA settings as plain data, users with their rights and without their passwords."""
    return {
        "security": list(settings.security), "allow_anonymous": settings.allow_anonymous,
        "anonymous_rights": sorted(settings.anonymous),
        "users": {name: {"rights": sorted(user.rights), "admin": name == settings.admin}
                  for name, user in settings.users.items()},
        "admin": settings.admin, "max_sessions": settings.max_sessions,
        "max_subscriptions": settings.max_subscriptions, "max_samples_per_s": settings.max_samples_per_s,
        "session_timeout_s": settings.session_timeout_s, "sample_interval_ms": settings.sample_interval_ms,
        "namespace_uri": settings.namespace_uri, "models": list(settings.models),
        "identification": dict(settings.identification),
        "stacklight": [{"color": color, "plc": plc} for color, plc in settings.stacklight],
        "accept_certificates": settings.accept_certificates,
        "trusted_certificates": settings.trusted_certificates, "certificate": settings.certificate,
    }
