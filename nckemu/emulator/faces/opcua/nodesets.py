"""The companion specifications' NodeSet files: where they are, how they are read, and their cache.

The OPC Foundation's NodeSet2 XML files of DI, IA, Machinery, ISA-95 job control, Machinery Jobs,
MachineTool (OPC 40501-1) and CNC Systems (OPC 40502) are read as published, never retyped. npm's
``node-opcua-nodesets`` (MIT) ships them; ``make`` installs it into the cache directory
(``<cache>/nodesets``), or ``$NCKEMU_NODESETS`` / the machine file's ``[opcua] nodesets`` names a
directory holding them. Without them the face serves the SINUMERIK namespace alone and says in one line
how to get them (``HOW_TO_GET``).

asyncua's importer reads them in about 10 s, so a face never imports them itself: the first face (or
``python -m nckemu.emulator.faces.opcua.prepare``, which ``make`` runs) writes the standard address
space plus the imported models into a shelf beside the standard one (``shelf.py``), keyed by the files'
digest; every face then starts from that shelf as from the standard one, reading only the nodes it
touches. With the cache off (``NCKEMU_CACHE=off``) the shelf is built once per process in a temporary
directory.

Three things are left out as the files are read, and nothing else: nodes marked ``DesignToolOnly`` and
instance nodes without a parent in the address space (the CNC file's example axis
``CncInterface.CncAxisList.X``), which the importer cannot take; example instances of a file's own type
right under Objects (the CNC file's ``test``), which would stand beside the face's own instance; and default values of a file's own structured types (the CNC file's
``CncPositionDataType`` defaults), which asyncua could only decode with Python classes generated per
process. The instances' values of those types are written by ``cnc.py`` as encoded structures.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import logging
import os
import pickle
import shelve
import shutil
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from asyncua import Server, ua

from nckemu.emulator.faces.opcua import asyncua_internals
from nckemu.emulator.faces.opcua import shelf as address_cache

log = logging.getLogger("nckemu.emulator.opcua.nodesets")

# The npm package and the version make installs (its files were checked against asyncua 1.1 and 2.1).
NPM_PACKAGE = "node-opcua-nodesets"
NPM_VERSION = "2.185.0"
ENV_DIRECTORY = "NCKEMU_NODESETS"

DI = "http://opcfoundation.org/UA/DI/"
IA = "http://opcfoundation.org/UA/IA/"
MACHINERY = "http://opcfoundation.org/UA/Machinery/"
ISA95_JOBS = "http://opcfoundation.org/UA/ISA95-JOBCONTROL_V2/"
MACHINERY_JOBS = "http://opcfoundation.org/UA/Machinery/Jobs/"
MACHINE_TOOL = "http://opcfoundation.org/UA/MachineTool/"
CNC = "http://opcfoundation.org/UA/CNC"

# In import order (each after the models it requires).
FILES: tuple[tuple[str, str], ...] = (
    (DI, "Opc.Ua.Di.NodeSet2.xml"),
    (IA, "Opc.Ua.IA.NodeSet2.xml"),
    (MACHINERY, "Opc.Ua.Machinery.NodeSet2.xml"),
    (ISA95_JOBS, "opc.ua.isa95-jobcontrol.nodeset2.xml"),
    (MACHINERY_JOBS, "Opc.Ua.Machinery.Jobs.Nodeset2.xml"),
    (MACHINE_TOOL, "Opc.Ua.MachineTool.NodeSet2.xml"),
    (CNC, "Opc.Ua.CNC.NodeSet.xml"),
)
# The namespace the face's own (SINUMERIK) namespace takes in the shelf: it stays ns=2.
FACE_NAMESPACE_PLACEHOLDER = "urn:nckemu:face-namespace"
NAMESPACES_FILE = "namespaces.json"
TYPES_FILE = "types.json"   # the models' types by namespace URI and browse name (found without browsing)

_UA_NODESET = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
_UA_TYPES = "{http://opcfoundation.org/UA/2008/02/Types.xsd}"
_INVERSE_DROPPED = frozenset({ua.NodeId(ua.ObjectIds.HasTypeDefinition), ua.NodeId(ua.ObjectIds.HasModellingRule)})
_INSTANCE_TAGS = {f"{_UA_NODESET}UAObject", f"{_UA_NODESET}UAVariable", f"{_UA_NODESET}UAMethod"}


def npm_directory(root: Path) -> Path:
    return root / "nodesets" / "node_modules" / NPM_PACKAGE / "nodesets"


def how_to_get() -> str:
    root = address_cache.cache_root() or Path.home() / ".cache" / "nckemu"
    return (f"OPC UA: umati/CNC models off, their NodeSet files are not here; `make nodesets` (or `npm install "
            f"--prefix {root / 'nodesets'} {NPM_PACKAGE}@{NPM_VERSION}`, or ${ENV_DIRECTORY}=DIR) brings them")


def find(configured: str | None = None) -> Path | None:
    """The directory holding all the NodeSet files: the machine file's, ``$NCKEMU_NODESETS``, the cache's
    npm install; None when none has them all."""
    candidates: list[Path] = []
    if configured:
        candidates.append(Path(configured))
    if os.environ.get(ENV_DIRECTORY):
        candidates.append(Path(os.environ[ENV_DIRECTORY]))
    root = address_cache.cache_root()
    for base in ([root] if root is not None else []) + [Path.home() / ".cache" / "nckemu"]:
        candidates.append(npm_directory(base))  # make's install (the home cache too when the cache moved)
    for directory in candidates:
        if all((directory / name).is_file() for _uri, name in FILES):
            return directory
    return None


# Bumped when ``readable_xml`` leaves out something else: a shelf built by an older reader is not used.
READER_VERSION = 2


def digest(directory: Path) -> str:
    """What the files hold and how they are read (the shelf's name changes with either)."""
    hasher = hashlib.sha256(f"reader {READER_VERSION}".encode())
    for _uri, name in FILES:
        hasher.update(name.encode())
        hasher.update((directory / name).read_bytes())
    return hasher.hexdigest()[:16]


def readable_xml(path: Path) -> tuple[str, int]:
    """The file's text without what asyncua cannot import (module docstring); how many nodes were left out."""
    ET.register_namespace("", _UA_NODESET[1:-1])
    root = ET.parse(path).getroot()
    elements = [el for el in root if el.tag.startswith(_UA_NODESET + "UA")]
    left_out = {el.get("NodeId") for el in elements if el.get("DesignToolOnly") == "true"}
    left_out |= {el.get("NodeId") for el in elements if _example_under_objects(el)}
    # Instances that nothing kept refers to (no parent, no inverse reference, no reference to them from a
    # node that stays), and so on down: the example instances some files carry without their root.
    ids = {el.get("NodeId") for el in elements}
    holders: dict[str, set[str]] = {el.get("NodeId"): set() for el in elements if el.tag in _INSTANCE_TAGS}
    for el in elements:
        source = el.get("NodeId")
        for ref in el.iter(_UA_NODESET + "Reference"):
            target = (ref.text or "").strip()
            if ref.get("IsForward", "true") != "false":
                if target in holders:
                    holders[target].add(source)
            elif source in holders:
                holders[source].add(target)
        if source in holders and el.get("ParentNodeId"):
            holders[source].add(el.get("ParentNodeId"))
    changed = True
    while changed:
        changed = False
        for node, held_by in holders.items():
            if node in left_out:
                continue
            if all(holder in ids and holder in left_out for holder in held_by):  # none from outside the file
                left_out.add(node)
                changed = True
    for el in elements:
        if el.get("NodeId") in left_out:
            root.remove(el)
            continue
        references = el.find(_UA_NODESET + "References")
        if references is not None:
            for ref in list(references):
                if (ref.text or "").strip() in left_out:
                    references.remove(ref)
                elif ref.get("ReferenceType") == "HasSubtype" and ref.get("IsForward") == "false":
                    # asyncua takes a node's last inverse reference for its parent: a type's is its supertype
                    references.remove(ref)
                    references.append(ref)
        value = el.find(_UA_NODESET + "Value")
        if value is None:
            continue
        for extension in value.iter(_UA_TYPES + "ExtensionObject"):
            type_id = extension.find(f"{_UA_TYPES}TypeId/{_UA_TYPES}Identifier")
            if type_id is not None and (type_id.text or "").startswith("ns="):
                el.remove(value)  # a default of the file's own structure (module docstring)
                break
    return ET.tostring(root, encoding="unicode"), len(left_out)


def _example_under_objects(element: ET.Element) -> bool:
    """An object right under Objects whose type is the file's own: an example instance (the CNC file's
    ``test`` of CncInterfaceType, beside which a client would find the face's real ``CncInterface``).
    The entry points the specifications define there (DeviceSet, Machines, ...) are typed by Part 5."""
    if element.tag != _UA_NODESET + "UAObject":
        return False
    under_objects = own_type = False
    for ref in element.iter(_UA_NODESET + "Reference"):
        target = (ref.text or "").strip()
        if target == "i=85" and ref.get("IsForward") == "false":
            under_objects = True
        if ref.get("ReferenceType") == "HasTypeDefinition" and target.startswith("ns=1;"):
            own_type = True
    return under_objects and own_type


async def import_models(server: Server, directory: Path) -> int:
    """Import every file into ``server`` (after its standard address space); the nodes added."""
    added = 0
    # asyncua's importer warns about the files' quirks it works around (duplicate parents, structures it
    # does not generate classes for); they are the files', not the user's, to know.
    importer = logging.getLogger("asyncua.common.xmlimporter")
    level = importer.level
    importer.setLevel(logging.ERROR)
    try:
        for _uri, name in FILES:
            text, _left_out = readable_xml(directory / name)
            added += len(await server.import_xml(xmlstring=text, auto_load_definitions=False))
    finally:
        importer.setLevel(level)
    return added


@dataclass(frozen=True)
class ModelsShelf:
    """A shelf of the standard address space and the models, and the namespace array it was built with."""

    path: Path
    namespaces: tuple[str, ...]
    types: dict[str, str]   # "namespace URI|browse name" -> node id string


_PROCESS_SHELVES: dict[str, ModelsShelf] = {}


# Changes with what a models' shelf holds beside the nodes (its files, the way it is built).
SHELF_FORMAT = 2


def _shelf_kind(directory: Path) -> str:
    return f"models{SHELF_FORMAT}-{digest(directory)}"


def ready(directory: Path) -> ModelsShelf | None:
    """The models' shelf for these files if it was built (on disk, or in this process)."""
    kind = _shelf_kind(directory)
    if kind in _PROCESS_SHELVES:
        return _PROCESS_SHELVES[kind]
    shelf = address_cache.ready_shelf(kind)
    if shelf is None:
        return None
    try:
        namespaces = tuple(json.loads((shelf.parent / NAMESPACES_FILE).read_text(encoding="utf-8")))
        types = dict(json.loads((shelf.parent / TYPES_FILE).read_text(encoding="utf-8")))
    except (OSError, ValueError):
        address_cache.discard(shelf)
        return None
    return ModelsShelf(shelf, namespaces, types)


async def models_shelf(directory: Path) -> ModelsShelf:
    """The models' shelf for these files, built now if there is none (about 10 s, once)."""
    found = ready(directory)
    if found is not None:
        return found
    kind = _shelf_kind(directory)
    started = time.monotonic()
    log.warning("OPC UA: importing the umati/CNC NodeSets from %s into the address-space cache (once, ~10 s)",
                directory)
    building = address_cache.new_shelf(kind)
    private = building is None
    if building is None:  # the cache is off or cannot be written: once per process, in a temporary directory
        scratch = Path(tempfile.mkdtemp(prefix="nckemu-models-"))
        atexit.register(shutil.rmtree, scratch, True)
        building = scratch / address_cache.SHELF_NAME
    namespaces, types = await _build(directory, building)
    (building.parent / NAMESPACES_FILE).write_text(json.dumps(list(namespaces)), encoding="utf-8")
    (building.parent / TYPES_FILE).write_text(json.dumps(types, indent=0, sort_keys=True), encoding="utf-8")
    if private:
        building.touch()
        built = ModelsShelf(building, namespaces, types)
        _PROCESS_SHELVES[kind] = built
    else:
        address_cache.publish(building, kind)
        found = ready(directory)
        if found is None:  # published by nobody (a race lost and the winner's copy gone): use our own again
            raise OSError("the models' address-space cache could not be published")
        built = found
    log.warning("OPC UA: umati/CNC models cached in %.1f s", time.monotonic() - started)
    return built


async def _build(directory: Path, path: Path) -> tuple[tuple[str, ...], dict[str, str]]:
    """A server of our own: standard address space, the face's namespace at index 2, the models; every
    node written to the shelf at ``path``."""
    server = Server()
    standard = address_cache.ready_shelf()
    building = address_cache.new_shelf() if standard is None else None
    await server.init(standard or building)  # without a standard shelf: build that too, as a face would
    if building is not None:
        address_cache.publish(building)
    await server.register_namespace(FACE_NAMESPACE_PLACEHOLDER)
    await import_models(server, directory)
    namespaces = tuple(await server.get_namespace_array())
    nodes = server.iserver.aspace
    keys: list[Any] = list(nodes.keys())
    source = asyncua_internals.shelf_source(nodes)  # a shelf-backed address space: the nodes never touched too
    if source is not None:
        keys += [ua.NodeId.from_string(key) for key in source.keys()]
    types: dict[str, str] = {}
    type_classes = {ua.NodeClass.ObjectType, ua.NodeClass.VariableType, ua.NodeClass.DataType}
    with shelve.open(str(path), "n", protocol=pickle.HIGHEST_PROTOCOL) as out:
        for nodeid in dict.fromkeys(keys):
            node = nodes[nodeid]
            if nodeid.NamespaceIndex > 2 and node.attributes[ua.AttributeIds.NodeClass].value.Value.Value in type_classes:
                name = node.attributes[ua.AttributeIds.BrowseName].value.Value.Value
                types.setdefault(f"{namespaces[nodeid.NamespaceIndex]}|{name.Name}", nodeid.to_string())
            # asyncua's importer also gives every type the inverse references of its instances (PropertyType
            # some 900): its standard address space carries none, and loading them cost each face a second.
            node.references = [ref for ref in node.references if ref.IsForward
                               or ref.ReferenceTypeId not in _INVERSE_DROPPED]
            node.call = None
            for attribute in node.attributes.values():
                attribute.value_callback = None
                attribute.datachange_callbacks = {}
            out[nodeid.to_string()] = node
    if source is not None:
        source.close()
    return namespaces, types


async def restore_namespaces(server: Server, shelf: ModelsShelf, face_namespace: str) -> None:
    """A server started from the models' shelf gets the namespace array the shelf was built with (asyncua
    resets it at init), the face's namespace at index 2 and the server's own URI at 1."""
    current = await server.get_namespace_array()
    namespaces = list(shelf.namespaces)
    namespaces[1] = current[1]
    namespaces[2] = face_namespace
    node = server.get_node(ua.NodeId(ua.ObjectIds.Server_NamespaceArray))
    await node.write_value(ua.Variant(namespaces, ua.VariantType.String))


def npm_prefix() -> Path:
    """Where ``make nodesets`` installs the npm package."""
    return (address_cache.cache_root() or Path.home() / ".cache" / "nckemu") / "nodesets"


def main(argv: list[str] | None = None) -> int:
    """``python -m nckemu.emulator.faces.opcua.prepare``: build the models' cache now (make runs it);
    ``--prefix``: print where npm installs the files."""
    import asyncio
    import sys

    if (argv if argv is not None else sys.argv[1:]) == ["--prefix"]:
        print(npm_prefix())
        return 0

    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    logging.getLogger("asyncua").setLevel(logging.ERROR)
    directory = find()
    if directory is None:
        print(how_to_get())
        return 0
    if address_cache.cache_root() is None:
        print("OPC UA: the cache is off (NCKEMU_CACHE=off): each process imports the NodeSets itself")
        return 0
    started = time.monotonic()
    shelf = asyncio.run(models_shelf(directory))
    print(f"OPC UA: umati/CNC models ready in {shelf.path.parent} ({time.monotonic() - started:.1f} s)")
    return 0

