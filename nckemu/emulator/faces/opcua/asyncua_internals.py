"""Every place where the OPC UA face relies on asyncua's internals, and why; checked when imported.

asyncua's public API covers part of what the face does: value callbacks
(``Server.set_attribute_value_callback``), the server callbacks (``Server.subscribe_server_callback``
with ``CallbackType.PreRead`` ...), the address space read and written as a mapping (``aspace[nodeid]``),
the port bound for port 0 (``BinaryServer.port``), the transport limits (``Server.limits``) and, since
asyncua 2.x, the server's bounds on its sessions (``InternalServer.min_session_timeout_ms`` ...). The
face uses those wherever they do the job. What they cannot do is listed here, each with its reason,
and nowhere else in the face touches an asyncua name that starts with ``_`` or replaces a method of an
asyncua object. asyncua 2.x (2.1) offers no public way to any of these:

- ``AddressSpace._nodes`` is replaced by a mapping that makes SINUMERIK nodes when first named
  (open-ended ids like ``R[u1,56]`` cannot be made in advance) and by a shelf shared by the faces of
  a process (asyncua opens the shelf once per server);
- ``AddressSpace._handle_to_attribute_map``: which node a monitored item's handle was on, when the item
  goes (the face stops sampling a node nobody monitors);
- ``AddressSpace.add_datachange_callback`` / ``delete_datachange_callback``: the face learns which
  nodes are monitored (asyncua's value callbacks do not feed monitored items; the face pushes). The
  server callbacks ``ItemSubscriptionCreated``/``Deleted`` do not replace them: items that go with
  their subscription or session go without either callback;
- ``AddressSpace.load_aspace_shelf``: replaced per server so that the faces share one open shelf;
- ``InternalServer.attribute_service``: replaced by the face's, which writes SINUMERIK variables
  through the model with the session user's rights (asyncua's refuses writes on access bits alone,
  and its ``PreWrite`` callback cannot refuse or redirect a write);
- ``InternalServer.create_session`` and five methods of each session (``create_session``,
  ``activate_session``, ``call``, ``create_subscription``, ``create_monitored_items``): the
  controller's limits (sessions, subscriptions, session timeout, allowed intervals) and the rights of
  the session's user on method calls and monitored items; asyncua has no server callback before
  them. asyncua 2.x's own bounds do not do the controller's: its session count is one class-wide
  count for every server of the process, its ``max_session_timeout_ms`` and ``max_subscriptions``
  are fixed when the server is made (the face reads its settings at each request) and a requested
  timeout of 0 becomes its minimum, not the controller's 60 s; the publishing intervals it keeps as
  asked;
- ``SubscriptionService.create_monitored_items``: the samples-per-second cap;
- ``MonitoredItemService._monitored_datachange``: how many items a subscription holds (the cap);
- ``BinaryServer._server``: the listening socket, for the port bound when asked for port 0 on a host
  that binds several sockets (for one socket asyncua's public ``BinaryServer.port`` says it);
- ``asyncua.server.server.BinaryServer``, ``UaProcessor._process_message``, ``_session_watchdog_task``
  (stopped when a second CreateSession ends the first session), ``_connection._incoming_parts``,
  ``OPCUAProtocol._buffer``, ``_process_one_msg``, ``BinaryServer._make_protocol``,
  ``BinaryServer._policies``: the connection guards of ``transport.py`` (hostile input answered with
  OPC UA errors; asyncua 2.x still has faults 1-5, 7, 8 and 10 of docs/asyncua-hostile-input.md); the
  three base classes here give them public names.

- ``InternalServer.time_task``: the loop that writes the server's CurrentTime sleeps a second between
  writes, and ``InternalServer.stop`` waits for it to wake: every face took a second to stop (a test
  run or a fleet stops hundreds). The face cancels it first, so that ``stop`` finds none to wait for.

- ``InternalServer.certificate`` and ``private_key``: what ``Server.load_certificate`` and
  ``load_private_key`` parse from files, read once and given to the process's next faces (parsing the
  RSA key costs ~60 ms, and asyncua parsed it twice a face start).

No longer reached for since asyncua 2.x: ``UaProcessor._publish_requests`` (2.x bounds the queued
Publish requests itself) and the session watchdog on close (2.x no longer awaits it from itself).

``check()`` runs at import and raises ``AsyncuaShapeError`` (an ``NckConfigError``) naming the asyncua
version and what moved, so that another asyncua fails at once with one line instead of misbehaving.
pyproject.toml pins the range this was tested with. asyncua 1.1 has the same shapes and still serves,
but without the two mends above (``MENDED_IN_2``, logged at debug level).
"""

