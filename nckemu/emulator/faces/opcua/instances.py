"""Instances of the companion models' types, made from the type definitions in the address space.

``Instantiator.make(parent, type, name)`` adds an object of ``type`` below ``parent`` with every child its
type (and its supertypes) declares Mandatory, recursively, and the Optional children the caller names by
path ("Monitoring/MachineTool/FeedOverride"). Each child copies its declaration: browse name, display
name, description, node class, type definition, data type, value rank, access level and default value;
a variable without a default gets a zero of its data type. Nothing here knows a model: the types are
read from the NodeSets as imported (``nodesets.py``).

asyncua's own ``instantiate`` does the same through its services, about a millisecond a node; here the
nodes are written into the face's address space directly, as ``face.make_node`` does for SINUMERIK ids.
Node ids are strings in the face's instance namespace: the path of browse names from the instance root.
"""

from __future__ import annotations

import datetime
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Protocol

from asyncua import ua
from asyncua.server.address_space import AttributeValue, NodeData

from nckemu.emulator.faces.opcua.structures import reference as described


class NodeStore(Protocol):
    """Nodes by id, as asyncua's ``AddressSpace`` offers them (``aspace[nodeid]``)."""

    def __getitem__(self, nodeid: ua.NodeId) -> NodeData: ...

    def __setitem__(self, nodeid: ua.NodeId, node: NodeData) -> None: ...

    def __contains__(self, nodeid: ua.NodeId) -> bool: ...

HAS_COMPONENT = ua.NodeId(ua.ObjectIds.HasComponent)
HAS_PROPERTY = ua.NodeId(ua.ObjectIds.HasProperty)
ORGANIZES = ua.NodeId(ua.ObjectIds.Organizes)
HAS_TYPE_DEFINITION = ua.NodeId(ua.ObjectIds.HasTypeDefinition)
HAS_MODELLING_RULE = ua.NodeId(ua.ObjectIds.HasModellingRule)
HAS_SUBTYPE = ua.NodeId(ua.ObjectIds.HasSubtype)
CHILD_REFERENCES = frozenset({ua.NodeId(ua.ObjectIds.HasComponent), ua.NodeId(ua.ObjectIds.HasProperty),
                              ua.NodeId(ua.ObjectIds.HasOrderedComponent), ua.NodeId(ua.ObjectIds.HasAddIn),
                              ua.NodeId(ua.ObjectIds.Organizes)})
MANDATORY = ua.NodeId(ua.ObjectIds.ModellingRule_Mandatory)
OPTIONAL = ua.NodeId(ua.ObjectIds.ModellingRule_Optional)
PLACEHOLDERS = frozenset({ua.NodeId(ua.ObjectIds.ModellingRule_OptionalPlaceholder),
                          ua.NodeId(ua.ObjectIds.ModellingRule_MandatoryPlaceholder)})

_A = ua.AttributeIds
_COPIED = {
    ua.NodeClass.Object: (_A.DisplayName, _A.Description, _A.WriteMask, _A.UserWriteMask, _A.EventNotifier),
    ua.NodeClass.Variable: (_A.DisplayName, _A.Description, _A.WriteMask, _A.UserWriteMask, _A.DataType,
                            _A.ValueRank, _A.ArrayDimensions, _A.AccessLevel, _A.UserAccessLevel,
                            _A.MinimumSamplingInterval, _A.Historizing, _A.Value),
    ua.NodeClass.Method: (_A.DisplayName, _A.Description, _A.WriteMask, _A.UserWriteMask, _A.Executable,
                          _A.UserExecutable),
}
# Built-in data types (Part 6) by their node id number, and the abstract numbers by the type we serve.
_BUILTIN = {1: ua.VariantType.Boolean, 2: ua.VariantType.SByte, 3: ua.VariantType.Byte, 4: ua.VariantType.Int16,
            5: ua.VariantType.UInt16, 6: ua.VariantType.Int32, 7: ua.VariantType.UInt32, 8: ua.VariantType.Int64,
            9: ua.VariantType.UInt64, 10: ua.VariantType.Float, 11: ua.VariantType.Double,
            12: ua.VariantType.String, 13: ua.VariantType.DateTime, 14: ua.VariantType.Guid,
            15: ua.VariantType.ByteString, 16: ua.VariantType.XmlElement, 17: ua.VariantType.NodeId,
            18: ua.VariantType.ExpandedNodeId, 19: ua.VariantType.StatusCode, 20: ua.VariantType.QualifiedName,
            21: ua.VariantType.LocalizedText, 22: ua.VariantType.ExtensionObject, 26: ua.VariantType.Double,
            27: ua.VariantType.Int64, 28: ua.VariantType.UInt64, 29: ua.VariantType.Int32}
