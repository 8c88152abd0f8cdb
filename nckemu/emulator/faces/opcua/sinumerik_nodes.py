"""The SINUMERIK namespace of the OPC UA face: its node ids parsed, its nodes made when first named, its
browse tree, and writes through the model with the session user's rights.

- Browsing: folders under ``Objects/Sinumerik`` hold one variable per catalogue row, first unit and
  line only, as the controller shows them.
- Any other id in the namespace (``R[u1,56]``, ``/Plc/DB2.DBD0:REAL[10]``) is parsed by the catalogue
  and its node made when a service first asks for it (``_LazyNodes``), so open-ended ids need no nodes
  made in advance. Values are read from the model on every read (a value callback).
- Writes go through ``_SinumerikAttributes.write`` with the session's user: rights, limits, then the
  model, as an S7 write would.
"""

from __future__ import annotations

from collections.abc import Callable, MutableMapping
from datetime import UTC, datetime
from typing import Any

from asyncua import Server, ua
from asyncua.crypto.permission_rules import User as UaUser
from asyncua.crypto.permission_rules import UserRole
from asyncua.server.address_space import AttributeService, AttributeValue, NodeData

from nckemu.catalogue.node_ids import NcNodeName, NodeName, node_paths, parse_node_id
from nckemu.emulator.faces.opcua import asyncua_internals, request, structures
from nckemu.emulator.faces.opcua.settings import ALLOWED_INTERVALS_MS, may
from nckemu.emulator.faces.opcua.values import UaStatus, read_value, variant_type, write_value
from nckemu.emulator.machine.core import Emulator
from nckemu.errors import NckNodeIdError

_ACCESS_RW = ua.AccessLevel.CurrentRead.mask | ua.AccessLevel.CurrentWrite.mask


def status_value(name: str) -> ua.DataValue:
    return structures.status_value(ua.StatusCode(getattr(ua.StatusCodes, name)))


def data_value(variant: ua.Variant) -> ua.DataValue:
    now = datetime.now(UTC)
    return ua.DataValue(variant, SourceTimestamp=now, ServerTimestamp=now)


def writable(name: NodeName) -> bool:
    """Whether anyone may write the variable (the realm rights then decide who)."""
    return not (isinstance(name, NcNodeName) and name.spec.read_only)


class SinumerikNodes:
    """The face's SINUMERIK namespace (``namespace`` is its index once ``install`` ran)."""

    def __init__(self, emulator: Emulator, rights_of: Callable[[str | None], frozenset[str]]) -> None:
        self.emulator = emulator
        self.rights_of = rights_of
        self.namespace = 2
        self._names: dict[str, NodeName] = {}

    @property
    def specs(self) -> tuple[Any, ...]:
        return tuple(self.emulator.nck.store.specs)

    def install(self, server: Server, namespace: int) -> None:
        """Serve the namespace ``namespace`` of ``server`` (initialised, not yet started)."""
        self.namespace = namespace
        iserver = server.iserver
        aspace = iserver.aspace
        asyncua_internals.replace_nodes(aspace, _LazyNodes(asyncua_internals.nodes(aspace), self))
        asyncua_internals.replace_attribute_service(iserver, _SinumerikAttributes(aspace, self))

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
        access = _ACCESS_RW if writable(name) else ua.AccessLevel.CurrentRead.mask
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
            ua.AttributeIds.MinimumSamplingInterval: ua.Variant(float(ALLOWED_INTERVALS_MS[0]), ua.VariantType.Double),
            ua.AttributeIds.Historizing: ua.Variant(False, ua.VariantType.Boolean),
        }
        for attribute, variant in attributes.items():
            node.attributes[attribute] = AttributeValue(ua.DataValue(variant))
        value = AttributeValue(None)  # type: ignore[arg-type]
        value.value_callback = self._reader(name)
        node.attributes[ua.AttributeIds.Value] = value
        user_access = AttributeValue(None)  # type: ignore[arg-type]
        user_access.value_callback = request.user_access_level(access, name.realm)  # the session's rights
        node.attributes[ua.AttributeIds.UserAccessLevel] = user_access
        return node

    def _reader(self, name: NodeName) -> Callable[[ua.NodeId, ua.AttributeIds], ua.DataValue]:
        def read(_nodeid: ua.NodeId, _attr: ua.AttributeIds) -> ua.DataValue:
            if not may(request.rights(), name.realm, write=False):
                return status_value("BadUserAccessDenied")
            try:
                return data_value(read_value(self.emulator, name))
            except UaStatus as status:
                return structures.status_value(status.code)
        return read

    async def build_browse_tree(self, server: Server) -> None:
        objects = server.nodes.objects
        ns = self.namespace
        root = await objects.add_folder(ua.NodeId("Sinumerik", ns), ua.QualifiedName("Sinumerik", ns))
        folders: dict[str, Any] = {"": root}
        aspace = server.iserver.aspace
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
            node = aspace[nodeid]  # made by _LazyNodes
            node.references.append(structures.reference(
                ua.NodeClass.Object, ReferenceTypeId=ua.NodeId(ua.ObjectIds.HasComponent), IsForward=False,
                NodeId=parent.nodeid, BrowseName=ua.QualifiedName(segments[-2] if len(segments) > 1 else "Sinumerik", ns),
                TypeDefinition=ua.NodeId(ua.ObjectIds.FolderType)))
            node.references.append(structures.reference(
                ua.NodeClass.VariableType, ReferenceTypeId=ua.NodeId(ua.ObjectIds.HasTypeDefinition), IsForward=True,
                NodeId=ua.NodeId(ua.ObjectIds.BaseDataVariableType), BrowseName=ua.QualifiedName("BaseDataVariableType", 0)))
            aspace[parent.nodeid].references.append(structures.reference(
                ua.NodeClass.Variable, ReferenceTypeId=ua.NodeId(ua.ObjectIds.HasComponent), IsForward=True,
                NodeId=nodeid, BrowseName=ua.QualifiedName(segments[-1], ns),
                DisplayName=ua.LocalizedText(segments[-1]), TypeDefinition=ua.NodeId(ua.ObjectIds.BaseDataVariableType)))


