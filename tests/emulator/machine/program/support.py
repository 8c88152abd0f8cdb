"""What the language tests share: an environment with programs in a dict, and a runner that moves
the axes to each motion's end before asking for the next event (as the channel does)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from nckemu.catalogue.program_names import program_path
from nckemu.emulator.machine.program.environment import ProgramEnvironment, UndefinedName
from nckemu.emulator.machine.program.language import Interpreter
from nckemu.emulator.machine.program.motions import Arc, Block, Event, Move, ProgramAlarm

MAIN = "/_N_MPF_DIR/_N_TEST_MPF"


class DictEnvironment(ProgramEnvironment):
    """Programs by user name (``SUB.SPF``), system variables in a dict, positions that follow moves."""

    def __init__(self, programs: dict[str, str] | None = None, axes: Sequence[str] = ("X", "Y", "Z", "A", "B", "C"),
                 system: dict[str, object] | None = None, offsets: dict[str, dict[str, float]] | None = None,
                 tool_lengths: dict[tuple[object, int], float] | None = None) -> None:
        super().__init__(axes=axes)
        self.programs = {program_path(name, default_type="SPF"): text for name, text in (programs or {}).items()}
        self.system = dict(system or {})
        self.offsets = offsets or {}
        self.tool_lengths = tool_lengths or {}

    def find_program(self, name: str, caller: str) -> tuple[str, str] | None:
        for kind in ("SPF", "MPF"):
            path = program_path(f"{name}.{kind}")
            if path in self.programs:
                return path, self.programs[path]
        return None

    def system_variable(self, name: str, indices: tuple[object, ...] = ()) -> object:
        if name in self.system:
            return self.system[name]
        raise UndefinedName(name)

    def set_system_variable(self, name: str, indices: tuple[object, ...], value: object) -> None:
        if name not in self.system:
            raise UndefinedName(name)
        self.system[name] = value

    def work_offset_mm(self, frame: str, axis: str) -> float:
        return self.offsets.get(frame, {}).get(axis, 0.0)

    def set_work_offset_mm(self, frame: str, axis: str, value_mm: float) -> None:
        self.offsets.setdefault(frame, {})[axis] = value_mm

    def tool_length_mm(self, tool: int | str | None, edge: int | None) -> float:
        return self.tool_lengths.get((tool, edge or 0), 0.0)

    def arrive(self, event: Event) -> None:
        if isinstance(event, Move | Arc):
            self._position_mm.update(event.target_mm)


@dataclass
class Run:
    events: list[Event] = field(default_factory=list)
    alarm: ProgramAlarm | None = None

    def of(self, kind: type) -> list:
        return [event for event in self.events if isinstance(event, kind)]

    @property
    def blocks(self) -> list[Block]:
        return self.of(Block)

    @property
    def moves(self) -> list[Move | Arc]:
        return [event for event in self.events if isinstance(event, Move | Arc)]


def run(text: str, env: DictEnvironment | None = None, *, path: str = MAIN, limit: int = 1_000_000) -> Run:
    """Every event of ``text`` (to its end, its alarm, or ``limit`` events)."""
    env = env or DictEnvironment()
    result = Run()
    try:
        for event in Interpreter(env, path, text).events():
            result.events.append(event)
            env.arrive(event)
            if len(result.events) >= limit:
                break
    except ProgramAlarm as alarm:
        result.alarm = alarm
    return result
