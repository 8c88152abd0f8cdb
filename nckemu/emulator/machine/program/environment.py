"""What the interpreter may ask of the NCK while a program runs.

The channel gives the interpreter a subclass bound to the NCK model; tests and offline tools may use
:class:`ProgramEnvironment` itself (R parameters in a dict, axes at zero). Every method has a default
here, so new questions can be added without breaking existing environments.
"""

from __future__ import annotations

from collections.abc import Sequence


class UndefinedName(KeyError):
    """A system variable or name the environment does not know (the interpreter raises alarm 12550)."""


class ProgramEnvironment:
    # Machine data the interpreter reads at program start (class attributes, so a subclass or an
    # instance can override them; documented defaults).
    reset_motion: int = 0          # MD20150 group 1 after reset: 0 = G0 (UNCONFIRMED default), 1 = G1
    reset_inch: bool = False       # MD10240 SCALING_SYSTEM_IS_METRIC TRUE: G71 (mm) after reset
    reset_plane: str = "G17"       # MD20150 group 6 after reset (a lathe: G18)
    tool_change_mode: int = 1      # MD22550 TOOL_CHANGE_MODE: 1 = T preselects and M6 changes; 0 = T changes
    subprogram_end_returns: bool = True  # M2/M30 in a subprogram return like M17 (UNCONFIRMED); False: end all
    # two G functions of one group that does not define the syntax (G90 G91): "last_wins" or "alarm" (12060);
    # which the control does is UNCONFIRMED ([program] repeated_g_group)
    repeated_g_group: str = "last_wins"

    def __init__(self, axes: Sequence[str] = ("X", "Y", "Z"), r_parameters: int = 100) -> None:
        self.axes = tuple(axes)
        self.r_count = r_parameters
        self._r: dict[int, float] = {}
        self._position_mm: dict[str, float] = {axis: 0.0 for axis in self.axes}
        self._offsets_mm: dict[str, dict[str, float]] = {}

    # R parameters: the same R the NCK serves (nckemu get R1 reads what R1=... wrote)
    def r_parameter(self, index: int) -> float:
        return self._r.get(index, 0.0)

    def set_r_parameter(self, index: int, value: float) -> None:
        self._r[index] = float(value)

    # positions
    def machine_position_mm(self, axis: str) -> float:
        """Where ``axis`` is now ($AA_IM), machine coordinates; the end of the last executed motion."""
        return self._position_mm[axis]

    def work_offset_mm(self, frame: str, axis: str) -> float:
        """The settable frame ``frame`` (G54...G57, G505...) of ``axis``; 0 where none is set."""
        return self._offsets_mm.get(frame, {}).get(axis, 0.0)

    def set_work_offset_mm(self, frame: str, axis: str, value_mm: float) -> None:
        """A program wrote settable frame ``frame`` ($P_UIFR[n,X,TR]=...): the NCK stores it."""
        self._offsets_mm.setdefault(frame, {})[axis] = float(value_mm)

    def axis_is_rotary(self, axis: str) -> bool:
        """Rotary axes take degrees and are not converted by G70/G700 (A, B, C unless told otherwise)."""
        return axis.upper() in ("A", "B", "C")

    def select_settable_frame(self, frame: str) -> None:
        """A block selected the settable frame ``frame`` (G500, G54...G57, G505...): the NCK makes it
        the active one, so what it reports (actFrameIndex, work positions) follows the program."""

    def set_programmable_frame(self, frame: object) -> None:
        """The frame the program has programmed on the settable frame (a
        :class:`~nckemu.emulator.machine.nck.frames.Frame`; identity after TRANS without values), so
        that the work positions the NCK reports follow it."""

    def tool_length_mm(self, tool: int | str | None, edge: int | None) -> float:
        """The active tool edge's length 1 (applied along the infeed axis of the plane)."""
        return 0.0

    def tool_radius_mm(self, tool: int | str | None, edge: int | None) -> float:
        """The active tool edge's radius (with its wear), which G41/G42 offset the contour by."""
        return 0.0

    # system variables ($AC_TIME, $AC_ACTUAL_PARTS, $P_EP[X], ...)
    def system_variable(self, name: str, indices: tuple[object, ...] = ()) -> object:
        raise UndefinedName(name)

    def set_system_variable(self, name: str, indices: tuple[object, ...], value: object) -> None:
        raise UndefinedName(name)

    # definition files (GUD and macros, language/definitions.py)
    def global_variables(self) -> dict:
        """The NCK's activated GUD variables by name (``language.variables.Variable``): a program
        reads and writes these objects, so their values outlive the run."""
        return {}

    def macros(self) -> dict[str, str]:
        """The activated ``DEFINE name AS text`` macros."""
        return {}

    # subprograms
    def find_program(self, name: str, caller: str) -> tuple[str, str] | None:
        """The NC path and text of the program a call names (``WARMUP_CYCLE``), searched from the
        caller's directory, then /_N_SPF_DIR, the cycle directories and /_N_MPF_DIR; None if none."""
        return None
