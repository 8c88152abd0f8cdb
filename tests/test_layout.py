"""The package's shape: no module imports itself back at run time, no circle once type imports
count (bar-style checks count them: a type import is still a dependency a reader has to hold in mind)
but the known ones, which may only shrink, and no class with more than 25 methods longer than 5 lines.

import-linter (``make lint``) checks the layers and, in its ``acyclic`` contract (acyclic_siblings,
type imports counted), that no siblings at any level of the package import each other round. It
compares siblings only: a package's ``__init__`` and a module inside it importing each other (plc/
``__init__`` -> memory -> channel_signals -> plc/``__init__``) are parent and child, and pass it. So the
module graph is walked here as well (grimp, which import-linter uses).
"""

from __future__ import annotations

import ast
from pathlib import Path

import grimp

import nckemu

# The developers' rule: no class with more than this many methods longer than 5 lines (def to its last line).
MOST_LONG_METHODS = 25


def strongly_connected(graph: grimp.ImportGraph) -> list[list[str]]:
    """Tarjan's strongly connected components of the module graph with more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0

    def visit(root: str) -> None:
        nonlocal counter
        work = [(root, iter(sorted(graph.find_modules_directly_imported_by(root))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            module, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.find_modules_directly_imported_by(child)))))
                    break
                if child in on_stack:
                    low[module] = min(low[module], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[module])
                if low[module] == index[module]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == module:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))

    for module in sorted(graph.modules):
        if module not in index:
            visit(module)
    return found


def test_no_import_circles_at_run_time() -> None:
    graph = grimp.build_graph("nckemu", exclude_type_checking_imports=True, cache_dir=None)
    assert strongly_connected(graph) == []


def test_the_walk_finds_a_circle() -> None:
    graph = grimp.ImportGraph()
    for module in ("a", "a.b", "a.c", "a.d"):
        graph.add_module(module)
    graph.add_import(importer="a.b", imported="a.c")
    graph.add_import(importer="a.c", imported="a.b")
    graph.add_import(importer="a.c", imported="a.d")
    assert strongly_connected(graph) == [["a.b", "a.c"]]


def test_the_opcua_face_parts_form_no_circle_even_under_type_checking() -> None:
    """Each part of the OPC UA face is typed against a protocol of ``parts.py``, never the face itself."""
    graph = grimp.build_graph("nckemu", exclude_type_checking_imports=False, cache_dir=None)
    package = "nckemu.emulator.faces.opcua"
    circles = [component for component in strongly_connected(graph)
               if any(module.startswith(package + ".") for module in component)]
    assert circles == []
    face_importers = {module for module in graph.find_modules_that_directly_import(f"{package}.face")}
    assert face_importers <= {package}, "only the package imports the face; its parts do not"


# Each circle that stands today once type imports count, named by one module it holds, with the most
# modules it may hold and what untangles it. A circle that grows past its size, or one not listed, fails;
# so does a listed one that is gone (take it off: the list only shrinks). None stands today.
KNOWN_TYPE_CIRCLES: dict[str, tuple[int, str]] = {}


def test_no_circle_with_type_imports_but_the_known_ones() -> None:
    """core and saves imported each other until saves asked for a protocol (RetainedSource)."""
    found = strongly_connected(grimp.build_graph("nckemu", exclude_type_checking_imports=False, cache_dir=None))
    known = {name: next((c for c in found if name in c), None) for name in KNOWN_TYPE_CIRCLES}
    new = [circle for circle in found if circle not in known.values()]
    grown = [circle for name, circle in known.items() if circle and len(circle) > KNOWN_TYPE_CIRCLES[name][0]]
    gone = [KNOWN_TYPE_CIRCLES[name][1] for name, circle in known.items() if circle is None]
    assert not new, f"new import circles: {new}"
    assert not grown, f"known circles grown: {grown}"
    assert not gone, f"circles untangled, take them off KNOWN_TYPE_CIRCLES: {gone}"
    assert not any("nckemu.emulator.machine.saves" in circle for circle in found)


def long_methods(cls: ast.ClassDef) -> list[str]:
    """The methods of ``cls`` longer than 5 lines, from ``def`` to their last line."""
    return [node.name for node in cls.body if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and node.end_lineno is not None and node.end_lineno - node.lineno + 1 > 5]


def crowded_classes(root: Path) -> dict[str, int]:
    """Every class under ``root`` with more than ``MOST_LONG_METHODS`` long methods, and how many."""
    crowded = {}
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and len(long_methods(node)) > MOST_LONG_METHODS:
                crowded[f"{path.relative_to(root.parent)}:{node.name}"] = len(long_methods(node))
    return crowded


def test_no_class_has_more_than_25_methods_longer_than_5_lines() -> None:
    assert crowded_classes(Path(nckemu.__file__).parent) == {}


def test_the_count_finds_a_crowded_class(tmp_path: Path) -> None:
    package = tmp_path / "package"
    package.mkdir()
    long_body = "\n".join(f"        x{line} = {line}" for line in range(5))
    methods = "\n".join(f"    def m{index}(self) -> None:\n{long_body}\n" for index in range(26))
    short = "\n".join(f"    def s{index}(self) -> None:\n        pass\n" for index in range(30))
    (package / "crowded.py").write_text(f"class Crowded:\n{methods}\n\nclass Roomy:\n{short}\n")
    assert crowded_classes(package) == {"package/crowded.py:Crowded": 26}
