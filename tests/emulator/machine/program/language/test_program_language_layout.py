"""The interpreter's shape: split by job (names, control flow, calls, motion, cycles), each job typed
against what it needs of the interpreter and none importing it, no class with more than 25 methods
longer than 5 lines, and compiled expressions that read only through the public Names protocol."""

from __future__ import annotations

import ast
from pathlib import Path

from nckemu.emulator.machine.program.environment import ProgramEnvironment
from nckemu.emulator.machine.program.language import Interpreter
from nckemu.emulator.machine.program.language import expressions as expressions_module
from nckemu.emulator.machine.program.language.expressions import Names, Parser, evaluate
from nckemu.emulator.machine.program.language.lexer import tokenize

LANGUAGE = Path(expressions_module.__file__).parent
JOBS = ("names.py", "control_flow.py", "calls.py", "motion_builder.py", "cycle_runner.py", "expressions.py")
MAIN = "/_N_MPF_DIR/_N_A_MPF"


def _long_methods(cls: ast.ClassDef) -> list[str]:
    return [node.name for node in cls.body
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.end_lineno - node.lineno + 1 > 5]  # type: ignore[operator]


def test_no_class_of_the_language_has_more_than_25_methods_longer_than_5_lines() -> None:
    crowded = {}
    for path in sorted(LANGUAGE.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and len(_long_methods(node)) > 25:
                crowded[f"{path.name}:{node.name}"] = len(_long_methods(node))
    assert crowded == {}


def test_no_job_imports_the_interpreter_even_for_types() -> None:
    importing = []
    for name in JOBS:
        for node in ast.walk(ast.parse((LANGUAGE / name).read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("interpreter"):
                importing.append(name)
    assert importing == []


def test_compiled_expressions_call_only_the_names_protocol() -> None:
    """Every ``ev.<name>`` in a closure the parser or the resolver builds is a method of Names."""
    protocol = {name for name in vars(Names) if not name.startswith("_")}
    called = set()
    for name in ("expressions.py", "names.py"):
        for node in ast.walk(ast.parse((LANGUAGE / name).read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "ev":
                called.add(node.attr)
    assert called, "the walk found no reads through ev"
    assert called <= protocol, f"not in the Names protocol: {called - protocol}"


def test_an_expression_reads_the_names_it_is_called_with() -> None:
    """A compiled expression holds no interpreter: the same closure gives each run's own values."""
    first_env, second_env = ProgramEnvironment(), ProgramEnvironment()
    first_env.set_r_parameter(1, 2.0)
    second_env.set_r_parameter(1, 5.0)
    first, second = Interpreter(first_env, MAIN, "M30"), Interpreter(second_env, MAIN, "M30")
    expression = Parser(tokenize("R1 * 10 + R[1]"), first.names.resolve).expression()
    assert evaluate(expression, first.names) == 22.0
    assert evaluate(expression, second.names) == 55.0