class _LazyNodes(dict):  # type: ignore[type-arg]
    """asyncua's node dict, making a SINUMERIK variable node when a service first names its id."""

    def __init__(self, nodes: MutableMapping[ua.NodeId, NodeData], face: SinumerikNodes) -> None:
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

    def __init__(self, aspace: Any, face: SinumerikNodes) -> None:
        super().__init__(aspace)
        self.nodes = aspace  # asyncua's own name for it is private
        self._face = face

    def read(self, params: ua.ReadParameters) -> list[ua.DataValue]:
        results = []
        for item in params.NodesToRead:
            status = self._unknown(item.NodeId)
            results.append(status if status is not None else self.nodes.read_attribute_value(item.NodeId, item.AttributeId))
        return results

    def _unknown(self, nodeid: ua.NodeId) -> ua.DataValue | None:
        """BadAttributeIdInvalid for a well-formed variable this machine lacks (asyncua would say unknown)."""
        face = self._face
        if nodeid.NamespaceIndex != face.namespace or not isinstance(nodeid.Identifier, str) \
                or dict.__contains__(asyncua_internals.nodes(self.nodes), nodeid):
            return None
        try:
            face.node_name(nodeid.Identifier)
        except NckNodeIdError as exc:
            return status_value(exc.ua_status)
        return None

    def _anyone_writes(self, nodeid: ua.NodeId, attribute: ua.AttributeIds) -> bool:
        """Whether a client could write this attribute of a standard or companion-model node at all (an
        unknown node is asyncua's to answer). Their UserAccessLevel is the same for every user."""
        if nodeid not in self.nodes:
            return True
        if attribute != ua.AttributeIds.Value:
            return False
        write = ua.AccessLevel.CurrentWrite.mask
        levels = [self.nodes.read_attribute_value(nodeid, level)
                  for level in (ua.AttributeIds.AccessLevel, ua.AttributeIds.UserAccessLevel)]
        return all(level.Value is not None and isinstance(level.Value.Value, int) and level.Value.Value & write
                   for level in levels)

    async def write(self, params: ua.WriteParameters, user: UaUser = _ADMIN) -> list[ua.StatusCode]:
        face = self._face
        results: list[ua.StatusCode] = []
        retained = False
        for item in params.NodesToWrite:
            nodeid = item.NodeId
            ours = nodeid.NamespaceIndex == face.namespace and isinstance(nodeid.Identifier, str)
            if not ours:
                if user.role != UserRole.Admin and not self._anyone_writes(nodeid, item.AttributeId):
                    results.append(ua.StatusCode(ua.StatusCodes.BadNotWritable))  # not a rights question
                    continue
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
            if item.AttributeId != ua.AttributeIds.Value or not writable(name):
                results.append(ua.StatusCode(ua.StatusCodes.BadNotWritable))  # whatever the user
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