from __future__ import annotations

import asyncio
import inspect
import logging
from collections.abc import Callable, MutableMapping
from typing import Any

import asyncua
import asyncua.server.server as _server_module
from asyncua.common.connection import SecureConnection
from asyncua.server.address_space import AddressSpace, AttributeService
from asyncua.server.binary_server_asyncio import BinaryServer, OPCUAProtocol
from asyncua.server.internal_server import InternalServer
from asyncua.server.internal_session import InternalSession
from asyncua.server.internal_subscription import InternalSubscription
from asyncua.server.monitored_item_service import MonitoredItemService
from asyncua.server.subscription_service import SubscriptionService
from asyncua.server.uaprocessor import UaProcessor

from nckemu.errors import NckConfigError

log = logging.getLogger("nckemu.emulator.opcua.asyncua")

TESTED = "asyncua >=2.1,<3 (the tested range, pinned in pyproject.toml)"
VERSION = getattr(asyncua, "__version__", "unknown")

# The session methods the face wraps (``override_session``).
SESSION_METHODS = ("create_session", "activate_session", "call", "create_subscription", "create_monitored_items")


class AsyncuaShapeError(NckConfigError):
    """The installed asyncua is not shaped as the OPC UA face relies on."""


def _assigns(function: Any, *names: str) -> list[str]:
    """The ``names`` that ``function``'s own code does not mention (attributes it sets or reads)."""
    mentioned = set(function.__code__.co_names)
    return [name for name in names if name not in mentioned]


def _parameters(function: Any) -> tuple[str, ...]:
    return tuple(inspect.signature(function).parameters)


def problems() -> list[str]:
    """What differs from the asyncua the face was written against (empty: nothing)."""
    found: list[str] = []

    def missing(where: str, names: list[str]) -> None:
        found.extend(f"{where} no longer uses {name}" for name in names)

    missing("AddressSpace.__init__", _assigns(AddressSpace.__init__, "_nodes", "_handle_to_attribute_map"))
    for method in ("add_datachange_callback", "delete_datachange_callback", "load_aspace_shelf",
                   "set_attribute_value_callback", "__getitem__", "get", "__contains__", "__setitem__", "keys"):
        if not callable(getattr(AddressSpace, method, None)):
            found.append(f"AddressSpace has no {method}")
    missing("InternalServer.__init__", _assigns(InternalServer.__init__, "aspace", "attribute_service",
                                                 "subscription_service", "time_task"))
    missing("InternalServer.stop", _assigns(InternalServer.stop, "time_task"))
    missing("Server.load_certificate", _assigns(_server_module.Server.load_certificate, "iserver", "certificate"))
    missing("Server.load_private_key", _assigns(_server_module.Server.load_private_key, "iserver", "private_key"))
    if _parameters(AttributeService.__init__) != ("self", "aspace") \
            or _parameters(AttributeService.write)[:3] != ("self", "params", "user"):
        found.append("AttributeService takes other arguments")
    for method in SESSION_METHODS:
        if not callable(getattr(InternalSession, method, None)):
            found.append(f"InternalSession has no {method}")
    if not callable(getattr(InternalServer, "create_session", None)):
        found.append("InternalServer has no create_session")
    missing("SubscriptionService.__init__", _assigns(SubscriptionService.__init__, "subscriptions"))
    missing("InternalSubscription.__init__", _assigns(InternalSubscription.__init__, "monitored_item_srv"))
    missing("MonitoredItemService.__init__", _assigns(MonitoredItemService.__init__, "_monitored_datachange"))
    missing("BinaryServer.start", _assigns(BinaryServer.start, "_server", "port"))
    missing("BinaryServer.__init__", _assigns(BinaryServer.__init__, "_policies", "iserver", "clients",
                                              "closing_tasks", "limits"))
    if not isinstance(getattr(_server_module, "BinaryServer", None), type) \
            or "BinaryServer" not in _server_module.Server.start.__code__.co_names:
        found.append("Server.start no longer makes asyncua.server.server.BinaryServer")
    if _parameters(UaProcessor._process_message) != ("self", "typeid", "requesthdr", "seqhdr", "body"):
        found.append("UaProcessor._process_message takes other arguments")
    missing("UaProcessor.__init__", _assigns(UaProcessor.__init__, "_session_watchdog_task",
                                             "_connection"))
    missing("SecureConnection.__init__", _assigns(SecureConnection.__init__, "_incoming_parts"))
    missing("OPCUAProtocol.__init__", _assigns(OPCUAProtocol.__init__, "_buffer", "processor"))
    if _parameters(OPCUAProtocol._process_one_msg) != ("self", "header", "buf"):
        found.append("OPCUAProtocol._process_one_msg takes other arguments")
    if _parameters(OPCUAProtocol.__init__)[1:] != ("iserver", "policies", "clients", "closing_tasks", "limits"):
        found.append("OPCUAProtocol takes other arguments")
    if _parameters(BinaryServer._make_protocol) != ("self",):
        found.append("BinaryServer._make_protocol takes arguments")
    return found


