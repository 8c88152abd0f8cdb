"""Settings of the OPC UA face and the users and rights of a machine file's ``[opcua]`` table.

```toml
[opcua]
anonymous = ["SinuReadAll"]          # rights of an anonymous session ([] as a new controller)
max_sessions = 10                    # 840D sl: 10 (828D: 5)
max_subscriptions = 10
max_samples_per_s = 1000             # 840D sl: 1000 (828D: 500); items x 1000 / interval_ms, summed
session_timeout_s = 60               # an idle session is closed; longer requests are revised down
security = ["None", "Basic256Sha256_SignAndEncrypt", ...]   # endpoints offered (default: all, see SECURITY)
allow_anonymous = true               # false: no anonymous logins at all (the endpoints do not offer them)
accept_certificates = true           # false: only client certificates in trusted_certificates (a directory)
# certificate = "server.der" and private_key = "server.pem": the server's own (default: made at first start)
admin = "nckemu"                     # the user who may call AddUser, DeleteUser, GiveUserAccess ...
models = ["MachineTool", "CNC"]      # the umati and CNC companion models (docs/opcua.md); [] for none
# nodesets = "DIR"                   # where their NodeSet files are (default: make nodesets' install)
stacklight = [{ color = "Red", plc = "Q0.0" }]   # umati Monitoring/Stacklight, a lamp per PLC bit
[opcua.identification]               # umati Identification: manufacturer, model, serial_number, ...
[opcua.users.nckemu]
password = "SUNRISE"
rights = ["SinuReadAll", "SinuWriteAll"]   # or realms: StateRead, SeaWrite, PlcRead, ...
```
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nckemu.errors import NckConfigError

_PLC_BIT = re.compile(r"^(?:[IQM]\d{1,5}\.[0-7]|DB\d{1,5}\.DBX\d{1,5}\.[0-7])$")
REALMS = ("State", "Frame", "Sea", "Tea", "Tool", "Drive", "Gud", "FS", "Plc")
RIGHTS = frozenset({f"{realm}{what}" for realm in REALMS for what in ("Read", "Write")}
                   | {"SinuReadAll", "SinuWriteAll", "AlarmRead", "RandomRead", "RandomWrite"})
# The controller's allowed sampling and publishing intervals (840D sl manual).
ALLOWED_INTERVALS_MS = (100, 250, 500, 1000, 2500, 5000)
_KEYS = frozenset({"anonymous", "users", "max_sessions", "max_subscriptions", "sample_interval_ms",
                   "namespace_uri", "max_samples_per_s", "security", "allow_anonymous", "accept_certificates",
                   "trusted_certificates", "certificate", "private_key", "admin", "session_timeout_s",
                   "models", "identification", "nodesets", "stacklight"})
# The companion models the face can serve (models.py): OPC 40501-1 MachineTool (umati), OPC 40502 CNC.
MODELS = ("MachineTool", "CNC")
# IA's SignalColor names (a stack light's lamps, [[opcua.stacklight]]).
SIGNAL_COLORS = ("Off", "Red", "Green", "Blue", "Yellow", "Purple", "Cyan", "White")
IDENTIFICATION_KEYS = frozenset({"manufacturer", "model", "serial_number", "software_revision", "location",
                                 "year_of_construction", "product_instance_uri", "product_code"})
# The controller offers "encryption None, 128 bit or 256 bit": None; 128 bit as the AES-128 policy; 256
# bit as Basic256Sha256 (the common one) and the AES-256 policy (docs/assumptions.md). Sign alone too.
SECURITY = ("None", "Basic256Sha256_Sign", "Basic256Sha256_SignAndEncrypt", "Aes128Sha256RsaOaep_Sign",
            "Aes128Sha256RsaOaep_SignAndEncrypt", "Aes256Sha256RsaPss_Sign", "Aes256Sha256RsaPss_SignAndEncrypt")


@dataclass(frozen=True)
class User:
    name: str
    password: str
    rights: frozenset[str]


def may(rights: frozenset[str], realm: str, write: bool) -> bool:
    """Whether ``rights`` allow reading (or writing) a variable of ``realm``."""
    if write:
        return "SinuWriteAll" in rights or f"{realm}Write" in rights
    return bool({"SinuReadAll", "SinuWriteAll", f"{realm}Read", f"{realm}Write"} & rights)


@dataclass(frozen=True)
class OpcUaSettings:
    namespace_uri: str = "SinumerikVarProvider"
    max_sessions: int = 10
    max_subscriptions: int = 10
    # The controller's cap on samples per second over all monitored items (each costs 1000 / its
    # interval in ms). What the controller does past it is not in our sources: the face refuses the
    # item that would exceed it with BadTooManyMonitoredItems (docs/assumptions.md).
    max_samples_per_s: int = 1000
    # A session idle this long is closed (840D sl: 60 s); a longer request is revised down to it.
    session_timeout_s: int = 60
    # How often monitored variables are read from the model and changes pushed to subscriptions: the
    # controller's smallest publishing interval, so a change is seen within two of them.
    sample_interval_ms: int = 100
    anonymous: frozenset[str] = frozenset({"SinuReadAll"})
    users: dict[str, User] = field(default_factory=dict)
    # The user who manages users (AddUser, GiveUserAccess ...): set up at commissioning on the
    # controller; ours by default (docs/assumptions.md).
    admin: str = "nckemu"
    security: tuple[str, ...] = SECURITY
    allow_anonymous: bool = True
    accept_certificates: bool = True   # the controller's "accept certificates automatically"
    trusted_certificates: str | None = None   # a directory of trusted client certificates (DER or PEM)
    certificate: str | None = None     # the server's certificate and key; None: made at first start
    private_key: str | None = None
    # The companion models served beside the SINUMERIK namespace (all by default), the machine's
    # identification they show ([opcua.identification]) and a directory holding their NodeSet files.
    models: tuple[str, ...] = MODELS
    identification: dict[str, Any] = field(default_factory=dict)
    nodesets: str | None = None
    # A stack light's lamps, top first: (colour, the PLC bit that lights it, e.g. "Q0.0").
    stacklight: tuple[tuple[str, str], ...] = ()

    @classmethod
    def from_machine(cls, table: dict[str, Any], source: str = "machine") -> OpcUaSettings:
        """From a machine file's ``[opcua]`` table (an error names the file and the field)."""
        unknown = sorted(set(table) - _KEYS)
        if unknown:
            raise NckConfigError(f"unknown key (known: {', '.join(sorted(_KEYS))})", path=source,
                                 field=f"opcua.{unknown[0]}")
        users: dict[str, User] = {}
        raw_users = table.get("users", {})
        if not isinstance(raw_users, dict):
            raise NckConfigError("expected [opcua.users.NAME] tables", path=source, field="opcua.users")
        for name, entry in raw_users.items():
            where = f"opcua.users.{name}"
            if not isinstance(entry, dict) or not isinstance(entry.get("password"), str):
                raise NckConfigError("expected password = \"...\" and rights = [...]", path=source, field=where)
            users[name] = User(name, entry["password"], _rights(entry.get("rights", []), source, f"{where}.rights"))
        limits = {}
        for key in ("max_sessions", "max_subscriptions", "sample_interval_ms", "max_samples_per_s", "session_timeout_s"):
            if key in table:
                value = table[key]
                if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 100_000:
                    raise NckConfigError("expected a whole number 1..100000", path=source, field=f"opcua.{key}")
                limits[key] = value
        uri = table.get("namespace_uri", cls.namespace_uri)
        if not isinstance(uri, str) or not uri:
            raise NckConfigError("expected a namespace URI", path=source, field="opcua.namespace_uri")
        anonymous = _rights(table.get("anonymous", sorted(cls.anonymous)), source, "opcua.anonymous")
        if any(right.endswith("Write") for right in anonymous):  # the controller's rule (manual)
            raise NckConfigError("anonymous sessions never write: give write rights to a user",
                                 path=source, field="opcua.anonymous")
        admin = table.get("admin", cls.admin)
        if not isinstance(admin, str) or not admin:
            raise NckConfigError("expected the name of the user who manages users", path=source, field="opcua.admin")
        limits["admin"] = admin
        return cls(namespace_uri=uri, anonymous=anonymous, users=users, **limits,
                   **_security(table, source), **_models(table, source))