_ZERO: dict[ua.VariantType, Callable[[], Any]] = {
    ua.VariantType.Boolean: lambda: False, ua.VariantType.String: lambda: "",
    ua.VariantType.DateTime: lambda: datetime.datetime(1601, 1, 1, tzinfo=datetime.UTC),
    ua.VariantType.ByteString: lambda: b"", ua.VariantType.NodeId: ua.NodeId,
    ua.VariantType.QualifiedName: ua.QualifiedName, ua.VariantType.LocalizedText: lambda: ua.LocalizedText(""),
    ua.VariantType.Float: lambda: 0.0, ua.VariantType.Double: lambda: 0.0,
}
_STRUCTURES: dict[int, Callable[[], Any]] = {
    ua.ObjectIds.Range: lambda: ua.Range(0.0, 0.0),
    ua.ObjectIds.EUInformation: ua.EUInformation,
}


@dataclass
class Made:
    """What ``make`` added: node ids by path from the instance root ("" is the root itself)."""

    root: ua.NodeId
    paths: dict[str, ua.NodeId]

    def __getitem__(self, path: str) -> ua.NodeId:
        return self.paths[path]

    def get(self, path: str) -> ua.NodeId | None:
        return self.paths.get(path)


class Types:
    """The type definitions of an address space (read once; shared by every face of the process)."""

    def __init__(self, nodes: NodeStore,
                 named: dict[tuple[int, str], ua.NodeId] | None = None) -> None:
        self.nodes = nodes
        self.named = named or {}   # (namespace index, browse name) -> type (nodesets.py writes the index)
        self._children: dict[ua.NodeId, dict[str, tuple[ua.NodeId, ua.NodeId]]] = {}

    def node(self, nodeid: ua.NodeId) -> NodeData:
        return self.nodes[nodeid]

    def _target(self, nodeid: ua.NodeId, reference: ua.NodeId, forward: bool = True) -> ua.NodeId | None:
        for ref in self.node(nodeid).references:
            if ref.ReferenceTypeId == reference and ref.IsForward == forward:
                return ref.NodeId  # type: ignore[no-any-return]
        return None

    def supertype(self, nodeid: ua.NodeId) -> ua.NodeId | None:
        return self._target(nodeid, HAS_SUBTYPE, forward=False)

    def type_definition(self, nodeid: ua.NodeId) -> ua.NodeId | None:
        return self._target(nodeid, HAS_TYPE_DEFINITION)

    def rule(self, nodeid: ua.NodeId) -> ua.NodeId | None:
        return self._target(nodeid, HAS_MODELLING_RULE)

    def is_subtype(self, nodeid: ua.NodeId, of: ua.NodeId) -> bool:
        current: ua.NodeId | None = nodeid
        while current is not None:
            if current == of:
                return True
            current = self.supertype(current)
        return False

    def browse_name(self, nodeid: ua.NodeId) -> ua.QualifiedName:
        return self.node(nodeid).attributes[_A.BrowseName].value.Value.Value  # type: ignore[union-attr]

    def node_class(self, nodeid: ua.NodeId) -> ua.NodeClass:
        return ua.NodeClass(self.node(nodeid).attributes[_A.NodeClass].value.Value.Value)  # type: ignore[union-attr]

    def _own(self, nodeid: ua.NodeId) -> dict[str, tuple[ua.NodeId, ua.NodeId]]:
        """The children a node declares itself: browse name -> (reference type, declaration)."""
        found: dict[str, tuple[ua.NodeId, ua.NodeId]] = {}
        for ref in self.node(nodeid).references:
            if ref.IsForward and ref.ReferenceTypeId in CHILD_REFERENCES and ref.NodeId in self.nodes:
                found.setdefault(ref.BrowseName.Name, (ref.ReferenceTypeId, ref.NodeId))
        return found

    def children_of_type(self, type_id: ua.NodeId) -> dict[str, tuple[ua.NodeId, ua.NodeId]]:
        """Every child a type declares, its supertypes' too; the most derived declaration wins."""
        cached = self._children.get(type_id)
        if cached is None:
            cached = {}
            current: ua.NodeId | None = type_id
            while current is not None:
                for name, entry in self._own(current).items():
                    cached.setdefault(name, entry)
                current = self.supertype(current)
            self._children[type_id] = cached
        return cached

    def children_of_declaration(self, declaration: ua.NodeId) -> dict[str, tuple[ua.NodeId, ua.NodeId]]:
        """A child's own declared children over those of its type definition."""
        found = dict(self._own(declaration))
        type_id = self.type_definition(declaration)
        if type_id is not None:
            for name, entry in self.children_of_type(type_id).items():
                found.setdefault(name, entry)
        return found

    def find(self, namespace: int, name: str) -> ua.NodeId:
        """A model's type by namespace index and browse name (the models' numeric ids are looked up, not
        written here)."""
        found = self.named.get((namespace, name))
        if found is None:
            raise KeyError(f"no type {name} in ns={namespace}")
        return found

    def variant_type(self, data_type: ua.NodeId) -> ua.VariantType:
        """The built-in type values of ``data_type`` travel as (enumerations as Int32)."""
        current: ua.NodeId | None = data_type
        while current is not None:
            if current.NamespaceIndex == 0 and current.Identifier in _BUILTIN:
                return _BUILTIN[current.Identifier]  # type: ignore[index]
            current = self.supertype(current)
        return ua.VariantType.Variant

    def zero(self, data_type: ua.NodeId, array: bool) -> ua.Variant:
        """A zero value of ``data_type`` (an empty array for arrays)."""
        kind = self.variant_type(data_type)
        if array:
            return ua.Variant([], kind if kind != ua.VariantType.Variant else ua.VariantType.Null, is_array=True)
        if kind == ua.VariantType.ExtensionObject:
            make = _STRUCTURES.get(data_type.Identifier) if data_type.NamespaceIndex == 0 else None  # type: ignore[arg-type]
            return ua.Variant(make() if make else None, kind if make else ua.VariantType.Null)
        if kind == ua.VariantType.Variant:
            return ua.Variant(None)
        make_zero = _ZERO.get(kind)
        return ua.Variant(make_zero() if make_zero else 0, kind)


