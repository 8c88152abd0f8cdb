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

from nckemu.emulator.faces.opcua.settings import may

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


def user_access_level(access: int, realm: str | None) -> Callable[[ua.NodeId, ua.AttributeIds], ua.DataValue]:
    """A value callback for a variable's UserAccessLevel: its AccessLevel ``access`` as far as the
    request's rights allow in ``realm`` (None: anyone reads, no one writes)."""
    read_bit, write_bit = ua.AccessLevel.CurrentRead.mask, ua.AccessLevel.CurrentWrite.mask

    def level(_nodeid: ua.NodeId, _attribute: ua.AttributeIds) -> ua.DataValue:
        if realm is None:
            allowed = read_bit
        else:
            rights = _RIGHTS.get()
            allowed = (read_bit if may(rights, realm, write=False) else 0) \
                | (write_bit if may(rights, realm, write=True) else 0)
        return ua.DataValue(ua.Variant(access & allowed, ua.VariantType.Byte))
    return level


def user_executable(allowed: Callable[[str, frozenset[str]], bool]) -> Callable[[ua.NodeId, ua.AttributeIds],
                                                                                ua.DataValue]:
    """A value callback for a method's UserExecutable: ``allowed(user, rights)`` of the request."""
    def executable(_nodeid: ua.NodeId, _attribute: ua.AttributeIds) -> ua.DataValue:
        return ua.DataValue(ua.Variant(bool(allowed(_USER.get(), _RIGHTS.get())), ua.VariantType.Boolean))
    return executable