def _rights(value: object, source: str, where: str) -> frozenset[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise NckConfigError("expected a list of rights such as [\"SinuReadAll\"]", path=source, field=where)
    unknown = sorted(set(value) - RIGHTS)
    if unknown:
        raise NckConfigError(f"unknown right {unknown[0]!r} (known: realms {', '.join(REALMS)} + Read/Write, "
                             f"SinuReadAll, SinuWriteAll)", path=source, field=where)
    return frozenset(value)


def _security(table: dict[str, Any], source: str) -> dict[str, Any]:
    """The security keys of an ``[opcua]`` table, checked; file paths relative to the machine file."""
    found: dict[str, Any] = {}
    if "security" in table:
        policies = table["security"]
        if not isinstance(policies, list) or not policies or not all(isinstance(p, str) for p in policies):
            raise NckConfigError(f"expected a list of security policies from {', '.join(SECURITY)}", path=source,
                                 field="opcua.security")
        unknown = sorted(set(policies) - set(SECURITY))
        if unknown:
            raise NckConfigError(f"unknown security policy {unknown[0]!r} (known: {', '.join(SECURITY)})",
                                 path=source, field="opcua.security")
        found["security"] = tuple(dict.fromkeys(policies))
    for key in ("allow_anonymous", "accept_certificates"):
        if key in table:
            if not isinstance(table[key], bool):
                raise NckConfigError("expected true or false", path=source, field=f"opcua.{key}")
            found[key] = table[key]
    base = Path(source).parent if source and Path(source).suffix == ".toml" else Path(".")
    for key in ("trusted_certificates", "certificate", "private_key"):
        if key in table:
            value = table[key]
            if not isinstance(value, str) or not value.strip():
                raise NckConfigError("expected a path", path=source, field=f"opcua.{key}")
            path = Path(value) if Path(value).is_absolute() else base / value
            if not (path.is_dir() if key == "trusted_certificates" else path.is_file()):
                raise NckConfigError(f"{value}: no such {'directory' if key == 'trusted_certificates' else 'file'}",
                                     path=source, field=f"opcua.{key}")
            found[key] = str(path)
    if ("certificate" in found) != ("private_key" in found):
        raise NckConfigError("certificate and private_key go together", path=source,
                             field="opcua.certificate" if "certificate" in found else "opcua.private_key")
    if found.get("accept_certificates") is False and "trusted_certificates" not in found:
        raise NckConfigError("accept_certificates = false needs trusted_certificates (a directory of client "
                             "certificates)", path=source, field="opcua.accept_certificates")
    return found


def _models(table: dict[str, Any], source: str) -> dict[str, Any]:
    """``models = ["MachineTool", "CNC"]``, ``nodesets = "DIR"`` and ``[opcua.identification]``, checked."""
    found: dict[str, Any] = {}
    if "models" in table:
        models = table["models"]
        if not isinstance(models, list) or not all(isinstance(m, str) for m in models) \
                or sorted(set(models) - set(MODELS)):
            raise NckConfigError(f"expected a list of models from {', '.join(MODELS)} ([] for none)", path=source,
                                 field="opcua.models")
        found["models"] = tuple(m for m in MODELS if m in models)
    if "nodesets" in table:
        value = table["nodesets"]
        if not isinstance(value, str) or not value.strip():
            raise NckConfigError("expected a directory holding the NodeSet files", path=source, field="opcua.nodesets")
        base = Path(source).parent if source and Path(source).suffix == ".toml" else Path(".")
        found["nodesets"] = str(Path(value) if Path(value).is_absolute() else base / value)
    if "identification" in table:
        ident = table["identification"]
        if not isinstance(ident, dict):
            raise NckConfigError("expected a table", path=source, field="opcua.identification")
        for key, value in ident.items():
            where = f"opcua.identification.{key}"
            if key not in IDENTIFICATION_KEYS:
                raise NckConfigError(f"unknown key (known: {', '.join(sorted(IDENTIFICATION_KEYS))})", path=source,
                                     field=where)
            if key == "year_of_construction":
                if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 65535:
                    raise NckConfigError("expected a year such as 2024", path=source, field=where)
            elif not isinstance(value, str):
                raise NckConfigError("expected a string", path=source, field=where)
        found["identification"] = dict(ident)
    if "stacklight" in table:
        lamps = table["stacklight"]
        if not isinstance(lamps, list):
            raise NckConfigError("expected [[opcua.stacklight]] tables with color and plc", path=source,
                                 field="opcua.stacklight")
        parsed = []
        for number, lamp in enumerate(lamps, start=1):
            where = f"opcua.stacklight[{number}]"
            if not isinstance(lamp, dict) or set(lamp) != {"color", "plc"} or lamp["color"] not in SIGNAL_COLORS \
                    or not isinstance(lamp["plc"], str) or not _PLC_BIT.match(lamp["plc"]):
                raise NckConfigError(f"expected color = one of {', '.join(SIGNAL_COLORS)} and plc = a PLC bit such "
                                     f"as \"Q0.0\", \"M5.1\" or \"DB130.DBX0.0\"", path=source, field=where)
            parsed.append((lamp["color"], lamp["plc"]))
        found["stacklight"] = tuple(parsed)
    return found
