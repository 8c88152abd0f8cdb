"""Channel state: what a channel reports about its program run (status, parts, tools, feed, times).

The values HMIs and collectors poll from module S (0x7F), SSP (0x72), SPARP (0x7D) and DIAGN (0x3B).
A channel is reset until it is started; the net program time runs while it is active; the end of a
program counts a part. The emulator drives it through ``start``/``stop``/``reset``/``end_program``
(the extension variable ``NCKEMU_CHAN_COMMAND`` does it over the wire).

Value meanings (sources in ``catalogue/variables.toml``): chanStatus 0 reset, 1 active, 2 interrupted
(two sources); progStatus 2 stopped, 3 running, 5 aborted (one source; 1 interrupted and 4 waiting
unconfirmed).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from nckemu.emulator.machine.clock import Clock
from nckemu.errors import NckAddressOutOfRange, NckItemError

CHAN_RESET, CHAN_ACTIVE, CHAN_INTERRUPTED = 0, 1, 2
PROG_INTERRUPTED, PROG_STOPPED, PROG_RUNNING, PROG_WAITING, PROG_ABORTED = 1, 2, 3, 4, 5
# NCKEMU_CHAN_COMMAND values
COMMAND_RESET, COMMAND_START, COMMAND_STOP, COMMAND_END_PROGRAM = 0, 1, 2, 3
# turnState (unconfirmed: the sources give no enumeration): 0 stopped, 1 clockwise M3, 2 counter-clockwise M4
TURN_STOPPED, TURN_CW, TURN_CCW = 0, 1, 2


@dataclass
class Spindle:
    commanded_rpm: float = 0.0
    override_pct: float = 100.0
    direction: int = TURN_STOPPED
    # An actual speed measured on the machine (plc run --inputs drives it from a recording's
    # spindle_rpm): when set, actSpeed reports it whatever the channel and the commanded speed say.
    measured_rpm: float | None = None


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


class Channel:
    """One channel's run state on the emulator's clock."""

    def __init__(self, number: int, clock: Clock, spindles: int) -> None:
        self.number = number
        self._clock = clock
        self.state = ChannelState(spindles={n: Spindle() for n in range(1, spindles + 1)})
        self._net_s = 0.0
        self._running_since: float | None = None

    # ------------------------------------------------------------------ commands
    def command(self, value: int) -> None:
        actions = {COMMAND_RESET: self.reset, COMMAND_START: self.start, COMMAND_STOP: self.stop,
                   COMMAND_END_PROGRAM: self.end_program}
        action = actions.get(value)
        if action is None:
            raise NckItemError(f"channel command {value} is not one of {sorted(actions)}", return_code=0x05)
        action()

    def start(self) -> None:
        if self.state.status == CHAN_RESET:
            self._net_s = 0.0
        if self._running_since is None:
            self._running_since = self._clock.now_s()
        self.state.status, self.state.program_status = CHAN_ACTIVE, PROG_RUNNING

    def stop(self) -> None:
        self._hold()
        if self.state.status == CHAN_ACTIVE:
            self.state.status, self.state.program_status = CHAN_INTERRUPTED, PROG_STOPPED

    def reset(self) -> None:
        self._hold()
        if self.state.status != CHAN_RESET:
            self.state.old_net_time_s = self._net_s
        self.state.status, self.state.program_status = CHAN_RESET, PROG_ABORTED

    def end_program(self) -> None:
        """M30: the run ends, its net time becomes the last program's, a part is counted."""
        self._hold()
        self.state.old_net_time_s = self._net_s
        self.state.actual_parts += 1.0
        self.state.total_parts += 1.0
        self.state.status, self.state.program_status = CHAN_RESET, PROG_ABORTED

    def _hold(self) -> None:
        if self._running_since is not None:
            elapsed = self._clock.now_s() - self._running_since
            self._net_s += elapsed
            self.state.cutting_time_s += elapsed
            self._running_since = None

    # ------------------------------------------------------------------ values
    @property
    def net_time_s(self) -> float:
        """actProgNetTime: time the current program has been running, pauses excluded."""
        running = 0.0 if self._running_since is None else self._clock.now_s() - self._running_since
        return self._net_s + running

    @property
    def cutting_time_s(self) -> float:
        running = 0.0 if self._running_since is None else self._clock.now_s() - self._running_since
        return self.state.cutting_time_s + running

    @property
    def actual_feed_mm_min(self) -> float:
        if self.state.status != CHAN_ACTIVE:
            return 0.0
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
        if self.state.status != CHAN_ACTIVE or spindle.direction == TURN_STOPPED:
            return 0.0
        return spindle.commanded_rpm * spindle.override_pct / 100.0
