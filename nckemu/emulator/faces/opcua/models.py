"""The companion models on one OPC UA face: which are on, the address space they start from, and the
values of their instances fed from the machine.

``face.py`` asks this object four things: the shelf to start from (``shelf``), to set the instances up
once the face's own namespace exists (``start``), whether a node is fed from the machine (``monitor``,
for its subscriptions) and which realm guards it (``realm_of``, for its rights). The instances
themselves are ``umati.py`` (OPC 40501-1, MachineTool) and ``cnc.py`` (OPC 40502).

A fed variable reads the machine on every read, as the SINUMERIK variables do: its ``Feed`` names a raw
reader (the same ``raw_reader`` of the BTSS variable it shows, so S7, the SINUMERIK node id and the umati
node read one model), the conversion to the model's data type, and the realm of that BTSS variable,
whose rights guard it here too. Subscriptions on it go through the face's capture and sampling: NC
writes capture it at write time, the 100 ms sampler catches what changes without a write.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua
from asyncua.server.address_space import AttributeValue

from nckemu.emulator.faces.opcua import cnc, nodesets, request, umati
from nckemu.emulator.faces.opcua.feeds import FedMonitored, Feed
from nckemu.emulator.faces.opcua.instances import Instantiator, Types
from nckemu.emulator.faces.opcua.production import ProgramTracker
from nckemu.emulator.faces.opcua.settings import may
from nckemu.emulator.faces.opcua.structures import status_value
from nckemu.emulator.faces.opcua.values import UaStatus

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import NamingHost

log = logging.getLogger("nckemu.emulator.opcua.models")

INSTANCE_NAMESPACE = "urn:nckemu:instances"
MODELS = ("MachineTool", "CNC")
_TYPES: dict[Path, Types] = {}   # per models' shelf, shared by the faces of a process
_TOLD_MISSING = False


class Models:
    """The companion models of one face (none when switched off or the NodeSets are missing)."""

    def __init__(self, face: NamingHost) -> None:
        self.face = face
        self.server: Server | None = None  # the face's, once started
        self.wanted = tuple(face.settings.models)
        self.directory: Path | None = None
        if self.wanted:
            self.directory = nodesets.find(face.settings.nodesets)
            if self.directory is None:
                global _TOLD_MISSING
                if not _TOLD_MISSING:  # once per process (a fleet has many faces)
                    log.warning(nodesets.how_to_get())
                    _TOLD_MISSING = True
        self.shelf_used: nodesets.ModelsShelf | None = None
        self.feeds: dict[ua.NodeId, Feed] = {}
        self.namespaces: dict[str, int] = {}
        self.instance_namespace = 0
        self.parts: list[Any] = []
        self.nodes_made = 0
        self.trackers: dict[int, ProgramTracker] = {}  # the program life of each channel shown (production.py)

    @property
    def on(self) -> bool:
        return self.shelf_used is not None

    async def shelf(self) -> Path | None:
        """The shelf the face starts from: the models' (built now if missing), or None for the standard one."""
        if self.directory is None:
            return None
        try:
            self.shelf_used = await nodesets.models_shelf(self.directory)
        except Exception as exc:  # the face serves without the models rather than not at all
            log.warning("OPC UA: umati/CNC models off, their NodeSets did not load (%s)", exc)
            self.directory = None
            return None
        return self.shelf_used.path

    async def after_init(self, server: Server) -> None:
        if self.shelf_used is not None:
            await nodesets.restore_namespaces(server, self.shelf_used, self.face.settings.namespace_uri)

    def dropped(self) -> None:
        """The shelf did not load: the face goes on with the standard address space alone."""
        self.shelf_used = None
        self.directory = None

    async def start(self, server: Server) -> None:
        if self.shelf_used is None:
            return
        namespaces = await server.get_namespace_array()
        self.namespaces = {uri: index for index, uri in enumerate(namespaces)}
        self.instance_namespace = await server.register_namespace(INSTANCE_NAMESPACE)
        self.server = server
        nodes = server.iserver.aspace
        types = _TYPES.get(self.shelf_used.path)
        if types is None:
            named = {}
            for key, nodeid in self.shelf_used.types.items():
                uri, name = key.split("|", 1)
                if uri in self.namespaces:
                    named[(self.namespaces[uri], name)] = ua.NodeId.from_string(nodeid)
            types = _TYPES[self.shelf_used.path] = Types(nodes, named)
        maker = Instantiator(types, nodes, self.instance_namespace)
        if "MachineTool" in self.wanted:
            self.parts.append(umati.MachineToolInstance(self, maker).build())
        if "CNC" in self.wanted:
            self.parts.append(cnc.CncInterfaceInstance(self, maker).build())
        self.nodes_made = maker.made
        for tracker in self.trackers.values():
            tracker.start()
        for part in self.parts:
            await part.start(server)

    async def stop(self) -> None:
        for part in self.parts:
            await part.stop()
        for tracker in self.trackers.values():
            tracker.stop()

    def tracker(self, channel: int) -> ProgramTracker:
        """Channel ``channel``'s program life, one per face for every model that shows it."""
        found = self.trackers.get(channel)
        if found is None:
            found = self.trackers[channel] = ProgramTracker(self.face.emulator, channel)
        return found

    def ns(self, uri: str) -> int:
        return self.namespaces[uri]

    @property
    def ns_uri(self) -> str:
        """The namespace of the instances' own nodes (the entries of lists: channels, spindles, tools ...)."""
        return INSTANCE_NAMESPACE

    def cnc_alarm_type(self) -> ua.NodeId | None:
        """OPC 40502's CncAlarmType when the CNC model is on."""
        if not any(isinstance(part, cnc.CncInterfaceInstance) for part in self.parts):
            return None
        return _TYPES[self.shelf_used.path].find(self.ns(nodesets.CNC), "CncAlarmType")  # type: ignore[union-attr]

    def cnc_interface(self) -> ua.NodeId | None:
        for part in self.parts:
            if isinstance(part, cnc.CncInterfaceInstance) and part.made is not None:
                return part.made.root
        return None

    # ------------------------------------------------------------------ values
    def bind(self, nodeid: ua.NodeId, feed: Feed) -> None:
        """``nodeid``'s value is read from the machine through ``feed`` on every read."""
        assert self.server is not None
        self.feeds[nodeid] = feed
        self.server.set_attribute_value_callback(nodeid, self._reader(feed))
        access = self.server.iserver.aspace[nodeid].attributes[ua.AttributeIds.AccessLevel].value
        level = access.Value.Value if access is not None and access.Value is not None else 0
        self.server.set_attribute_value_callback(  # readable by the sessions that may read its realm
            nodeid, request.user_access_level(int(level or 0), feed.realm), ua.AttributeIds.UserAccessLevel)

    def set(self, nodeid: ua.NodeId, variant: ua.Variant) -> None:
        """A value that does not change while the face runs (identification)."""
        assert self.server is not None
        node = self.server.iserver.aspace[nodeid]
        node.attributes[ua.AttributeIds.Value] = AttributeValue(ua.DataValue(variant))

    @staticmethod
    def _reader(feed: Feed) -> Callable[[ua.NodeId, ua.AttributeIds], ua.DataValue]:
        realm = feed.realm

        def read(_nodeid: ua.NodeId, _attr: ua.AttributeIds) -> ua.DataValue:
            if realm is not None and not may(request.rights(), realm, write=False):
                return status_value(ua.StatusCode(ua.StatusCodes.BadUserAccessDenied))
            try:
                variant = feed.variant(feed.reader())
            except UaStatus as status:
                return status_value(status.code)
            now = datetime.now(UTC)
            return ua.DataValue(variant, SourceTimestamp=now, ServerTimestamp=now)
        return read

    def realm_of(self, nodeid: ua.NodeId) -> str | None:
        feed = self.feeds.get(nodeid)
        return feed.realm if feed is not None else None

    def monitor(self, nodeid: ua.NodeId) -> FedMonitored | None:
        """The monitored entry of a fed node (None for anything else)."""
        feed = self.feeds.get(nodeid)
        if feed is None:
            return None
        assert self.server is not None
        return FedMonitored(self.server.iserver.aspace[nodeid], feed)
