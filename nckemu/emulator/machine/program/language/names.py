"""The names a running program reads and writes: its variables (DEF, PROC parameters, GUD of the
definition files), R parameters, system variables, the axis settings (ACC[X]) and the axes as values.

:class:`ProgramNames` is the expressions' environment: a compiled expression is called with it
(``expr(names)``) and reads through :class:`~.expressions.Names`, its public protocol. It builds those
closures too (:meth:`ProgramNames.resolve`, the block compiler's resolver). The system variables the
interpreter itself knows ($AA_IW, $P_GG, the frames ...) it reads from the interpreter as a
:class:`NameHost`, named here so that this module does not import the interpreter.
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING, Any, Protocol

from nckemu.emulator.machine.frame_math import IDENTITY_FRAME, Frame

from ..environment import ProgramEnvironment, UndefinedName
from ..motions import ALARM_NAME_NOT_DEFINED, ALARM_SYNTAX, ProgramAlarm
from . import blocks as b
from . import framing
from .expressions import Parser, evaluate, number, undefined
from .gfunctions import GROUP_DEFAULTS, number_in_group
from .motion_builder import PLANES
from .variables import Variable

if TYPE_CHECKING:
    from .modal import ModalState

_R_NAME = re.compile(r"\$?R(\d+)")


class NameHost(Protocol):
    """What the names read of the interpreter (the Interpreter is it) for the system variables it knows."""

    env: ProgramEnvironment
    modal: ModalState
    work_pos: dict[str, float]
    feed_mm: float
    tool: int | str | None
    edge: int | None
    spindle_speed: dict[int, float]
    tool_length_mm: float

    @property
    def modal_call(self) -> Any: ...

    def programmable_frame(self) -> Frame: ...

    def update_shift(self) -> None: ...


class ProgramNames:
    """The names of one interpreter's run (see the module docstring); ``locals`` are the variables of
    the program level that runs now (the call stack switches them)."""

    def __init__(self, host: NameHost, axes: tuple[str, ...]) -> None:
        self.host = host
        self.env = host.env
        self.axes = axes
        self.r_count = int(host.env.r_count)
        # GUD of the NCK's definition files (the same Variable objects: values outlive the run);
        # DEF NCK/CHAN in a program adds to this run's copy of the table only.
        self.globals: dict[str, Variable] = dict(host.env.global_variables())
        self.locals: dict[str, Variable] = {}
        self.settings: dict[tuple[str, str], Any] = {}  # ACC[X]=.. and the like, by (word, axis)

    # --- compiling: a name in an expression as a closure of the names ------------------------------
    def resolve(self, parser: Parser, name: str) -> Any:
        """A name in an expression as a closure (called by the expression parser)."""
        r_match = _R_NAME.fullmatch(name)
        if r_match:
            index = int(r_match.group(1))
            fn = lambda ev: ev.read_r(index)  # noqa: E731
            fn.lvalue = ("R", index, [])  # type: ignore[attr-defined]
            return fn
        if parser.at_op("["):
            indices = parser.indices()
            if name in ("R", "$R"):
                index_expr = indices[0]
                return lambda ev: ev.read_r(evaluate(index_expr, ev))
            if name.startswith("$"):
                return lambda ev: ev.read_system(name, tuple(evaluate(i, ev) for i in indices))
            if name in b.AXIS_SETTINGS:
                return lambda ev: ev.read_setting(name, tuple(evaluate(i, ev) for i in indices))
            fn = lambda ev: ev.read_variable(name, tuple(evaluate(i, ev) for i in indices))  # noqa: E731
            fn.lvalue = ("VAR", name, indices)  # type: ignore[attr-defined]
            return fn
        if name.startswith("$"):
            return lambda ev: ev.read_system(name, ())
        if parser.at_op("("):
            raise undefined(name)
        fn = lambda ev: ev.read_variable(name, ())  # noqa: E731
        fn.lvalue = ("VAR", name, [])  # type: ignore[attr-defined]
        return fn

    # --- variables --------------------------------------------------------------------------------
    def variable(self, name: str) -> Variable | None:
        variable = self.locals.get(name)
        if variable is None:
            variable = self.globals.get(name)
        return variable

    def read_variable(self, name: str, indices: tuple) -> Any:
        variable = self.locals.get(name)
        if variable is None:
            variable = self.globals.get(name)
            if variable is None:
                if name in self.axes and not indices:  # an axis as a value: _AX=(C), AXIS variables
                    return name
                raise undefined(name)
        if not indices:
            if variable.dims:
                return variable.get(())
            return variable.value
        return variable.get(indices)

    def name_or_value(self, name: str) -> Any:
        """An index written as a bare name: a variable's value, else the name itself (an axis)."""
        variable = self.variable(name)
        if variable is not None and not variable.dims:
            return variable.value
        return name

    def define(self, declarations: list, local: dict[str, Variable]) -> None:
        """DEF: each declared variable into ``local`` (the program level's), or the globals (NCK/CHAN)."""
        for name, kind, dims, init, shared in declarations:
            if name in self.axes or len(name) == 1 or re.fullmatch(r"R\d+", name) or name in b.WORD_ADDRESSES:
                raise ProgramAlarm(ALARM_SYNTAX, f"DEF {name}: the name is taken by the control")
            variable = Variable(name, kind, dims)
            if init is not None:
                which, value = init
                if which == "value":
                    evaluated = evaluate(value, self)
                    if dims:
                        variable.fill((), [evaluated], repeat=True)
                    else:
                        variable.set((), evaluated)
                else:
                    variable.fill((), [evaluate(item, self) for item in value], repeat=which == "REP")
            (self.globals if shared else local)[name] = variable

    # --- R parameters, axes, settings -------------------------------------------------------------
    def r_index(self, index: Any) -> int:
        position = number(index)
        if position.__class__ is float:
            position = int(position)
        if not 0 <= position < self.r_count:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name R{position} not defined")
        return position

    def read_r(self, index: Any) -> float:
        return self.env.r_parameter(self.r_index(index))

    def axis_name(self, value: Any) -> str:
        """An axis given by name or by its index (1 = the first axis)."""
        if value.__class__ is str:
            axis = value.upper()
        else:
            position = int(number(value))
            if not 1 <= position <= len(self.axes):
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"no axis with index {position}")
            axis = self.axes[position - 1]
        if axis not in self.axes:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name {axis} not defined (no such axis)")
        return axis

    def read_setting(self, name: str, indices: tuple) -> Any:
        if len(indices) != 1:
            raise ProgramAlarm(ALARM_SYNTAX, f"{name}[axis]")
        axis = self.axis_name(indices[0])
        return self.settings.get((name, axis), 100 if name == "ACC" else 0)

    # --- system variables -------------------------------------------------------------------------
    def read_system(self, name: str, indices: tuple) -> Any:
        try:
            value = self.env.system_variable(name, indices)
        except UndefinedName:
            try:
                value = self._builtin_system(name, indices)
            except ProgramAlarm:
                raise
            except Exception as exc:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name {name} not defined ({exc})") from None
        except ProgramAlarm:
            raise
        except Exception as exc:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name {name} not defined ({exc})") from None
        if isinstance(value, bool | int | float | str | Frame):
            return value
        raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name {name} not defined")

    def _builtin_system(self, name: str, indices: tuple) -> Any:
        """System variables the interpreter itself knows when the environment does not."""
        host = self.host
        if name == "$R" and len(indices) == 1:
            return self.read_r(indices[0])
        if name in ("$AA_IM", "$AA_IW", "$P_EP", "$AA_IB") and len(indices) == 1:
            axis = self.axis_name(indices[0])
            if name == "$P_EP":
                return host.work_pos[axis]
            machine = float(self.env.machine_position_mm(axis))
            if name != "$AA_IW":
                return machine
            if host.modal.chain is None:
                return machine - host.modal.shift.get(axis, 0.0)
            return self._work_position(axis)
        if name == "$AC_DRF" and len(indices) == 1:  # the handwheel's DRF offset: no handwheel turns here
            self.axis_name(indices[0])
            return 0.0
        if name in framing.FRAME_VARIABLES:
            return self._frame_variable(name, indices)
        if name == "$P_GG" and len(indices) == 1:  # the active G function of a group, as its number in it
            group = int(number(indices[0]))
            active = f"G{host.modal.motion}" if group == 1 else host.modal.g_groups.get(group)
            return number_in_group(group, active or GROUP_DEFAULTS.get(group))
        if not indices:
            if name == "$PI":  # the circle constant the control predefines (a cycle's wheel speed from its diameter)
                return math.pi
            if name in ("$P_AXN1", "$P_AXN2", "$P_AXN3"):  # the plane's abscissa, ordinate, applicate
                return PLANES[host.modal.plane][int(name[-1]) - 1]
            if name == "$P_MC":  # a modal call (MCALL) is active: cycles ask before they position
                return host.modal_call is not None
            if name == "$P_F":
                return host.feed_mm
            if name == "$P_TOOLNO":
                return host.tool if host.tool is not None else 0
            if name == "$P_TOOL":
                return host.edge or 0
            if name == "$P_S":
                return host.spindle_speed.get(1, 0.0)
        raise undefined(name)

    def _work_position(self, axis: str) -> float:
        """Where ``axis`` is now in the work system, back through the frame chain (and the tool)."""
        modal = self.host.modal
        chain = modal.chain or Frame(modal.shift)
        infeed = PLANES[modal.plane][2]
        point = {}
        for name in self.axes:
            try:
                point[name] = float(self.env.machine_position_mm(name))
            except Exception:
                point[name] = 0.0
            if name == infeed:
                point[name] -= self.host.tool_length_mm
        return chain.inverse_apply(point)[axis]

    def _frame_variable(self, name: str, indices: tuple) -> float:
        """$P_PFRAME[X,TR], $P_IFRAME[..], $P_ACTFRAME[..], $P_BFRAME[..] and $P_UIFR[n,X,TR]."""
        if name == "$P_UIFR":
            if len(indices) == 1:  # the whole settable frame (a translation, as the NCK keeps it)
                frame_name = framing.settable_name(indices[0])
                return Frame({axis: offset for axis in self.axes
                              if (offset := float(self.env.work_offset_mm(frame_name, axis)))})
            if len(indices) != 3:
                raise ProgramAlarm(ALARM_SYNTAX, "$P_UIFR[frame, axis, component]")
            frame_name = framing.settable_name(indices[0])
            if str(indices[2]).upper() == "TR":
                return float(self.env.work_offset_mm(frame_name, self.axis_name(indices[1])))
            return framing.read_component(IDENTITY_FRAME, indices[1:], name)
        modal = self.host.modal
        frame = {"$P_PFRAME": modal.pframe, "$P_IFRAME": Frame(dict(modal.settable)),
                 "$P_BFRAME": IDENTITY_FRAME}.get(name) or framing.chain(modal.settable, self.host.programmable_frame())
        if not indices:  # the whole FRAME value ($P_PFRAME = $P_PFRAME : CROT(Z, 45))
            return frame
        return framing.read_component(frame, indices, name)

    def _write_whole_frame(self, name: str, indices: tuple, frame: Frame) -> None:
        """``$P_PFRAME=CTRANS(..)``, ``$P_UIFR[n]=..``, ``$P_IFRAME=..``: a whole FRAME value. The NCK's
        settable frames are translations: a value that rotates, scales or mirrors is 12550 there."""
        modal = self.host.modal
        if name == "$P_PFRAME" and not indices:
            modal.pframe = frame
        elif (name == "$P_UIFR" and len(indices) == 1) or (name == "$P_IFRAME" and not indices):
            if not frame.is_translation:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name}: the NCK's settable frames are translations; a "
                                                           "rotation, scale or mirror there is not supported by "
                                                           "the emulator")
            frame_name = framing.settable_name(indices[0]) if indices else modal.frame_name
            for axis in self.axes:
                try:
                    self.env.set_work_offset_mm(frame_name, axis, frame.translation.get(axis, 0.0))
                except UndefinedName:
                    raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name}: no settable frame {frame_name}") from None
            if indices:
                return
            modal.settable = {axis: value for axis, value in frame.translation.items() if value}
        else:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name} cannot be written with these indices")
        self.host.update_shift()
        self.env.set_programmable_frame(self.host.programmable_frame())

    def _write_frame_variable(self, name: str, indices: tuple, value: float) -> None:
        """$P_PFRAME[X,RT]=.. changes the programmable frame; $P_UIFR[n,X,TR]=.. the stored settable
        frame n (active with its next selection, as on the control); $P_IFRAME[X,TR]=.. the active
        settable frame at once (and its stored data, which is what the NCK's faces read)."""
        modal = self.host.modal
        if name == "$P_PFRAME":
            modal.pframe = framing.with_component(modal.pframe, indices, name, value)
        elif name in ("$P_UIFR", "$P_IFRAME") and len(indices) == (3 if name == "$P_UIFR" else 2):
            frame_name = framing.settable_name(indices[0]) if name == "$P_UIFR" else modal.frame_name
            axis, kind = self.axis_name(indices[-2]), str(indices[-1]).upper()
            if kind != "TR":
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name}[..,{kind}]: the NCK's settable frames are "
                                                           "translations; other components are not supported "
                                                           "by the emulator")
            try:
                self.env.set_work_offset_mm(frame_name, axis, value)
            except UndefinedName:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name}: no settable frame {frame_name}") from None
            if name == "$P_UIFR":
                return
            modal.settable = {**modal.settable, axis: value}
        else:
            raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name} cannot be written with these indices")
        self.host.update_shift()
        self.env.set_programmable_frame(self.host.programmable_frame())

    # --- targets of assignments (R, system variable, variable) ------------------------------------
    def assign(self, target: tuple, value: Any) -> None:
        kind, name, indices = target
        if kind == "R":
            self.env.set_r_parameter(self.r_index(evaluate(name, self)), float(number(value)))
            return
        if kind == "SYS":
            evaluated = tuple(evaluate(i, self) for i in indices)
            if name == "$R" and len(evaluated) == 1:
                self.env.set_r_parameter(self.r_index(evaluated[0]), float(number(value)))
                return
            if name in framing.FRAME_VARIABLES:
                if value.__class__ is Frame:  # $P_PFRAME=CTRANS(X,10):CROT(Z,45): a whole FRAME value
                    self._write_whole_frame(name, evaluated, value)
                else:
                    self._write_frame_variable(name, evaluated, float(number(value)))
                return
            try:
                self.env.set_system_variable(name, evaluated, value)
            except UndefinedName:
                raise undefined(name) from None
            except ProgramAlarm:
                raise
            except Exception as exc:
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name} cannot be written ({exc})") from None
            return
        variable = self.variable(name)
        if variable is None:
            raise undefined(name)
        variable.set(tuple(evaluate(i, self) for i in indices), value)

    def read_target(self, target: tuple) -> Any:
        kind, name, indices = target
        if kind == "R":
            return self.read_r(evaluate(name, self))
        if kind == "SYS":
            return self.read_system(name, tuple(evaluate(i, self) for i in indices))
        return self.read_variable(name, tuple(evaluate(i, self) for i in indices))


__all__ = ["NameHost", "ProgramNames"]
