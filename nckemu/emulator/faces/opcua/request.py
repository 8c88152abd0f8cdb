"""Who is asking: the user and rights of the OPC UA request being served.

The face's session wrapper binds them for each request (``bind``); the method handlers (users, files)
and the face's own checks read them. They live here, below the face, so that the handlers need not
import the face.
"""

from __future__ import annotations

import contextvars
from collections.abc import Awaitable, Callable
from typing import Any

from asyncua import ua

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


def with_arguments(method: Callable[..., Awaitable[Any]], count: int) -> Callable[..., Awaitable[Any]]:
    """``method`` called only with its ``count`` input arguments: a Call with fewer or more gets Part 4's
    BadArgumentsMissing or BadTooManyArguments (asyncua calls the handler anyway, and logs the
    TypeError with a traceback)."""
    async def checked(parent: Any, *arguments: Any) -> Any:
        if len(arguments) < count:
            return ua.StatusCode(ua.StatusCodes.BadArgumentsMissing)
        if len(arguments) > count:
            return ua.StatusCode(ua.StatusCodes.BadTooManyArguments)
        return await method(parent, *arguments)
    return checked
