"""Settings of the OPC UA face and the users and rights of a machine file's ``[opcua]`` table.

```toml
[opcua]
anonymous = ["SinuReadAll"]          # rights of an anonymous session ([] as a new controller)
max_sessions = 10                    # 840D sl: 10 (828D: 5)
max_subscriptions = 10
max_samples_per_s = 1000             # 840D sl: 1000 (828D: 500); items x 1000 / interval_ms, summed
[opcua.users.nckemu]
password = "SUNRISE"
rights = ["SinuReadAll", "SinuWriteAll"]   # or realms: StateRead, SeaWrite, PlcRead, ...
```
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from nckemu.errors import NckConfigError

REALMS = ("State", "Frame", "Sea", "Tea", "Tool", "Drive", "Gud", "FS", "Plc")
RIGHTS = frozenset({f"{realm}{what}" for realm in REALMS for what in ("Read", "Write")}
                   | {"SinuReadAll", "SinuWriteAll", "AlarmRead", "RandomRead", "RandomWrite"})
# The controller's allowed sampling and publishing intervals (840D sl manual).
ALLOWED_INTERVALS_MS = (100, 250, 500, 1000, 2500, 5000)
_KEYS = frozenset({"anonymous", "users", "max_sessions", "max_subscriptions", "sample_interval_ms",
                   "namespace_uri", "max_samples_per_s"})


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
    # How often monitored variables are read from the model and changes pushed to subscriptions: the
    # controller's smallest publishing interval, so a change is seen within two of them.
    sample_interval_ms: int = 100
    anonymous: frozenset[str] = frozenset({"SinuReadAll"})
    users: dict[str, User] = field(default_factory=dict)

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
        for key in ("max_sessions", "max_subscriptions", "sample_interval_ms", "max_samples_per_s"):
            if key in table:
                value = table[key]
                if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 100_000:
                    raise NckConfigError("expected a whole number 1..100000", path=source, field=f"opcua.{key}")
                limits[key] = value
        uri = table.get("namespace_uri", cls.namespace_uri)
        if not isinstance(uri, str) or not uri:
            raise NckConfigError("expected a namespace URI", path=source, field="opcua.namespace_uri")
        anonymous = _rights(table.get("anonymous", sorted(cls.anonymous)), source, "opcua.anonymous")
        return cls(namespace_uri=uri, anonymous=anonymous, users=users, **limits)


def _rights(value: object, source: str, where: str) -> frozenset[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise NckConfigError("expected a list of rights such as [\"SinuReadAll\"]", path=source, field=where)
    unknown = sorted(set(value) - RIGHTS)
    if unknown:
        raise NckConfigError(f"unknown right {unknown[0]!r} (known: realms {', '.join(REALMS)} + Read/Write, "
                             f"SinuReadAll, SinuWriteAll)", path=source, field=where)
    return frozenset(value)
