"""Channel state: what a channel reports about its program run (status, parts, tools, feed, times), and
the small interface every way in uses to run a program: select, unselect, start, stop, reset, mode.

The values HMIs and collectors poll from module S (0x7F), SSP (0x72), SPARP (0x7D) and DIAGN (0x3B).
A channel is reset until it is started; the net program time runs while it is active; the end of a
program counts a part. PI ``_N_SELECT``, OPC UA ``Select``, the PLC's ``DB21.DBX7.x`` edges and the
extension variable ``NCKEMU_CHAN_COMMAND`` all end in the same calls. The program itself runs in
:mod:`nckemu.emulator.machine.nck.program_run`, one cycle at a time (:meth:`Channel.step`).

Value meanings (sources in ``catalogue/variables.toml``, docs/programs.md): chanStatus 0 reset,
1 active, 2 interrupted (two sources); progStatus 1 interrupted, 2 stopped, 3 running, 4 waiting,
5 aborted (2, 3, 5 one source; 1 and 4 unconfirmed); acProg 0 reset, 1 stopped, 2 running, 3 waiting,
4 interrupted (one source); opMode 0 JOG, 1 MDA, 2 AUTOMATIC.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from nckemu.emulator.machine.clock import Clock
from nckemu.emulator.machine.nck.channel_life import Event, Life, next_life
from nckemu.emulator.machine.nck.channel_states import (  # noqa: F401 (also imported from here)
    AC_INTERRUPTED,
    AC_RESET,
    AC_RUNNING,
    AC_STOPPED,
    AC_WAITING,
    CHAN_ACTIVE,
    CHAN_INTERRUPTED,
    CHAN_RESET,
    MODE_AUTOMATIC,
    MODE_JOG,
    MODE_MDA,
    MODE_NAMES,
    PROG_ABORTED,
    PROG_INTERRUPTED,
    PROG_RUNNING,
    PROG_STOPPED,
    PROG_WAITING,
)
from nckemu.emulator.machine.nck.programs import program_text
from nckemu.emulator.machine.program.motions import Block, ProgramAlarm
from nckemu.emulator.machine.program.planner import SpindleRamp
from nckemu.errors import NckAddressOutOfRange, NckError, NckItemError, NckNoSuchFile, NckPiStateError

if TYPE_CHECKING:
    from nckemu.emulator.machine.machine_file import Machine
    from nckemu.emulator.machine.nck.alarms import Alarms
    from nckemu.emulator.machine.nck.programs import Programs
    from nckemu.emulator.machine.program.block_record import BlockRecord

log = logging.getLogger("nckemu.emulator.nck.channel")

# NCKEMU_CHAN_COMMAND values
COMMAND_RESET, COMMAND_START, COMMAND_STOP, COMMAND_END_PROGRAM = 0, 1, 2, 3
# turnState (unconfirmed: the sources give no enumeration): 0 stopped, 1 clockwise M3, 2 counter-clockwise M4
TURN_STOPPED, TURN_CW, TURN_CCW = 0, 1, 2
# What on_change listeners are told.
CHANGES = ("selected", "unselected", "started", "interrupted", "resumed", "ended", "aborted")
# The figures of ChannelState others may set (a client through the catalogue, a program through its
# system variables): the part counters, the overrides and the commanded feed.
SETTABLE_FIGURES = frozenset({"required_parts", "total_parts", "actual_parts", "specified_parts",
                              "feed_override_pct", "rapid_override_pct", "commanded_feed_mm_min"})


class ChannelParts(Protocol):
    """What a channel uses of the NCK: the program store (select, read, what runs), the alarm list (its
    program alarms and refusals) and the machine's program settings. Not the whole NCK (``parts.NckParts``
    names the channel among its parts): the channel and the NCK would import each other."""

    @property
    def machine(self) -> Machine: ...

    @property
    def programs(self) -> Programs: ...

    @property
    def alarm_list(self) -> Alarms: ...


class ChannelRun(Protocol):
    """What the channel asks of its program run (program_run.py's ProgramRun). A protocol, and the run
    handed in as a factory by the model, so the channel does not import the run, which is typed against
    the whole NCK (issue 52: no circle through the channel)."""

    t_s: float            # the simulated time the run has reached
    ended: bool
    blocks: int           # blocks executed so far
    notes: list[str]      # what the run did other than programmed
    not_simulated: dict[str, int]

    def advance(self, until_s: float, max_blocks: int) -> str: ...

    def pause(self, now_s: float) -> None: ...

    def resume(self, now_s: float) -> None: ...

    def close(self, now_s: float) -> None: ...

    def programs_in_use(self) -> frozenset[str]: ...


# (channel, program path, program text, start time) -> the run; the model binds the NCK the run works on
RunFactory = Callable[["Channel", str, str, float], ChannelRun]


@dataclass
class Spindle:
    commanded_rpm: float = 0.0
    override_pct: float = 100.0
    direction: int = TURN_STOPPED
    # An actual speed measured on the machine (plc run --inputs drives it from a recording's
    # spindle_rpm): when set, actSpeed reports it whatever the channel and the commanded speed say.
    measured_rpm: float | None = None
    # Set while a program drives the spindle: its speed ramps (program_run.py), whatever the channel's status.
    ramp: SpindleRamp | None = None


@dataclass
class ChannelState:
    status: int = CHAN_RESET
    program_status: int = PROG_ABORTED
    feed_override_pct: float = 100.0
    rapid_override_pct: float = 100.0
    commanded_feed_mm_min: float = 0.0
    t_number: int = 0
    d_number: int = 0
    tool_ident: str = ""
    required_parts: float = 0.0
    total_parts: float = 0.0
    actual_parts: float = 0.0
    specified_parts: float = 0.0
    old_net_time_s: float = 0.0
    cutting_time_s: float = 0.0
    spindles: dict[int, Spindle] = field(default_factory=dict)
    # What the program run shows (SPARP/SPARPP, S columns 20/251/252)
    mode: int = MODE_AUTOMATIC
    message: str = ""
    block_number: str = ""
    line_number: int = 0
    block_text: str = ""
    program: str = ""                 # the program the current block belongs to (a subprogram too)
    start_counter: int = 0
    end_counter: int = 0
    reset_counter: int = 0
    path_feed_mm_min: float = 0.0     # the path speed of the motion under way (0 when none)


class Channel:
    """One channel's run state on the emulator's clock, and its program run."""

    def __init__(self, number: int, clock: Clock, spindles: int, parts: ChannelParts,
                 start_run: RunFactory) -> None:
        self.number = number
        self._clock = clock
        self.state = ChannelState(spindles={n: Spindle() for n in range(1, spindles + 1)})
        self._net_s = 0.0
        self._running_since: float | None = None
        self.parts = parts   # the program store, the alarm list and the program settings
        self.selected = ""
        # The NC path a run without a program is shown under (a recording's run: progName and the
        # program of the current block name it); kept after its end, as a selection is, until a select.
        self.recorded_program = ""
        self._start_run = start_run       # makes a run of a selected program (the model hands ProgramRun)
        self.run: ChannelRun | None = None
        self.last_run_blocks = 0          # blocks the last run executed (program run offline)
        # Where the program is (channel_life.py's table); state.status and state.program_status report it.
        self.life = Life.RESET
        self.last_run_notes: list[str] = []   # and what it did other than programmed (run.notes)
        # The net time of the last complete run (ended by M2/M30 or its last block, not by reset) of each
        # program: path -> (hash of its text, seconds), what time_left_s counts down from. A changed text
        # is another program (its old time says nothing about it) and replaces the entry.
        self.completed_runs_s: dict[str, tuple[int, float]] = {}
        self._run_key: tuple[str, int] | None = None
        self._alarms: list[str] = []      # program alarms: the run stopped, reset clears them
        self._notices: list[str] = []     # refusals (NC start, mode): cleared by reset or the next start
        # Told of each change of the program's life, with one of CHANGES (the OPC UA face's umati states).
        self.on_change: list[Callable[[str], None]] = []
        # Told after every change of status, program status or mode (the PLC's DB21.DBB35, DB11.DBB6).
        self.state_listeners: list[Callable[[Channel], None]] = []
        # Told of every executed block (program run offline: the block table).
        self.block_listeners: list[Callable[[BlockRecord], None]] = []

    @property
    def ended_normally(self) -> bool:
        """progStatus 5 says "aborted" after a reset and after the program's end alike (BTSS has no
        "ended"): True when the last run reached its end, for the faces that can say so (live page)."""
        return self.life is Life.ENDED

    # ------------------------------------------------------------------ the interface every face uses
    def select(self, path: str) -> None:
        """Select ``path`` for execution (only in reset). NckNoSuchFile without such a program."""
        parts = self.parts
        if not path.startswith("/"):
            from nckemu.catalogue.program_names import program_path

            path = program_path(path)
        if self.state.status != CHAN_RESET:
            raise NckPiStateError(f"channel {self.number} is not in reset: a program is selected only in reset")
        if not parts.programs.exists(path):
            raise NckNoSuchFile(f"no program {path}")
        self.selected = path
        self.recorded_program = ""
        if self.number == 1:
            parts.programs.select(path)
        self._tell("selected")
        self._tell_state()

    def unselect(self) -> None:
        if self.state.status != CHAN_RESET:
            raise NckPiStateError(f"channel {self.number} is not in reset")
        if not self.selected:
            raise NckPiStateError(f"channel {self.number} has no program selected")
        self.selected = ""
        if self.number == 1:
            self.parts.programs.selected = ""
        self._tell("unselected")
        self._tell_state()

    def start(self) -> None:
        """NC start: from reset the selected program starts; interrupted, it resumes. Refused (an
        alarm, NckPiStateError) in JOG, with nothing selected, or with a program alarm pending."""
        if self.state.status == CHAN_ACTIVE:
            return
        settings = self.parts.machine.program
        if self.state.mode == MODE_JOG:
            self._refuse(settings.start_refused_alarm, "NC start not possible in JOG")
        if self._alarms:
            self._refuse(settings.start_refused_alarm, "NC start not possible: reset the channel's alarm first")
        self._clear_alarms(self._notices)
        now = self._clock.now_s()
        if self.state.status == CHAN_INTERRUPTED:
            if self.run is not None:
                self.run.resume(now)
            self._begin_timing(now)
            self.state.start_counter += 1
            self._enter(Event.RESUME)
            return
        if not self.selected:
            self._refuse(settings.start_refused_alarm, "NC start not possible: no program selected")
        try:
            text = self.parts.programs.read(self.selected)
        except NckNoSuchFile:
            self._refuse(settings.start_refused_alarm, f"NC start not possible: {self.selected} no longer exists")
        self.run = self._start_run(self, self.selected, program_text(text), now)
        self._run_key = (self.selected, hash(text))
        if self.number == 1:
            self.parts.programs.running = self.selected
            self.parts.programs.called = self.run.programs_in_use
        self._net_s = 0.0
        self._begin_timing(now)
        self.state.message = ""
        self.state.start_counter += 1
        self._enter(Event.START)

    def stop(self) -> None:
        """NC stop: the run holds where it is (motion and dwell resume where they stopped)."""
        if not self.life.active:
            return
        self._interrupt(Event.STOP)

    def reset(self) -> None:
        """Reset: the run is aborted, alarms of the run are cleared, the spindle stops."""
        self._hold()
        if not self.life.at_rest:
            self.state.old_net_time_s = self._net_s
        self._finish_run()
        self._clear_alarms(self._alarms)
        self._clear_alarms(self._notices)
        self.state.reset_counter += 1
        self._enter(Event.RESET)

    def set_mode(self, mode: int) -> None:
        """AUTOMATIC (2), MDA (1) or JOG (0); refused (an alarm, NckPiStateError) while a program runs."""
        if mode not in MODE_NAMES:
            raise NckItemError(f"operating mode {mode} is not 0 (JOG), 1 (MDA) or 2 (AUTOMATIC)", return_code=0x05)
        if mode == self.state.mode:
            return
        if self.state.status == CHAN_ACTIVE:
            self._refuse(self.parts.machine.program.mode_refused_alarm, f"mode change to {MODE_NAMES[mode]} not possible while a program runs")
        self.state.mode = mode
        self._tell_state()

    # ------------------------------------------------------------------ the older commands
    def command(self, value: int) -> None:
        """NCKEMU_CHAN_COMMAND: 0 reset, 1 start (the selected program, or a run without one), 2 stop,
        3 end of program."""
        actions = {COMMAND_RESET: self.reset, COMMAND_START: self._command_start, COMMAND_STOP: self.stop,
                   COMMAND_END_PROGRAM: self.end_program}
        action = actions.get(value)
        if action is None:
            raise NckItemError(f"channel command {value} is not one of {sorted(actions)}", return_code=0x05)
        action()

    def _command_start(self) -> None:
        if self.selected or self.state.status == CHAN_INTERRUPTED and self.run is not None:
            self.start()
        else:
            self.run_without_program()

    def run_without_program(self, shown_as: str = "") -> None:
        """The channel active with no program (a recording says the machine works): times and counters
        run, nothing executes. ``shown_as``: the NC path the faces name the run by (nothing is stored
        under it; a program selected in the channel names it instead)."""
        if self.life.at_rest:
            self._net_s = 0.0
        if shown_as:
            self.recorded_program = shown_as
        if self.run is None and self.recorded_program and not self.selected:
            self.state.program = self.recorded_program
        self._begin_timing()
        if not self.life.active:
            self.state.start_counter += 1
        self._enter(Event.WORK)

    def end_program(self, at_s: float | None = None, *, part_done: bool = True) -> None:
        """M30: the run ends, its net time becomes the last program's, a part is counted. ``at_s``: the
        simulated time the program reached its end (within the cycle that found it). ``part_done``
        False: a program with no block to execute (empty, only comments) ends without a part."""
        self._hold(at_s)
        self.state.old_net_time_s = self._net_s
        if part_done:
            self.state.actual_parts += 1.0
            self.state.total_parts += 1.0
        self.state.end_counter += 1
        had_run = self.run is not None
        if had_run and self._run_key is not None:
            path, text_hash = self._run_key
            self.completed_runs_s[path] = (text_hash, self.state.old_net_time_s)
        self._finish_run()
        self._enter(Event.END, tell=had_run)

    # ------------------------------------------------------------------ the cycle
    def step(self, t_s: float) -> None:
        """Run the program up to simulated time ``t_s`` (at most the machine's blocks per cycle)."""
        run = self.run
        if run is None or self.state.status != CHAN_ACTIVE:
            return
        try:
            outcome = run.advance(t_s, self.parts.machine.program.max_blocks_per_cycle)
        except ProgramAlarm as exc:
            self.program_alarm(exc)
            return
        except NckError as exc:  # a value the model refused: the program's fault, never the server's
            self.program_alarm(ProgramAlarm(12080, str(exc)))
            return
        except Exception as exc:  # the interpreter's own fault: an alarm, never a traceback to a client
            log.exception("channel %d: the program run failed", self.number)
            self.program_alarm(ProgramAlarm(12080, f"internal error: {type(exc).__name__}: {exc}"))
            return
        waiting = outcome == "waiting"
        if waiting and self.life is Life.RUNNING:
            self._enter(Event.WAIT)
        elif not waiting and self.life is Life.WAITING:
            self._enter(Event.GO_ON)
        if outcome == "ended":
            self.end_program(run.t_s, part_done=run.blocks > 0)
        elif outcome == "stopped":  # M0 / M1
            self._interrupt(Event.STOP, run.t_s)

    def program_alarm(self, alarm: ProgramAlarm) -> None:
        """A program alarm: on the NCK's list (cleared by reset), the channel interrupted."""
        block = alarm.block or self.state.block_number
        text = f"channel {self.number}: {alarm}"
        log.warning("%s", text)
        self.parts.alarm_list.raise_alarm(text, alarm.number, (str(self.number), block or str(alarm.line)))
        self._alarms.append(text)
        if self.life.active:
            self._interrupt(Event.ALARM)

    # ------------------------------------------------------------------ helpers
    def _refuse(self, alarm_number: int, reason: str) -> Any:
        text = f"channel {self.number}: {reason}"
        if alarm_number:
            self.parts.alarm_list.raise_alarm(text, alarm_number, (str(self.number),))
            if text not in self._notices:
                self._notices.append(text)
        log.info("%s", text)
        raise NckPiStateError(reason)

    def _enter(self, event: Event, *, tell: bool = True) -> None:
        """The one place the channel's life changes: the table's next place, reported as BTSS numbers,
        then the change told (unless ``tell`` is False) and the state listeners called."""
        self.life, change = next_life(self.life, event)
        self.state.status, self.state.program_status = self.life.reported
        if change is not None and tell:
            self._tell(change)
        self._tell_state()

    def _interrupt(self, event: Event, at_s: float | None = None) -> None:
        at_s = self._clock.now_s() if at_s is None else at_s
        self._hold(at_s)
        if self.run is not None:
            self.run.pause(at_s)
        self.state.path_feed_mm_min = 0.0
        self._enter(event)

    def _finish_run(self) -> None:
        run, self.run = self.run, None
        self.state.path_feed_mm_min = 0.0
        if run is not None:
            run.close(run.t_s if run.ended else self._clock.now_s())
            self.last_run_blocks = run.blocks
            self.last_run_notes = list(run.notes)
        if self.parts.programs.running and self.number == 1:
            self.parts.programs.running = ""
            self.parts.programs.called = tuple

    def _clear_alarms(self, texts: list[str]) -> None:
        for text in texts:
            self.parts.alarm_list.clear(text)
        texts.clear()

    def _begin_timing(self, at_s: float | None = None) -> None:
        if self._running_since is None:
            self._running_since = self._clock.now_s() if at_s is None else at_s

    def _tell(self, change: str) -> None:
        for listener in list(self.on_change):
            try:
                listener(change)
            except Exception:  # a listener's fault never stops the channel
                log.exception("channel %d: an on_change listener failed on %r", self.number, change)

    def _tell_state(self) -> None:
        for listener in list(self.state_listeners):
            try:
                listener(self)
            except Exception:
                log.exception("channel %d: a state listener failed", self.number)

    def _hold(self, at_s: float | None = None) -> None:
        if self._running_since is not None:
            now_s = self._clock.now_s() if at_s is None else min(at_s, self._clock.now_s())
            elapsed = max(0.0, now_s - self._running_since)
            self._net_s += elapsed
            self.state.cutting_time_s += elapsed
            self._running_since = None

    # ------------------------------------------------------------------ what a run shows
    # The program run and the NCK tell the channel what it reports through these; only the channel
    # assigns ChannelState's fields (tests/emulator/machine/nck/test_channel_life.py checks it).
    def show_block(self, block: Block) -> None:
        """The block now executing: its program, line, block number and text (SPARP, S columns)."""
        state = self.state
        state.program, state.line_number, state.block_number = block.program, block.line, block.number
        state.block_text = block.text

    def show_message(self, text: str) -> None:
        """MSG("..."): the operator message the channel shows until the next one or the next start."""
        self.state.message = text

    def set_path_feed(self, path_mm_min: float) -> None:
        """The path speed of the motion under way (0 when none)."""
        self.state.path_feed_mm_min = path_mm_min

    def set_commanded_feed(self, feed_mm_min: float) -> None:
        """The feed the block programs (0 for a rapid move)."""
        self.state.commanded_feed_mm_min = feed_mm_min

    def set_tool(self, t_number: int | None = None, ident: str = "", d_number: int | None = None) -> None:
        """A tool (T, with its ident) and a cutting edge (D) active in the channel; None leaves one as it is."""
        state = self.state
        state.t_number, state.tool_ident = (state.t_number, state.tool_ident) if t_number is None else (t_number, ident)
        state.d_number = state.d_number if d_number is None else d_number

    def command_spindle(self, line: int, *, rpm: float | None = None, direction: int | None = None) -> None:
        """S (the commanded speed) and M3/M4/M5 (the turn state) of spindle ``line``; None leaves one as it is."""
        spindle = self.spindle(line)
        spindle.commanded_rpm = spindle.commanded_rpm if rpm is None else rpm
        spindle.direction = spindle.direction if direction is None else direction

    def ramp_spindle(self, line: int, ramp: SpindleRamp) -> None:
        """Spindle ``line``'s speed follows ``ramp`` (a program's acceleration, G96, the run-down at reset)."""
        self.spindle(line).ramp = ramp

    def set_spindle_override(self, line: int, override_pct: float) -> None:
        self.spindle(line).override_pct = float(override_pct)

    def figure(self, name: str) -> float:
        """One of :data:`SETTABLE_FIGURES`."""
        if name not in SETTABLE_FIGURES:
            raise KeyError(name)
        return float(getattr(self.state, name))

    def set_figure(self, name: str, value: float) -> None:
        """A part counter, an override or the commanded feed, as a client or a program writes it."""
        if name not in SETTABLE_FIGURES:
            raise KeyError(f"{name} is not a figure of the channel others may set")
        setattr(self.state, name, float(value))

    # ------------------------------------------------------------------ values
    @property
    def ac_prog(self) -> int:
        """$AC_PROG from the channel's state."""
        status, program = self.state.status, self.state.program_status
        if status == CHAN_RESET:
            return AC_RESET
        if status == CHAN_ACTIVE:
            return AC_WAITING if program == PROG_WAITING else AC_RUNNING
        return AC_INTERRUPTED if program == PROG_INTERRUPTED else AC_STOPPED

    @property
    def alarms(self) -> list[str]:
        """The texts of the program alarms this channel raised that are still pending (reset clears
        them; NC start is refused while there are any)."""
        return list(self._alarms)

    @property
    def notices(self) -> list[str]:
        """Refusals still on the alarm list (NC start in JOG, a mode change while running)."""
        return list(self._notices)

    @property
    def net_time_s(self) -> float:
        """actProgNetTime: time the current program has been running, pauses excluded."""
        running = 0.0 if self._running_since is None else self._clock.now_s() - self._running_since
        return self._net_s + running

    @property
    def last_run_s(self) -> float | None:
        """The net time the last complete run of the program running now took (None: it never ended
        since it was last changed, or nothing runs)."""
        if self.run is None or self._run_key is None:
            return None
        path, text_hash = self._run_key
        text_hash_then, seconds = self.completed_runs_s.get(path, (None, 0.0))
        return seconds if text_hash_then == text_hash else None

    @property
    def time_left_s(self) -> float | None:
        """The live page's "time left": the last complete run's net time less this run's net time so far,
        never below 0; None before one run of this text has ended. Chosen over planning the rest of the
        program ahead because a run's path depends on what it reads as it runs (R parameters, $AA_IM,
        loops, the overrides); for a program that runs the same way each time it is exact."""
        last = self.last_run_s
        return None if last is None else max(0.0, last - self.net_time_s)

    @property
    def cutting_time_s(self) -> float:
        running = 0.0 if self._running_since is None else self._clock.now_s() - self._running_since
        return self.state.cutting_time_s + running

    @property
    def actual_feed_mm_min(self) -> float:
        if self.state.status != CHAN_ACTIVE:
            return 0.0
        if self.run is not None:
            return self.state.path_feed_mm_min
        return self.state.commanded_feed_mm_min * self.state.feed_override_pct / 100.0

    def spindle(self, line: int) -> Spindle:
        spindle = self.state.spindles.get(line)
        if spindle is None:
            raise NckAddressOutOfRange(f"channel {self.number} has no spindle {line}")
        return spindle

    def set_measured_speed(self, line: int, rpm: float | None) -> None:
        """Drive spindle ``line``'s actual speed from a measurement (None: back to the commanded speed);
        its turn state follows the measured sign (M3 turning, M4 the other way, M5 standing)."""
        spindle = self.spindle(line)
        spindle.measured_rpm = None if rpm is None else float(rpm)
        if rpm is not None:
            spindle.direction = TURN_CW if rpm >= 1.0 else TURN_CCW if rpm <= -1.0 else TURN_STOPPED

    def spindle_speed_rpm(self, line: int) -> float:
        spindle = self.spindle(line)
        if spindle.measured_rpm is not None:
            return spindle.measured_rpm
        if spindle.ramp is not None:
            return spindle.ramp.rpm_at(self._clock.now_s())
        if self.state.status != CHAN_ACTIVE or spindle.direction == TURN_STOPPED:
            return 0.0
        return spindle.commanded_rpm * spindle.override_pct / 100.0

    def spindle_commanded_rpm(self, line: int) -> float:
        """cmdSpeed: the speed the spindle is commanded to turn at now (0 when stopped)."""
        spindle = self.spindle(line)
        if spindle.ramp is not None:
            return spindle.ramp.to_rpm
        if spindle.direction == TURN_STOPPED:
            return 0.0
        return spindle.commanded_rpm * spindle.override_pct / 100.0
