"""Who is asking: the user and rights of the OPC UA request being served.

The face's session wrapper binds them for each request (``bind``); the method handlers (users, files)
and the face's own checks read them. They live here, below the face, so that the handlers need not
import the face.
"""

from __future__ import annotations

import contextvars

_RIGHTS: contextvars.ContextVar[frozenset[str]] = contextvars.ContextVar("nckemu_opcua_rights", default=frozenset())
_USER: contextvars.ContextVar[str] = contextvars.ContextVar("nckemu_opcua_user", default="")


def bind(user: str | None, rights: frozenset[str]) -> None:
    """The request now served is ``user``'s (None: anonymous) with ``rights``."""
    _RIGHTS.set(rights)
    _USER.set(user or "")


def user() -> str:
    """The request's user name, "" when anonymous."""
    return _USER.get()


def rights() -> frozenset[str]:
    """The request's rights (the controller's realms: SinuReadAll, AlarmRead, ...)."""
    return _RIGHTS.get()
