"""Import circles in the package, counted as bar-style checks count them: every ``import`` and ``from ...
import`` of a module, those under ``if TYPE_CHECKING:`` included (a type import is still a dependency a
reader has to hold in mind). import-linter's contracts (pyproject.toml) keep the layers apart; this keeps
the rooms inside a layer free of circles.

The circles that stand today are listed in KNOWN_CIRCLES, each with the issue that untangles it: the list
may only shrink. A new circle fails the test, and so does a listed one that is gone (take it off the list).
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "nckemu"

# Each circle that stands today, named by one module it holds, with the most modules it may hold and what
# untangles it. A circle that grows past its size, or one not listed, fails; so does a listed one that is
# gone (take it off: the list only shrinks).
KNOWN_CIRCLES: dict[str, tuple[int, str]] = {
    "nckemu.emulator.machine.nck.parts": (
        14, "every part of the machine is handed the whole NCK (NckParts) and names its type: issue 52 item 4, "
            "a narrow protocol per part"),
    "nckemu.thermal.discovery.selector": (
        2, "the selector asks explain for words and explain reads the selector's records: issue 52 item 5"),
}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(path: Path, known: set[str]) -> set[str]:
    """The package's modules that ``path`` imports (a ``from X import name`` counts X.name where that is a
    module of its own, else X)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    here = module_name(path)
    package = here if path.name == "__init__.py" else here.rsplit(".", 1)[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names if alias.name in known)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base_parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(base_parts + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            for alias in node.names:
                if f"{base}.{alias.name}" in known:
                    found.add(f"{base}.{alias.name}")
                elif base in known:
                    found.add(base)
    found.discard(here)
    return found


def import_graph() -> dict[str, set[str]]:
    files = {module_name(path): path for path in PACKAGE.rglob("*.py")}
    known = set(files)
    return {name: imported_modules(path, known) for name, path in files.items()}


def circles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found: list[frozenset[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(frozenset(component))
    return found


def test_the_counter_finds_a_circle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert circles(graph) == [frozenset({"a", "b", "c"})]


def test_no_circle_but_the_known_ones() -> None:
    """core and saves imported each other until saves asked for a protocol."""
    found = circles(import_graph())
    known = {name: next((c for c in found if name in c), None) for name in KNOWN_CIRCLES}
    new = [sorted(circle) for circle in found if circle not in known.values()]
    grown = [sorted(circle) for name, circle in known.items() if circle and len(circle) > KNOWN_CIRCLES[name][0]]
    gone = [KNOWN_CIRCLES[name][1] for name, circle in known.items() if circle is None]
    assert not new, f"new import circles: {new}"
    assert not grown, f"known circles grown: {grown}"
    assert not gone, f"circles untangled, take them off KNOWN_CIRCLES: {gone}"
    assert not any("nckemu.emulator.machine.saves" in circle for circle in found)