def check() -> None:
    """Raise ``AsyncuaShapeError`` when the installed asyncua differs (see ``problems``)."""
    found = problems()
    if found:
        raise AsyncuaShapeError(
            f"the OPC UA face needs {TESTED}; asyncua {VERSION} is installed and differs: {'; '.join(found)}",
            field="asyncua")


def mends_missing() -> list[str]:
    """What the face leaves to asyncua since 2.x and the installed asyncua lacks (asyncua 1.1: both)."""
    missing: list[str] = []
    if not callable(getattr(UaProcessor, "publish_request_limit", None)):
        missing.append("a bound on queued Publish requests")
    if "current_task" not in UaProcessor.close.__code__.co_names:
        missing.append("a session watchdog that does not await itself")
    return missing


check()
MENDED_IN_2 = mends_missing()
if MENDED_IN_2:  # at debug: commands that answer in one line keep it (tests of the mends skip, saying why)
    log.debug("OPC UA: asyncua %s serves the face without %s (asyncua 2.x has them; pyproject.toml asks "
                "for %s)", VERSION, " and ".join(MENDED_IN_2), TESTED.split(" (")[0])


# ---------------------------------------------------------------------- the server's own tasks
async def stop_time_updates(iserver: InternalServer) -> None:
    """Cancel the server's CurrentTime loop now rather than let ``InternalServer.stop`` wait up to a
    second for its sleep to end (the server is stopping: nobody reads its time after)."""
    task = iserver.time_task
    if task is None:
        return
    iserver.time_task = None
    task.cancel()
    await asyncio.wait([task])  # not ``await task``: a cancellation of the caller itself is not swallowed
    if not task.cancelled():
        task.exception()  # one that ended with an error before: seen, so asyncio does not log it as lost


# ---------------------------------------------------------------------- the server's certificate
def loaded_certificate(server: asyncua.Server) -> tuple[Any, Any]:
    """The certificate and private key ``Server.load_certificate``/``load_private_key`` loaded."""
    return server.iserver.certificate, server.iserver.private_key


def use_certificate(server: asyncua.Server, certificate: Any, private_key: Any) -> None:
    """What ``load_certificate`` and ``load_private_key`` do, with the two already loaded."""
    server.iserver.certificate = certificate
    server.iserver.private_key = private_key


# ---------------------------------------------------------------------- the address space
def nodes(aspace: AddressSpace) -> MutableMapping[Any, Any]:
    """The address space's own node mapping (what ``replace_nodes`` put there)."""
    return aspace._nodes  # type: ignore[no-any-return]


def replace_nodes(aspace: AddressSpace, mapping: MutableMapping[Any, Any]) -> None:
    aspace._nodes = mapping  # type: ignore[assignment]


def shelf_source(aspace: AddressSpace) -> Any:
    """The open shelf behind a shelf-backed address space (asyncua's or ``shelf.ShelfNodes``), or None."""
    return getattr(aspace._nodes, "source", None)


def node_of_handle(aspace: AddressSpace, handle: int) -> Any:
    """The node id a data-change handle was given for, or None."""
    where = aspace._handle_to_attribute_map.get(handle)
    return where[0] if where is not None else None


def intercept_datachange(aspace: AddressSpace,
                         added: Callable[[Any, Any, tuple[Any, int]], None],
                         deleting: Callable[[int], Any], deleted: Callable[[Any], None]) -> None:
    """``added(nodeid, attr, result)`` after asyncua added a data-change callback; ``deleting(handle)``
    before it removes one (its answer is handed to ``deleted`` after)."""
    add, delete = aspace.add_datachange_callback, aspace.delete_datachange_callback

    def add_datachange_callback(nodeid: Any, attr: Any, callback: Callable) -> Any:  # type: ignore[type-arg]
        result = add(nodeid, attr, callback)
        added(nodeid, attr, result)
        return result

    def delete_datachange_callback(handle: int) -> None:
        before = deleting(handle)
        delete(handle)
        deleted(before)

    aspace.add_datachange_callback = add_datachange_callback  # type: ignore[method-assign]
    aspace.delete_datachange_callback = delete_datachange_callback  # type: ignore[method-assign]


