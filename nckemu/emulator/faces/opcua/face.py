"""The OPC UA face: an asyncua server in SINUMERIK naming over one ``Emulator`` (the S7 face's model).

``face = OpcUaFace(emulator, "127.0.0.1", 4840); await face.start(); ...; await face.stop()`` on the
running event loop; any number of faces may share a loop (a fleet).

How it sits on asyncua (its address space is a plain dict ``NodeId -> NodeData``):
- Browsing: folders under ``Objects/Sinumerik`` hold one variable per catalogue row, first unit and
  line only, as the controller shows them.
- Any other id in the namespace (``R[u1,56]``, ``/Plc/DB2.DBD0:REAL[10]``) is parsed by the catalogue
  and its node made when a service first asks for it (``_LazyNodes``), so open-ended ids need no nodes
  made in advance. Values are read from the model on every read (a value callback).
- Writes go through ``_SinumerikAttributes.write`` with the session's user: rights, limits, then the
  model, as an S7 write would.
- Subscriptions: asyncua's value callbacks do not feed monitored items, so a sampler reads only the
  monitored nodes every ``sample_interval_ms`` and pushes changed values to their callbacks.
"""

from __future__ import annotations

import asyncio
import bisect
import dataclasses
import logging
import threading
import time
from collections.abc import Callable, MutableMapping
from datetime import UTC, datetime
from typing import Any

from asyncua import Server, ua
from asyncua.common.utils import ServiceError
from asyncua.crypto.permission_rules import PermissionRuleset, UserRole
from asyncua.crypto.permission_rules import User as UaUser
from asyncua.server.address_space import AttributeService, AttributeValue, NodeData

from nckemu.catalogue.node_ids import NcNodeName, NodeName, PlcNodeName, node_paths, parse_node_id
from nckemu.emulator.faces.opcua import files, request, security, selection, transport, users
from nckemu.emulator.faces.opcua import shelf as address_cache
from nckemu.emulator.faces.opcua.alarms import ALARM_RIGHTS, AlarmEvents
from nckemu.emulator.faces.opcua.models import Models
from nckemu.emulator.faces.opcua.settings import ALLOWED_INTERVALS_MS, OpcUaSettings, may
from nckemu.emulator.faces.opcua.users import STATE_KEY as USERS_STATE
from nckemu.emulator.faces.opcua.users import UserRegistry
from nckemu.emulator.faces.opcua.values import (
    PLC_AREAS,
    UaStatus,
    raw_reader,
    read_value,
    variant_from_raw,
    variant_type,
    write_value,
)
from nckemu.emulator.machine.core import Emulator
from nckemu.errors import NckNodeIdError
from nckemu.protocol.addresses import S7Area

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.opcua.face")

_ACCESS_RW = ua.AccessLevel.CurrentRead.mask | ua.AccessLevel.CurrentWrite.mask


def _status(name: str) -> ua.DataValue:
    return ua.DataValue(StatusCode_=ua.StatusCode(getattr(ua.StatusCodes, name)))


class _RealmRules(PermissionRuleset):
    """asyncua's service-level rules let everything through: the realm rights decide per variable and
    method (asyncua's default refuses e.g. ModifySubscription to a non-admin user)."""

    def check_validity(self, user: Any, action_type: Any, body: Any) -> bool:
        return True


class _UserManager:
    """The face's users (``UserRegistry``: the machine file's, as the methods changed them); an unknown
    user or a wrong password is refused at activation, and anonymous where it is switched off."""

    def __init__(self, face: OpcUaFace) -> None:
        self.face = face

    def get_user(self, iserver: Any, username: str | None = None, password: str | None = None,
                 certificate: Any = None) -> UaUser | None:
        if username is None and password is None:  # an anonymous token (a user name token needs a name)
            if not self.face.settings.allow_anonymous:
                return None
            return UaUser(role=UserRole.User, name=None)  # asyncua refuses reads to its Anonymous role
        if not username or not self.face.users.login(username, password):
            return None
        return UaUser(role=UserRole.User, name=username)


