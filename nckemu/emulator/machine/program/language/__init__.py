"""A throwaway stand-in for the interpreter (branch ``interp`` writes the real one; it replaces this
file at merge). It knows just enough to develop the channel against: ``;`` comments, ``N`` numbers,
labels, ``GOTOB``/``GOTOF``, R parameters with + - * /, G0 G1 G4 G90 G91 G60 G64 G70 G71 G700 G710 G94
SUPA, axis words, F, S, M0 M1 M2 M3 M4 M5 M30, MSG and subprogram calls by name without arguments."""

from __future__ import annotations

import re
from collections.abc import Iterator

from nckemu.emulator.machine.program.environment import ProgramEnvironment
from nckemu.emulator.machine.program.motions import (
    ALARM_JUMP_TARGET,
    ALARM_PROGRAM_NOT_FOUND,
    ALARM_SYNTAX,
    Block,
    Dwell,
    Event,
    Message,
    MFunction,
    Move,
    ProgramAlarm,
    ProgramEnd,
    SpindleCommand,
)

_WORD = re.compile(r"([A-Z]+)\s*=?\s*(-?[0-9.]+|R[0-9]+)")
_ASSIGN = re.compile(r"R(\d+)\s*=\s*(.+)")
INCH_MM = 25.4


class Interpreter:
    def __init__(self, env: ProgramEnvironment, path: str, text: str) -> None:
        self.env, self.path, self.text = env, path, text
        self.absolute, self.inch, self.inch_feed, self.motion, self.feed, self.exact = True, False, False, 0, 0.0, True

    def events(self) -> Iterator[Event]:
        yield from self._run(self.path, self.text, 0)
        yield ProgramEnd(0)

    def _run(self, path: str, text: str, depth: int) -> Iterator[Event]:
        lines = text.splitlines()
        labels = {}
        for index, raw in enumerate(lines):
            match = re.match(r"\s*(?:N\d+\s+)?([A-Z_][A-Z0-9_]*):", raw.upper())
            if match:
                labels[match.group(1)] = index
        index = 0
        while index < len(lines):
            raw = lines[index]
            code = raw.split(";", 1)[0].strip().upper()
            line = index + 1
            index += 1
            if not code:
                continue
            number = ""
            match = re.match(r"N(\d+)\s*", code)
            if match:
                number, code = f"N{match.group(1)}", code[match.end():]
            match = re.match(r"([A-Z_][A-Z0-9_]*):\s*", code)
            if match:
                code = code[match.end():]
            yield Block(path, line, number, raw.split(";", 1)[0].strip(), depth)
            if not code:
                continue

            def alarm(n: int, message: str) -> ProgramAlarm:
                return ProgramAlarm(n, message, program=path, line=line, block=number)  # noqa: B023

            jump = re.match(r"GOTO([BF]?)\s+([A-Z_][A-Z0-9_]*)$", code)
            if jump:
                if jump.group(2) not in labels:
                    raise alarm(ALARM_JUMP_TARGET, f"jump destination {jump.group(2)} not found")
                index = labels[jump.group(2)]
                continue
            assign = _ASSIGN.fullmatch(code)
            if assign:
                self.env.set_r_parameter(int(assign.group(1)), self._value(assign.group(2), alarm))
                continue
            message = re.fullmatch(r'MSG\s*\(\s*"(.*)"\s*\)', raw.split(";", 1)[0].strip(), re.IGNORECASE)
            if message:
                yield Message(message.group(1))
                continue
            if re.fullmatch(r"[A-Z_][A-Z0-9_]*(\(\))?", code) and not _WORD.fullmatch(code):
                found = self.env.find_program(code.rstrip("()"), path)
                if found is None:
                    raise alarm(ALARM_PROGRAM_NOT_FOUND, f"program {code} not existing")
                yield from self._run(found[0], found[1], depth + 1)
                continue
            yield from self._words(code, alarm)

    def _value(self, text: str, alarm: object) -> float:
        def term(match: re.Match[str]) -> str:
            return repr(self.env.r_parameter(int(match.group(1))))
        expression = re.sub(r"R(\d+)", term, text.strip())
        if not re.fullmatch(r"[0-9.+\-*/() e]+", expression):
            raise alarm(ALARM_SYNTAX, f"cannot read {text!r}")  # type: ignore[operator]
        try:
            return float(eval(expression, {"__builtins__": {}}))  # noqa: S307 - digits and operators only
        except ZeroDivisionError:
            raise alarm(14051, "arithmetic error: division by zero") from None  # type: ignore[operator]
        except SyntaxError:
            raise alarm(ALARM_SYNTAX, f"cannot read {text!r}") from None  # type: ignore[operator]

    def _words(self, code: str, alarm: object) -> Iterator[Event]:
        rest = _WORD.sub("", code).replace("SUPA", "").strip()
        if rest:
            raise alarm(ALARM_SYNTAX, f"syntax error: {rest!r}")  # type: ignore[operator]
        target: dict[str, float] = {}
        dwell = False
        spindle_speed: float | None = None
        direction = None
        m_codes: list[int] = []
        for letter, raw_value in _WORD.findall(code):
            value = self.env.r_parameter(int(raw_value[1:])) if raw_value.startswith("R") else float(raw_value)
            if letter == "G":
                g = int(value)
                if g in (0, 1):
                    self.motion = g
                elif g == 4:
                    dwell = True
                elif g in (90, 91):
                    self.absolute = g == 90
                elif g in (70, 71):
                    self.inch = g == 70
                elif g in (700, 710):
                    self.inch = self.inch_feed = g == 700
                elif g in (60, 64):
                    self.exact = g == 60
            elif letter == "F":
                if dwell:
                    yield Dwell(seconds=value)
                else:
                    self.feed = value * (INCH_MM if self.inch_feed else 1.0)
            elif letter == "S":
                if dwell:
                    yield Dwell(spindle_revolutions=value)
                else:
                    spindle_speed = value
            elif letter == "M":
                m = int(value)
                if m in (3, 4, 5):
                    direction = f"M{m}"
                else:
                    m_codes.append(m)
            elif letter in self.env.axes:
                scale = INCH_MM if self.inch else 1.0
                base = 0.0 if self.absolute else self.env.machine_position_mm(letter)
                target[letter] = base + value * scale
            else:
                raise alarm(ALARM_SYNTAX, f"unknown address {letter}")  # type: ignore[operator]
        if spindle_speed is not None or direction is not None:
            yield SpindleCommand(1, spindle_speed, direction)  # type: ignore[arg-type]
        if target:
            yield Move(target, None if self.motion == 0 else self.feed, exact_stop=self.exact)
        for m in m_codes:
            yield MFunction(m)
            if m in (2, 30):
                yield ProgramEnd(m)
                return