class Instantiator:
    """Makes instances in one face's address space (``nodes``), node ids in ``namespace``."""

    def __init__(self, types: Types, nodes: NodeStore, namespace: int) -> None:
        self.types = types
        self.nodes = nodes
        self.namespace = namespace
        self.made = 0

    def make(self, parent: ua.NodeId, type_id: ua.NodeId, name: str, *, root: str | None = None,
             reference: ua.NodeId = ORGANIZES, optional: Iterable[str] = (),
             browse_namespace: int | None = None) -> Made:
        """An object of ``type_id`` named ``name`` below ``parent`` with its mandatory children and the
        ``optional`` ones (paths below the new object); ``root`` its node id string (default ``name``)."""
        types = self.types
        root = root or name
        nodeid = ua.NodeId(root, self.namespace)
        wanted = set(optional)
        for path in list(wanted):  # an optional child's ancestors come with it
            parts = path.split("/")
            wanted.update("/".join(parts[:end]) for end in range(1, len(parts)))
        browse = ua.QualifiedName(name, self.namespace if browse_namespace is None else browse_namespace)
        node = self._node(nodeid, ua.NodeClass.Object, browse, type_id, declaration=type_id)
        node.attributes[_A.DisplayName] = AttributeValue(ua.DataValue(ua.Variant(ua.LocalizedText(name))))
        self._link(parent, node, reference, browse, ua.NodeClass.Object, type_id)
        made = Made(nodeid, {"": nodeid})
        self._children(node, types.children_of_type(type_id), "", wanted, made)
        return made

    def _children(self, parent: NodeData, children: dict[str, tuple[ua.NodeId, ua.NodeId]], path: str,
                  wanted: set[str], made: Made) -> None:
        types = self.types
        for name, (reference, declaration) in children.items():
            rule = types.rule(declaration)
            child_path = f"{path}/{name}" if path else name
            if rule is None or rule in PLACEHOLDERS:
                continue
            if rule != MANDATORY and child_path not in wanted:
                continue
            node_class = types.node_class(declaration)
            browse = types.browse_name(declaration)
            type_id = types.type_definition(declaration)
            nodeid = ua.NodeId(f"{made.root.Identifier}/{child_path}", self.namespace)
            node = self._node(nodeid, node_class, browse, type_id, declaration=declaration)
            self._link(parent.nodeid, node, reference, browse, node_class, type_id)
            made.paths[child_path] = nodeid
            self._children(node, types.children_of_declaration(declaration), child_path, wanted, made)

    def _node(self, nodeid: ua.NodeId, node_class: ua.NodeClass, browse: ua.QualifiedName,
              type_id: ua.NodeId | None, declaration: ua.NodeId) -> NodeData:
        source = self.types.node(declaration)
        node = NodeData(nodeid)
        attributes = node.attributes
        attributes[_A.NodeId] = AttributeValue(ua.DataValue(ua.Variant(nodeid, ua.VariantType.NodeId)))
        attributes[_A.NodeClass] = AttributeValue(ua.DataValue(ua.Variant(node_class, ua.VariantType.Int32)))
        attributes[_A.BrowseName] = AttributeValue(ua.DataValue(ua.Variant(browse, ua.VariantType.QualifiedName)))
        for attribute in _COPIED[node_class]:
            copied = source.attributes.get(attribute)
            if copied is not None and copied.value is not None:
                attributes[attribute] = AttributeValue(copied.value)
        if node_class == ua.NodeClass.Object:
            attributes.setdefault(_A.EventNotifier, AttributeValue(ua.DataValue(ua.Variant(0, ua.VariantType.Byte))))
        if node_class == ua.NodeClass.Variable:
            data_type = attributes[_A.DataType].value.Value.Value  # type: ignore[union-attr]
            rank = attributes[_A.ValueRank].value.Value.Value if _A.ValueRank in attributes else -1  # type: ignore[union-attr]
            value = attributes.get(_A.Value)
            if value is None or value.value is None or value.value.Value is None or value.value.Value.Value is None:
                zero = self.types.zero(data_type, rank is not None and rank >= 0)
                attributes[_A.Value] = AttributeValue(ua.DataValue(zero))
            attributes.setdefault(_A.AccessLevel, AttributeValue(ua.DataValue(ua.Variant(
                ua.AccessLevel.CurrentRead.mask, ua.VariantType.Byte))))
            # Users read the instances; the machine is changed through its SINUMERIK variables (and S7).
            attributes[_A.UserAccessLevel] = AttributeValue(ua.DataValue(ua.Variant(
                ua.AccessLevel.CurrentRead.mask, ua.VariantType.Byte)))
        attributes.setdefault(_A.WriteMask, AttributeValue(ua.DataValue(ua.Variant(0, ua.VariantType.UInt32))))
        attributes.setdefault(_A.UserWriteMask, AttributeValue(ua.DataValue(ua.Variant(0, ua.VariantType.UInt32))))
        attributes.setdefault(_A.Description, AttributeValue(ua.DataValue(ua.Variant(ua.LocalizedText(None)))))
        attributes.setdefault(_A.DisplayName, AttributeValue(ua.DataValue(ua.Variant(ua.LocalizedText(browse.Name)))))
        if type_id is not None:
            type_class = self.types.node_class(type_id)
            node.references.append(described(
                type_class, ReferenceTypeId=HAS_TYPE_DEFINITION, IsForward=True, NodeId=type_id,
                BrowseName=self.types.browse_name(type_id),
                DisplayName=ua.LocalizedText(self.types.browse_name(type_id).Name)))
        self.nodes[nodeid] = node
        self.made += 1
        return node

    def _link(self, parent: ua.NodeId, node: NodeData, reference: ua.NodeId, browse: ua.QualifiedName,
              node_class: ua.NodeClass, type_id: ua.NodeId | None) -> None:
        parent_node = self.nodes[parent]
        display = node.attributes[_A.DisplayName].value.Value.Value  # type: ignore[union-attr]
        parent_node.references.append(described(
            node_class, ReferenceTypeId=reference, IsForward=True, NodeId=node.nodeid, BrowseName=browse,
            DisplayName=display, TypeDefinition=type_id or ua.NodeId()))
        parent_browse = parent_node.attributes[_A.BrowseName].value.Value.Value  # type: ignore[union-attr]
        parent_class = parent_node.attributes[_A.NodeClass].value.Value.Value  # type: ignore[union-attr]
        node.references.append(described(
            ua.NodeClass(parent_class), ReferenceTypeId=reference, IsForward=False, NodeId=parent,
            BrowseName=parent_browse, DisplayName=ua.LocalizedText(parent_browse.Name)))
