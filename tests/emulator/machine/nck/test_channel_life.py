"""The channel's program life table (nck/channel_life.py): every place is reachable from reset, every
place can be reset and ended, and only the channel moves along it."""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.machine.nck.channel import ChannelState, Spindle
from nckemu.emulator.machine.nck.channel_life import TRANSITIONS, Event, Life, LifeError, next_life
from nckemu.emulator.machine.nck.channel_states import CHAN_RESET, PROG_ABORTED

PACKAGE = Path(__file__).resolve().parents[4] / "nckemu"
CHANNEL_MODULE = "emulator/machine/nck/channel.py"


def test_every_place_is_reached_from_reset_and_left_by_reset_and_end() -> None:
    reached, frontier = {Life.RESET}, [Life.RESET]
    while frontier:
        where = frontier.pop()
        for (source, _event), (target, _told) in TRANSITIONS.items():
            if source is where and target not in reached:
                reached.add(target)
                frontier.append(target)
    assert reached == set(Life)
    for where in Life:
        assert next_life(where, Event.END)[0] is Life.ENDED
        assert next_life(where, Event.RESET)[0].at_rest


def test_reset_and_ended_report_alike_as_btss_does() -> None:
    assert Life.RESET.reported == Life.ENDED.reported == (CHAN_RESET, PROG_ABORTED)
    assert len({life.reported for life in Life}) == len(Life) - 1


@given(st.sampled_from(list(Life)), st.sampled_from(list(Event)))
def test_a_change_is_in_the_table_or_an_error(where: Life, event: Event) -> None:
    if (where, event) in TRANSITIONS:
        target, told = next_life(where, event)
        assert target in Life and (told is None or told in ("started", "resumed", "interrupted", "ended", "aborted"))
    else:
        with pytest.raises(LifeError):
            next_life(where, event)


def test_only_the_channel_writes_its_status() -> None:
    writes = re.compile(r"\.(?:status|program_status)\s*(?:,[^=\n]*)?=(?!=)")
    writers = {path.relative_to(PACKAGE).as_posix() for path in PACKAGE.rglob("*.py")
               if any(writes.search(line) and "state." in line for line in path.read_text(encoding="utf-8").splitlines())}
    assert writers <= {"emulator/machine/nck/channel.py"}, writers


def _state_writes(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, field) of every assignment to a ChannelState field in ``tree``: ``x.state.field = ...``
    (``+=``, tuple targets), through a name bound to ``x.state`` in the same function, and
    ``setattr(x.state, ...)``; and of a Spindle's field (the spindles are the channel's state too) on
    anything but ``self``, by assignment or ``setattr(x, "field", ...)``."""
    fields = {field.name for field in dataclasses.fields(ChannelState)}
    spindle_fields = {field.name for field in dataclasses.fields(Spindle)}
    found = []
    for function in ast.walk(tree):
        if not isinstance(function, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            continue
        aliases = {target.id for node in ast.walk(function)
                   if isinstance(node, ast.Assign) and isinstance(node.value, ast.Attribute) and node.value.attr == "state"
                   for target in node.targets if isinstance(target, ast.Name)}

        def is_state(node: ast.expr, aliases: set[str] = aliases) -> bool:
            return (isinstance(node, ast.Attribute) and node.attr == "state") or (
                isinstance(node, ast.Name) and node.id in aliases)

        for node in ast.walk(function):
            targets: list[ast.expr] = []
            if isinstance(node, ast.Assign):
                for target in node.targets:
                    targets += target.elts if isinstance(target, ast.Tuple) else [target]
            elif isinstance(node, ast.AugAssign | ast.AnnAssign):
                targets = [node.target]
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "setattr":
                if node.args and is_state(node.args[0]):
                    found.append((node.lineno, "setattr"))
                elif len(node.args) > 1 and isinstance(node.args[1], ast.Constant) and node.args[1].value in spindle_fields:
                    found.append((node.lineno, f"setattr {node.args[1].value}"))
            for target in targets:
                if not isinstance(target, ast.Attribute):
                    continue
                if (target.attr in fields and is_state(target.value)) or (
                        target.attr in spindle_fields and not (isinstance(target.value, ast.Name) and target.value.id == "self")):
                    found.append((node.lineno, target.attr))
    return found


def test_only_the_channel_assigns_its_state() -> None:
    """Runs, sources and the model tell the channel (show_block, set_tool, set_figure, command_spindle ...);
    none assigns a field of ChannelState or of a spindle itself."""
    writers = {}
    for path in PACKAGE.rglob("*.py"):
        name = path.relative_to(PACKAGE).as_posix()
        writes = _state_writes(ast.parse(path.read_text(encoding="utf-8")))
        if writes and name != CHANNEL_MODULE:
            writers[name] = writes
    assert writers == {}


def test_the_state_check_sees_the_ways_a_field_is_assigned() -> None:
    code = """
def f(channel, value):
    channel.state.message = "x"
    state = channel.state
    state.t_number, state.d_number = 1, 2
    state.actual_parts += 1
    setattr(channel.state, "total_parts", value)
    channel.state.spindles[1].ramp = None
    setattr(channel.spindle(1), "override_pct", value)
    other.message = "not a state"
    self.direction = 1
"""
    assert sorted(field for _, field in _state_writes(ast.parse(code))) == [
        "actual_parts", "d_number", "message", "ramp", "setattr", "setattr override_pct", "t_number"]
    channel = _state_writes(ast.parse((PACKAGE / CHANNEL_MODULE).read_text(encoding="utf-8")))
    assert {"status", "program_status", "message", "t_number"} <= {field for _, field in channel}