def load_shelves_with(aspace: AddressSpace, load: Callable[[Any], None]) -> None:
    """``Server.init(shelf)`` calls ``load(path)`` instead of asyncua's own shelf loader."""
    aspace.load_aspace_shelf = load  # type: ignore[method-assign]


# ---------------------------------------------------------------------- services and sessions
def replace_attribute_service(iserver: InternalServer, service: AttributeService) -> None:
    iserver.attribute_service = service


def on_new_session(iserver: InternalServer, made: Callable[[InternalSession], None]) -> None:
    """``made(session)`` for every session the server creates, before it is used."""
    create = iserver.create_session

    def create_session(*args: Any, **kwargs: Any) -> Any:
        session = create(*args, **kwargs)
        made(session)
        return session

    iserver.create_session = create_session  # type: ignore[method-assign]


def override_session(session: InternalSession, method: str, wrap: Callable[[Any], Any]) -> None:
    """Replace ``session.<method>`` (one of ``SESSION_METHODS``) by ``wrap(asyncua's method)``."""
    assert method in SESSION_METHODS, method
    setattr(session, method, wrap(getattr(session, method)))


def override_monitored_item_creation(service: SubscriptionService, wrap: Callable[[Any], Any]) -> None:
    service.create_monitored_items = wrap(service.create_monitored_items)  # type: ignore[method-assign]


def datachange_items(subscription: InternalSubscription) -> int:
    """How many data-change monitored items a subscription holds."""
    return len(subscription.monitored_item_srv._monitored_datachange)


def bound_port(server: asyncua.Server) -> int:
    """The port bound when asked for port 0: asyncua's socket server notes it (``BinaryServer.port``)
    when it bound one socket; a host name that binds several (IPv4 and IPv6) leaves it 0."""
    port = int(server.bserver.port)  # type: ignore[union-attr]
    if port:
        return port
    return int(server.bserver._server.sockets[0].getsockname()[1])  # type: ignore[union-attr]


# ---------------------------------------------------------------------- connections (transport.py)
class Processor(UaProcessor):
    """asyncua's request processor with its per-request step under a public name (``serve``)."""

    async def _process_message(self, typeid: Any, requesthdr: Any, seqhdr: Any, body: Any) -> Any:
        return await self.serve(typeid, requesthdr, seqhdr, body)

    async def serve(self, typeid: Any, requesthdr: Any, seqhdr: Any, body: Any) -> Any:
        """asyncua's handling of one decoded request."""
        return await UaProcessor._process_message(self, typeid, requesthdr, seqhdr, body)

    def take_session_watchdog(self) -> Any:
        """The channel's session watchdog task (None when there is none), no longer the processor's."""
        watchdog, self._session_watchdog_task = self._session_watchdog_task, None
        return watchdog

    @property
    def chunks_waiting(self) -> bool:
        """Chunks of a message have come and its last has not."""
        return bool(self._connection._incoming_parts)


class Protocol(OPCUAProtocol):
    """asyncua's connection protocol with its buffer and per-message step under public names."""

    @property
    def buffered(self) -> bytes:
        """Bytes received that do not yet make a whole message."""
        return self._buffer  # type: ignore[no-any-return]

    @buffered.setter
    def buffered(self, data: bytes) -> None:
        self._buffer = data

    async def _process_one_msg(self, header: Any, buf: Any) -> bool:
        return await self.process_one_message(header, buf)

    async def process_one_message(self, header: Any, buf: Any) -> bool:
        """asyncua's handling of one whole message; False: the connection is closed, read no more
        (asyncua 2.x stops its message loop on False; 1.1 answered None and read on)."""
        return await OPCUAProtocol._process_one_msg(self, header, buf) is not False


class SocketServer(BinaryServer):
    """asyncua's socket server; ``make_protocol`` chooses each connection's protocol."""

    def _make_protocol(self) -> OPCUAProtocol:
        return self.make_protocol()

    @property
    def security_policies(self) -> Any:
        return self._policies

    def make_protocol(self) -> OPCUAProtocol:
        """What asyncua itself makes."""
        return BinaryServer._make_protocol(self)


def serve_connections_with(server_class: type[BinaryServer]) -> None:
    """asyncua's ``Server.start`` makes its socket server by this module-level name."""
    _server_module.BinaryServer = server_class  # type: ignore[misc]