class OpcUaFace:
    """One machine's OPC UA server; ``start()``/``stop()`` on the running loop."""

    def __init__(self, emulator: Emulator, host: str = "127.0.0.1", port: int = 4840,
                 settings: OpcUaSettings | None = None) -> None:
        self.emulator = emulator
        self.host = host
        self.port = port
        self.settings = settings or OpcUaSettings.from_machine(emulator.machine.opcua, emulator.machine.source)
        quiet = logging.getLogger("asyncua")
        if quiet.level == logging.NOTSET:  # its INFO lines (a thousand at init) would drown serve's own
            quiet.setLevel(logging.WARNING)
        self.users = UserRegistry(self.settings, changed=emulator.saves.request)  # methods await the save
        self.users.restore(emulator.restored_face_state.get(USERS_STATE))
        emulator.face_state[USERS_STATE] = self.users.snapshot
        self.server = Server(user_manager=_UserManager(self))
        self.namespace = 2
        self._names: dict[str, NodeName] = {}
        self._monitored: dict[ua.NodeId, _Monitored] = {}
        self._plc_index: _PlcIndex | None = None  # rebuilt after the monitored set changed
        self._pending: list[tuple[_Monitored, object]] = []  # captured at the write, pushed in order
        self._push_scheduled = False
        self._pusher: asyncio.Task[None] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_thread = 0
        self._sampler: asyncio.Task[None] | None = None
        self._sessions: list[Any] = []
        self.updates_pushed = 0
        self.alarm_events = AlarmEvents(self)
        self.models = Models(self)  # the umati and CNC companion models (models.py)

    @property
    def specs(self) -> tuple[Any, ...]:
        return tuple(self.emulator.nck.store.specs)

    def rights_of(self, user: str | None) -> frozenset[str]:
        if not user:
            return self.settings.anonymous
        return self.users.rights_of(user) or frozenset()

    # ------------------------------------------------------------------ start / stop
    async def start(self) -> OpcUaFace:
        await self._init_server()
        server = self.server
        server.set_endpoint(f"opc.tcp://{self.host}:{self.port}/")
        server.set_server_name(f"nckemu {self.emulator.machine.name}")
        await security.apply(server, self.emulator, self.settings, _RealmRules())
        self.namespace = await server.register_namespace(self.settings.namespace_uri)
        iserver = server.iserver
        iserver.aspace._nodes = _LazyNodes(iserver.aspace._nodes, self)
        iserver.attribute_service = _SinumerikAttributes(iserver.aspace, self)
        self._wrap_datachange(iserver.aspace)
        self._wrap_sessions(iserver)
        self._cap_samples(iserver.subscription_service)
        await self._build_browse_tree()
        await self.models.start(server)
        methods = await files.add_methods(self, server)
        await users.add_methods(self, server, methods, self.users)
        await selection.add_methods(self, server, methods)
        await self.alarm_events.start(server)
        transport.install(server)  # hostile input answered with OPC UA errors, half-open connections closed
        # A port in use reaches the caller as OSError (serve says so in one line); asyncua would also
        # log it with a traceback.
        starting = logging.getLogger("asyncua.server.server")
        level = starting.level
        starting.setLevel(logging.CRITICAL)
        try:
            await server.start()
        finally:
            starting.setLevel(level)
        if self.port == 0:
            self.port = self.bound_port()
        self._listen()
        self._sampler = asyncio.get_running_loop().create_task(self._sample_forever())
        log.info("OPC UA face on opc.tcp://%s:%d/ (namespace %s = ns=%d)", self.host, self.port,
                 self.settings.namespace_uri, self.namespace)
        return self

    async def _init_server(self) -> None:
        """asyncua's standard address space from the shared shelf (built by the first face to start), with
        the companion models when they are on (their own shelf, ``models.py``)."""
        shelf = await self.models.shelf() or address_cache.ready_shelf()
        self.server.iserver.bind_condition_methods = True  # ConditionRefresh (alarm events), off by default
        if shelf is not None:
            address_cache.share(self.server)
            try:
                await self.server.init(shelf)
                await self.models.after_init(self.server)
                return
            except Exception as exc:  # a damaged cache costs the time to build it again, nothing else
                log.warning("OPC UA: the address-space cache %s did not load (%s); building it again",
                            shelf.parent, exc)
                address_cache.discard(shelf)
                self.models.dropped()
                self.server = Server(user_manager=_UserManager(self))
                self.server.iserver.bind_condition_methods = True
        building = address_cache.new_shelf()
        await self.server.init(building)
        if building is not None:
            address_cache.publish(building)

    def bound_port(self) -> int:
        sockets = self.server.bserver._server.sockets  # type: ignore[union-attr]
        return int(sockets[0].getsockname()[1])

    @property
    def url(self) -> str:
        return f"opc.tcp://{self.host}:{self.port}/"

    # what `nckemu serve` reads of a face (the Face protocol in emulator/faces)
    what = "OPC UA"

    @property
    def ready(self) -> dict[str, Any]:
        return {"opcua": self.url}

    @property
    def ready_line(self) -> str:
        return (f"OPC UA: {self.url} (namespace {self.settings.namespace_uri}), e.g. "
                f"uaread -u {self.url} -n 'ns={self.namespace};s=/Channel/State/progStatus'")

    async def stop(self) -> None:
        self._unlisten()
        await self.alarm_events.stop()
        await self.models.stop()
        if self._pusher is not None:
            self._pusher.cancel()
        if self._sampler is not None:
            self._sampler.cancel()
            try:
                await self._sampler
            except asyncio.CancelledError:
                pass
            self._sampler = None
        await self.server.stop()

    # ------------------------------------------------------------------ address space
    def node_name(self, identifier: str) -> NodeName:
        """The parsed name of a node id string (cached; raises the catalogue's typed errors)."""
        name = self._names.get(identifier)
        if name is None:
            name = parse_node_id(identifier, self.specs)
            if len(self._names) < 100_000:
                self._names[identifier] = name
        return name

    def make_node(self, nodeid: ua.NodeId, name: NodeName) -> NodeData:
        """A variable node for a parsed id, its value read from the model on every read."""
        node = NodeData(nodeid)
        text = str(nodeid.Identifier)
        kind = variant_type(name)
        writable = not (isinstance(name, NcNodeName) and name.spec.read_only)
        access = _ACCESS_RW if writable else ua.AccessLevel.CurrentRead.mask
        attributes = {
            ua.AttributeIds.NodeId: ua.Variant(nodeid, ua.VariantType.NodeId),
            ua.AttributeIds.NodeClass: ua.Variant(ua.NodeClass.Variable, ua.VariantType.Int32),
            ua.AttributeIds.BrowseName: ua.Variant(ua.QualifiedName(text.rsplit("/", 1)[-1], nodeid.NamespaceIndex)),
            ua.AttributeIds.DisplayName: ua.Variant(ua.LocalizedText(text.rsplit("/", 1)[-1])),
            ua.AttributeIds.Description: ua.Variant(ua.LocalizedText(
                name.spec.description if isinstance(name, NcNodeName) else text)),
            ua.AttributeIds.WriteMask: ua.Variant(0, ua.VariantType.UInt32),
            ua.AttributeIds.UserWriteMask: ua.Variant(0, ua.VariantType.UInt32),
            ua.AttributeIds.DataType: ua.Variant(ua.NodeId(kind.value), ua.VariantType.NodeId),
            ua.AttributeIds.ValueRank: ua.Variant(1 if name.array else -1, ua.VariantType.Int32),
            ua.AttributeIds.ArrayDimensions: ua.Variant([name.count] if name.array else [], ua.VariantType.UInt32),
            ua.AttributeIds.AccessLevel: ua.Variant(access, ua.VariantType.Byte),
            ua.AttributeIds.UserAccessLevel: ua.Variant(access, ua.VariantType.Byte),
            ua.AttributeIds.MinimumSamplingInterval: ua.Variant(float(ALLOWED_INTERVALS_MS[0]), ua.VariantType.Double),
            ua.AttributeIds.Historizing: ua.Variant(False, ua.VariantType.Boolean),
        }
        for attribute, variant in attributes.items():
            node.attributes[attribute] = AttributeValue(ua.DataValue(variant))
        value = AttributeValue(None)  # type: ignore[arg-type]
        value.value_callback = self._reader(name)
        node.attributes[ua.AttributeIds.Value] = value
        return node

    def _reader(self, name: NodeName) -> Callable[[ua.NodeId, ua.AttributeIds], ua.DataValue]:
        def read(_nodeid: ua.NodeId, _attr: ua.AttributeIds) -> ua.DataValue:
            if not may(request.rights(), name.realm, write=False):
                return _status("BadUserAccessDenied")
            try:
                return _data_value(read_value(self.emulator, name))
            except UaStatus as status:
                return ua.DataValue(StatusCode_=status.code)
        return read

    async def _build_browse_tree(self) -> None:
        objects = self.server.nodes.objects
        ns = self.namespace
        root = await objects.add_folder(ua.NodeId("Sinumerik", ns), ua.QualifiedName("Sinumerik", ns))
        folders: dict[str, Any] = {"": root}
        aspace = self.server.iserver.aspace
        paths = [(path, spec) for spec in self.specs for path in node_paths(spec)[:1]]
        paths += [(f"/Plc/{item}", None) for item in ("MB0", "IB0", "QB0")]
        paths += [(f"/Plc/DB{db}.DBB0", None) for db in sorted(self.emulator.machine.data_blocks)]
        for path, _spec in paths:
            parent = root
            segments = path.strip("/").split("/")
            for depth in range(1, len(segments)):
                key = "/" + "/".join(segments[:depth])
                if key not in folders:
                    folders[key] = await parent.add_folder(ua.NodeId(key, ns), ua.QualifiedName(segments[depth - 1], ns))
                parent = folders[key]
            nodeid = ua.NodeId(path, ns)
            try:
                name = self.node_name(path)
            except NckNodeIdError:
                continue
            del name  # parsed only to know the node can be made
            node = aspace._nodes[nodeid]  # made by _LazyNodes
            node.references.append(ua.ReferenceDescription(
                ReferenceTypeId=ua.NodeId(ua.ObjectIds.HasComponent), IsForward=False, NodeId=parent.nodeid,
                BrowseName=ua.QualifiedName(segments[-2] if len(segments) > 1 else "Sinumerik", ns),
                NodeClass_=ua.NodeClass.Object, TypeDefinition=ua.NodeId(ua.ObjectIds.FolderType)))
            node.references.append(ua.ReferenceDescription(
                ReferenceTypeId=ua.NodeId(ua.ObjectIds.HasTypeDefinition), IsForward=True,
                NodeId=ua.NodeId(ua.ObjectIds.BaseDataVariableType), NodeClass_=ua.NodeClass.VariableType,
                BrowseName=ua.QualifiedName("BaseDataVariableType", 0)))
            aspace._nodes[parent.nodeid].references.append(ua.ReferenceDescription(
                ReferenceTypeId=ua.NodeId(ua.ObjectIds.HasComponent), IsForward=True, NodeId=nodeid,
                BrowseName=ua.QualifiedName(segments[-1], ns), DisplayName=ua.LocalizedText(segments[-1]),
                NodeClass_=ua.NodeClass.Variable, TypeDefinition=ua.NodeId(ua.ObjectIds.BaseDataVariableType)))

    # ------------------------------------------------------------------ sessions, rights, limits
    def _wrap_sessions(self, iserver: Any) -> None:
        create = iserver.create_session

        def create_session(*args: Any, **kwargs: Any) -> Any:
            session = create(*args, **kwargs)
            self._sessions = [s for s in self._sessions if s.state.name != "Closed"]
            self._sessions.append(session)
            self._wrap_session(session)
            return session

        iserver.create_session = create_session

    def _wrap_session(self, session: Any) -> None:
        face = self
        activate, read, call, subscribe, monitor = (session.activate_session, session.read, session.call,
                                                    session.create_subscription, session.create_monitored_items)

        def activate_session(params: Any, peer_certificate: Any) -> Any:
            active = sum(1 for s in face._sessions if s is not session and s.state.name == "Activated")
            if session.state.name == "Created" and active >= face.settings.max_sessions:
                raise ServiceError(ua.StatusCodes.BadTooManySessions)
            return activate(params, peer_certificate)

        def bind() -> None:
            user = getattr(session.user, "name", None)
            request.bind(user, face.rights_of(user))

        async def read_as_user(params: Any) -> Any:
            bind()
            return await read(params)

        async def call_as_user(params: Any) -> Any:
            bind()
            return await call(params)

        async def create_subscription(params: Any, callback: Any, request_callback: Any = None) -> Any:
            if len(session.subscription_service.subscriptions) >= face.settings.max_subscriptions:
                raise ServiceError(ua.StatusCodes.BadTooManySubscriptions)
            params.RequestedPublishingInterval = _allowed_interval(params.RequestedPublishingInterval)
            return await subscribe(params, callback, request_callback)

        async def monitor_as_user(params: ua.CreateMonitoredItemsParameters) -> Any:
            # The item's first value is read as this user, and an item on a variable the user may not
            # read is refused: pushes later would otherwise carry values its reads are denied.
            bind()
            return await face._monitor_with_rights(params, monitor)

        create_session = session.create_session

        async def create_session_capped(params: ua.CreateSessionParameters, sockname: Any = None) -> Any:
            # asyncua keeps what the client asks for (its own client asks for an hour) and closes a
            # session idle that long; the controller's is 60 s.
            cap_ms = face.settings.session_timeout_s * 1000.0
            requested = params.RequestedSessionTimeout
            params.RequestedSessionTimeout = cap_ms if not requested or requested <= 0 else min(requested, cap_ms)
            return await create_session(params, sockname=sockname)

        session.create_session = create_session_capped
        session.activate_session = activate_session
        session.read = read_as_user
        session.call = call_as_user
        session.create_subscription = create_subscription
        session.create_monitored_items = monitor_as_user

    def samples_per_s(self, subscriptions: Any) -> float:
        """What the data-change items of all subscriptions cost, in samples per second."""
        return sum(len(sub.monitored_item_srv._monitored_datachange) * 1000.0 / max(
            sub.data.RevisedPublishingInterval, ALLOWED_INTERVALS_MS[0]) for sub in subscriptions.values())

    def _cap_samples(self, service: Any) -> None:
        """Items past ``max_samples_per_s`` are refused one by one; the others are created."""
        create = service.create_monitored_items
        face = self

        async def create_monitored_items(params: ua.CreateMonitoredItemsParameters) -> Any:
            subscription = service.subscriptions.get(params.SubscriptionId)
            if subscription is None:
                return await create(params)
            each = 1000.0 / max(subscription.data.RevisedPublishingInterval, ALLOWED_INTERVALS_MS[0])
            budget = face.settings.max_samples_per_s - face.samples_per_s(service.subscriptions)
            refused: set[int] = set()
            for position, item in enumerate(params.ItemsToCreate):
                if item.ItemToMonitor.AttributeId == ua.AttributeIds.Value:
                    if budget + 1e-9 < each:
                        refused.add(position)
                        continue
                    budget -= each
            return await _create_refusing(params, refused, ua.StatusCodes.BadTooManyMonitoredItems, create)

        service.create_monitored_items = create_monitored_items

    async def _monitor_with_rights(self, params: ua.CreateMonitoredItemsParameters,
                                   create: Callable[[ua.CreateMonitoredItemsParameters], Any]) -> Any:
        rights = request.rights()
        denied: set[int] = set()
        for position, item in enumerate(params.ItemsToCreate):
            nodeid = item.ItemToMonitor.NodeId
            if item.ItemToMonitor.AttributeId == ua.AttributeIds.EventNotifier:
                if not rights & ALARM_RIGHTS:  # alarm events need AlarmRead (the controller's realm)
                    denied.add(position)
                continue
            if item.ItemToMonitor.AttributeId == ua.AttributeIds.Value and nodeid.NamespaceIndex != self.namespace:
                realm = self.models.realm_of(nodeid)  # a companion model's variable: its BTSS variable's realm
                if realm is not None and not may(rights, realm, write=False):
                    denied.add(position)
                continue
            if item.ItemToMonitor.AttributeId != ua.AttributeIds.Value or not isinstance(nodeid.Identifier, str):
                continue
            try:
                name = self.node_name(nodeid.Identifier)
            except NckNodeIdError:
                continue  # asyncua answers for ids that are no variable
            if not may(rights, name.realm, write=False):
                denied.add(position)
        return await _create_refusing(params, denied, ua.StatusCodes.BadUserAccessDenied, create)

    # ------------------------------------------------------------------ subscriptions
    def _wrap_datachange(self, aspace: Any) -> None:
        add, delete = aspace.add_datachange_callback, aspace.delete_datachange_callback
        monitored = self._monitored

        def add_datachange_callback(nodeid: ua.NodeId, attr: ua.AttributeIds, callback: Callable) -> Any:
            result = add(nodeid, attr, callback)
            if attr == ua.AttributeIds.Value and nodeid.NamespaceIndex == self.namespace and result[0].is_good():
                try:  # parsed again if the name cache was full when the node was made
                    name: NodeName | None = self.node_name(str(nodeid.Identifier))
                except NckNodeIdError:
                    name = None  # a folder
                if name is not None and nodeid not in monitored:
                    # The baseline is the value the monitored item has just read itself.
                    monitored[nodeid] = _Monitored(aspace._nodes[nodeid], name, raw_reader(self.emulator, name))
                    self._plc_index = None
            elif attr == ua.AttributeIds.Value and nodeid not in monitored and result[0].is_good():
                fed = self.models.monitor(nodeid)  # a companion model's variable fed from the machine
                if fed is not None:
                    monitored[nodeid] = fed  # type: ignore[assignment]
                    self._plc_index = None
            return result

        def delete_datachange_callback(handle: int) -> None:
            where = aspace._handle_to_attribute_map.get(handle)
            delete(handle)
            if where is not None and where[0] in monitored:
                node = aspace._nodes.get(where[0])
                if node is None or not node.attributes[ua.AttributeIds.Value].datachange_callbacks:
                    del monitored[where[0]]
                    self._plc_index = None

        aspace.add_datachange_callback = add_datachange_callback
        aspace.delete_datachange_callback = delete_datachange_callback

    # A write to the model captures, there and then, the new raw value of every monitored item it
    # touched; one pusher task hands the captured values to the monitored items in the order they were
    # written. Capturing at the write (not reading at the push) keeps each value even when the next
    # write lands before the pusher runs, so every change a writer makes reaches the item's queue. The
    # sampler captures what changes without a write (the machine's own dynamics, sensors, PI services,
    # the PLC program's memory).
    def _listen(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._loop_thread = threading.get_ident()
        self.emulator.plc.write_listeners.append(self._plc_written)
        self.emulator.nck.write_listeners.append(self._nc_written)

    def _unlisten(self) -> None:
        for listeners, listener in ((self.emulator.plc.write_listeners, self._plc_written),
                                    (self.emulator.nck.write_listeners, self._nc_written)):
            if listener in listeners:
                listeners.remove(listener)

    def _plc_written(self, area: int, db_number: int, start_byte: int, size_bytes: int) -> None:
        if self._plc_index is None:
            self._plc_index = _PlcIndex(self._monitored.values())
        touched = self._plc_index.touched(area, db_number, start_byte, start_byte + size_bytes)
        if touched:
            self._capture(touched)

    def _nc_written(self, _address: Any) -> None:
        # One NC write can move other NC values (a compensation value moves positions): all NC items.
        self._capture([entry for entry in self._monitored.values() if entry.nc])

    def _capture(self, entries: Any) -> int:
        """Queue the raw value of each entry that differs from the one queued last; how many."""
        captured = 0
        for entry in entries:
            try:
                raw = entry.reader()
            except Exception:  # the variable went away (a DB shrank): the client keeps its last value
                continue
            if raw != entry.raw:
                entry.raw = raw
                self._pending.append((entry, raw))
                captured += 1
        if captured:
            self._schedule_push()
        return captured

    def _schedule_push(self) -> None:
        if self._push_scheduled or self._pusher is not None or self._loop is None:
            return  # a pusher running takes what was queued meanwhile before it ends
        self._push_scheduled = True
        if threading.get_ident() == self._loop_thread:
            self._loop.call_soon(self._start_push)
        else:  # a writer on another thread (a test driving the model directly)
            self._loop.call_soon_threadsafe(self._start_push)

    def _start_push(self) -> None:
        self._push_scheduled = False
        if self._pusher is None and self._loop is not None:
            self._pusher = self._loop.create_task(self._drain())

    async def _drain(self) -> None:
        try:
            while self._pending:
                batch, self._pending = self._pending, []
                await self._push(batch)
        except Exception:  # a pusher must not die silently; what it could not push is dropped, logged
            log.exception("OPC UA pusher")
        finally:
            self._pusher = None

    async def _sample_forever(self) -> None:
        interval_s = self.settings.sample_interval_ms / 1000.0
        next_s = time.monotonic()
        while True:
            next_s += interval_s
            try:
                self.sample()
            except Exception:  # a sampler must keep sampling; the fault is logged
                log.exception("OPC UA sampler")
            delay = next_s - time.monotonic()
            if delay < 0:
                next_s = time.monotonic()
                delay = 0
            await asyncio.sleep(delay)

    def sample(self) -> int:
        """Queue the monitored values that changed since they were last queued; how many."""
        return self._capture(list(self._monitored.values()))

    async def _push(self, batch: list[tuple[_Monitored, object]]) -> None:
        now = datetime.now(UTC)
        value_attribute = ua.AttributeIds.Value
        pushed = 0
        for entry, raw in batch:
            try:
                variant = entry.to_variant(raw)
            except (UaStatus, ValueError, TypeError, IndexError):
                continue
            value = _PushedValue(variant, SourceTimestamp=now, ServerTimestamp=now)
            for handle, callback in list(entry.node.attributes[value_attribute].datachange_callbacks.items()):
                await callback(handle, value)
            pushed += 1
        self.updates_pushed += pushed


class _PushedValue(ua.DataValue):
    """A value pushed to monitored items. asyncua deep-copies every value it is handed, once per
    monitored item, so that the writer cannot change it afterwards; the face builds a new one for each
    push and never changes it, so the copy may be the value itself (the copy cost more than the rest
    of a push together)."""

    def __deepcopy__(self, memo: dict[int, Any]) -> _PushedValue:
        return self


class _Monitored:
    """A monitored SINUMERIK variable: its node, parsed name, a raw reader and the raw value last pushed."""

    __slots__ = ("node", "name", "reader", "raw", "nc", "block", "first_byte", "end_byte")

    def __init__(self, node: NodeData, name: NodeName, reader: Callable[[], object]) -> None:
        self.node, self.name, self.reader = node, name, reader
        self.raw = _raw_now(reader)
        self.nc = isinstance(name, NcNodeName)
        self.block: tuple[int, int] | None = None
        self.first_byte = self.end_byte = 0
        if isinstance(name, PlcNodeName):
            area = PLC_AREAS[name.area]
            self.block = (area, name.db if area == S7Area.DB else 0)
            self.first_byte = name.byte
            self.end_byte = name.byte + (_STRING_BYTES if name.kind == "STRING" else max(1, name.size_bytes))

    def to_variant(self, raw: object) -> ua.Variant:
        return variant_from_raw(self.name, raw)


_STRING_BYTES = 256  # an S7 string: maximum length, length, up to 254 characters


class _PlcIndex:
    """Monitored PLC items by memory block and byte range, to find what a write touched."""

    def __init__(self, entries: Any) -> None:
        by_block: dict[tuple[int, int], list[_Monitored]] = {}
        for entry in entries:
            if entry.block is not None:
                by_block.setdefault(entry.block, []).append(entry)
        self._blocks: dict[tuple[int, int], tuple[list[int], list[_Monitored], int]] = {}
        for block, items in by_block.items():
            items.sort(key=lambda item: item.first_byte)
            longest = max(item.end_byte - item.first_byte for item in items)
            self._blocks[block] = ([item.first_byte for item in items], items, longest)

    def touched(self, area: int, db_number: int, first_byte: int, end_byte: int) -> list[_Monitored]:
        found = self._blocks.get((area, db_number if area == S7Area.DB else 0))
        if found is None:
            return []
        starts, items, longest = found
        low = bisect.bisect_left(starts, first_byte - longest + 1)
        high = bisect.bisect_left(starts, end_byte)
        return [item for item in items[low:high] if item.end_byte > first_byte]


async def _create_refusing(params: ua.CreateMonitoredItemsParameters, refused: set[int], status: int,
                           create: Callable[[ua.CreateMonitoredItemsParameters], Any]) -> Any:
    """Create the items of ``params`` but those at the ``refused`` positions, which get ``status``; the
    results in the request's order."""
    if not refused:
        return await create(params)
    taken = [item for position, item in enumerate(params.ItemsToCreate) if position not in refused]
    created = iter(await create(dataclasses.replace(params, ItemsToCreate=taken)) if taken else [])
    refusal = ua.StatusCode(status)
    return [ua.MonitoredItemCreateResult(StatusCode_=refusal) if position in refused else next(created)
            for position in range(len(params.ItemsToCreate))]


def _raw_now(reader: Callable[[], object]) -> object:
    try:
        return reader()
    except Exception:  # read errors are the client's to see on its own reads; None: compare afresh
        return None


def _data_value(variant: ua.Variant) -> ua.DataValue:
    now = datetime.now(UTC)
    return ua.DataValue(variant, SourceTimestamp=now, ServerTimestamp=now)


def _allowed_interval(requested_ms: float) -> float:
    """The smallest allowed interval at or above the request (the controller revises to its set)."""
    for allowed in ALLOWED_INTERVALS_MS:
        if requested_ms <= allowed:
            return float(allowed)
    return float(ALLOWED_INTERVALS_MS[-1])


class _LazyNodes(dict):  # type: ignore[type-arg]
    """asyncua's node dict, making a SINUMERIK variable node when a service first names its id."""

    def __init__(self, nodes: MutableMapping[ua.NodeId, NodeData], face: OpcUaFace) -> None:
        super().__init__(nodes)  # what asyncua has made so far (from a shelf: only the nodes it touched)
        self._standard = nodes   # the standard address space, read from the shelf as nodes are first named
        self._face = face

    def _make(self, nodeid: object) -> NodeData | None:
        face = self._face
        if not isinstance(nodeid, ua.NodeId):
            return None
        if nodeid.NamespaceIndex != face.namespace:  # standard and companion-model nodes: from the shelf
            try:
                node = self._standard[nodeid]
            except KeyError:
                return None
            dict.__setitem__(self, nodeid, node)
            return node
        if nodeid.NamespaceIndex != face.namespace or not isinstance(nodeid.Identifier, str):
            return None
        try:
            name = face.node_name(nodeid.Identifier)
        except NckNodeIdError:
            return None
        node = face.make_node(nodeid, name)
        if len(self) < 200_000:  # a client naming endless distinct ids cannot grow the server without bound
            dict.__setitem__(self, nodeid, node)
        return node

    def __missing__(self, nodeid: ua.NodeId) -> NodeData:
        node = self._make(nodeid)
        if node is None:
            raise KeyError(nodeid)
        return node

    def __contains__(self, nodeid: object) -> bool:
        return dict.__contains__(self, nodeid) or self._make(nodeid) is not None

    def get(self, nodeid: Any, default: Any = None) -> Any:
        node = dict.get(self, nodeid)
        if node is None:
            node = self._make(nodeid)
        return default if node is None else node


_ADMIN = UaUser(role=UserRole.Admin)  # asyncua's own default: its internal session writes as admin


class _SinumerikAttributes(AttributeService):
    """asyncua's attribute service; reads as usual (value callbacks), writes of SINUMERIK variables
    through the model with the session user's rights."""

    def __init__(self, aspace: Any, face: OpcUaFace) -> None:
        super().__init__(aspace)
        self._face = face

    def read(self, params: ua.ReadParameters) -> list[ua.DataValue]:
        results = []
        for item in params.NodesToRead:
            status = self._unknown(item.NodeId)
            results.append(status if status is not None else self._aspace.read_attribute_value(item.NodeId, item.AttributeId))
        return results

    def _unknown(self, nodeid: ua.NodeId) -> ua.DataValue | None:
        """BadAttributeIdInvalid for a well-formed variable this machine lacks (asyncua would say unknown)."""
        face = self._face
        if nodeid.NamespaceIndex != face.namespace or not isinstance(nodeid.Identifier, str) \
                or dict.__contains__(self._aspace._nodes, nodeid):
            return None
        try:
            face.node_name(nodeid.Identifier)
        except NckNodeIdError as exc:
            return _status(exc.ua_status)
        return None

    async def write(self, params: ua.WriteParameters, user: UaUser = _ADMIN) -> list[ua.StatusCode]:
        face = self._face
        results: list[ua.StatusCode] = []
        retained = False
        for item in params.NodesToWrite:
            nodeid = item.NodeId
            ours = nodeid.NamespaceIndex == face.namespace and isinstance(nodeid.Identifier, str)
            if not ours:
                results.extend(await super().write(ua.WriteParameters(NodesToWrite=[item]), user))
                continue
            unknown = self._unknown(nodeid)
            if unknown is not None:
                results.append(unknown.StatusCode)  # type: ignore[arg-type]
                continue
            try:
                name = face.node_name(nodeid.Identifier)
            except NckNodeIdError:
                results.append(ua.StatusCode(ua.StatusCodes.BadNotWritable))  # a folder
                continue
            if item.AttributeId != ua.AttributeIds.Value:
                results.append(ua.StatusCode(ua.StatusCodes.BadNotWritable))
                continue
            if not may(face.rights_of(getattr(user, "name", None)), name.realm, write=True):
                results.append(ua.StatusCode(ua.StatusCodes.BadUserAccessDenied))
                continue
            try:
                if write_value(face.emulator, name, item.Value.Value if item.Value else None):
                    face.emulator.saves.request()
                    retained = True
            except UaStatus as status:
                results.append(status.code)
                continue
            results.append(ua.StatusCode())  # monitored items: the model's write listener pushes the value
        if retained:
            await face.emulator.saves.durable()  # acknowledged once on disk; other clients go on meanwhile
        return results
