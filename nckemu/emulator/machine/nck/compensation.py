"""Temperature compensation (840D setting data, 840C user DB) and leadscrew error compensation.

The 840D TC follows the clock at the IPO cycle and is advanced lazily in closed form: between two
events the applied value ramps linearly toward a fixed target at most MD32760 · MD32000 · T_IPO per
cycle, so jumping two simulated hours costs the same as one cycle.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from nckemu.catalogue.leadscrew import LeadscrewTable, parse_leadscrew_program
from nckemu.emulator.machine.clock import Clock
from nckemu.emulator.machine.machine_file import Machine
from nckemu.emulator.machine.nck.axes import Axes
from nckemu.emulator.machine.nck.store import VariableStore
from nckemu.errors import NckPiStateError

TC_BIT_POSITION_INDEPENDENT = 0x01
TC_BIT_POSITION_DEPENDENT = 0x02
TC_BIT_TOOL_DIRECTION = 0x04


@dataclass
class _TcRamp:
    """The 840D TC value applied to an axis and the IPO-quantized time it belongs to."""

    applied_mm: float = 0.0
    time_s: float = 0.0


@dataclass(frozen=True)
class Tc840c:
    k_tcabs_mm: float
    tan_beta: float
    p0_mm: float
    position_independent: bool
    position_dependent: bool

    def value_mm(self, position_mm: float) -> float:
        value = self.k_tcabs_mm if self.position_independent else 0.0
        if self.position_dependent:
            value += self.tan_beta * (position_mm - self.p0_mm)
        return value


class Compensation:
    """TC per axis (840D ramped, 840C immediate) and LEC tables (loaded, and active after power-on)."""

    def __init__(self, machine: Machine, clock: Clock, store: VariableStore, axes: Axes) -> None:
        self.machine = machine
        self.clock = clock
        self.store = store
        self.axes = axes
        now_s = clock.now_s()
        self._tc = {axis.number: _TcRamp(0.0, now_s) for axis in machine.axes}
        self._tc_840c: dict[int, Tc840c] = {}
        self.lec_loaded: dict[tuple[int, int], LeadscrewTable] = {}
        self._lec_active: dict[int, LeadscrewTable] = {}
        axes.on_unreferenced(lambda axis: self._lec_active.pop(axis, None))

    # ------------------------------------------------------------------ 840D TC
    def tc_target_mm(self, axis: int) -> float:
        """ΔK = K0 + tanβ·(P − P0), with only the parts the active MD32750 enables."""
        comp_type = int(self.store.active_value("TEMP_COMP_TYPE", axis))
        if self.machine.settings.tc_requires_referenced and not self.axes.referenced[axis]:
            return 0.0
        target = 0.0
        if comp_type & TC_BIT_POSITION_INDEPENDENT:
            target += float(self.store.stored_value("TEMP_COMP_ABS_VALUE", axis))
        if comp_type & TC_BIT_POSITION_DEPENDENT:
            slope = float(self.store.stored_value("TEMP_COMP_SLOPE", axis))
            p0_mm = float(self.store.stored_value("TEMP_COMP_REF_POSITION", axis))
            target += slope * (self.axes.positions_mm[axis] - p0_mm)
        if comp_type & TC_BIT_TOOL_DIRECTION:
            target += self.tool_direction_tc_mm(axis)
        return target

    def tool_direction_tc_mm(self, axis: int) -> float:
        """SD42960 TOOL_TEMP_COMP[component] of channel 1, limited by MD20392 without an alarm, where
        MD20390 is on. Which component acts on which axis is a machine setting (unconfirmed)."""
        component = self.axes.specs[axis].tool_temp_comp_component
        if component is None or not int(self.store.active_value("TOOL_TEMP_COMP_ON", 1)):
            return 0.0
        value_mm = float(self.store.stored_value("TOOL_TEMP_COMP", 1, component))
        limit_mm = float(self.store.active_value("TOOL_TEMP_COMP_LIMIT", 1, component))
        return max(-limit_mm, min(limit_mm, value_mm))

    def tc_max_step_mm(self, axis: int) -> float:
        """Largest change per IPO cycle: MD32760 · MD32000 · T_IPO (MD32000 is in mm/min)."""
        factor = float(self.store.active_value("COMP_ADD_VELO_FACTOR", axis))
        max_velo_mm_per_s = float(self.store.active_value("MAX_AX_VELO", axis)) / 60.0
        return factor * max_velo_mm_per_s * self.machine.ipo_cycle_s

    def advance(self, axis: int) -> None:
        ramp = self._tc[axis]
        ipo_s = self.machine.ipo_cycle_s
        cycles = math.floor((self.clock.now_s() - ramp.time_s) / ipo_s + 1e-9)
        if cycles <= 0:
            return
        ramp.time_s += cycles * ipo_s
        delta = self.tc_target_mm(axis) - ramp.applied_mm
        if delta == 0.0:
            return
        reach = cycles * self.tc_max_step_mm(axis)
        ramp.applied_mm = ramp.applied_mm + delta if abs(delta) <= reach else \
            ramp.applied_mm + math.copysign(reach, delta)

    def advance_all(self) -> None:
        for axis in self._tc:
            self.advance(axis)

    def tc_value_mm(self, axis: int) -> float:
        """Applied temperature compensation: the smoothed 840D part plus any 840C part."""
        self.axes.check(axis)
        self.advance(axis)
        value = self._tc[axis].applied_mm
        tc_840c = self._tc_840c.get(axis)
        if tc_840c is not None:
            value += tc_840c.value_mm(self.axes.positions_mm[axis])
        return value

    # ------------------------------------------------------------------ 840C TC
    def apply_840c_tc(self, axis: int, tc: Tc840c) -> None:
        """840C: applied at once, without smoothing; erased at power-on."""
        self.axes.check(axis)
        self._tc_840c[axis] = tc

    def tc_840c(self, axis: int) -> Tc840c | None:
        return self._tc_840c.get(axis)

    # ------------------------------------------------------------------ leadscrew tables
    def lec_value_mm(self, axis: int) -> float:
        self.axes.check(axis)
        table = self._lec_active.get(axis)
        if table is None or not self.axes.referenced[axis]:
            return 0.0
        return table.value_mm(self.axes.positions_mm[axis])

    def load_leadscrew_program(self, text: str, source: str = "<string>") -> list[LeadscrewTable]:
        """Load $AA_ENC_COMP tables (only while MD32700 = 0 is active); they act after power-on."""
        tables = parse_leadscrew_program(
            text, source, self.axes.number,
            lambda axis, encoder: int(self.store.active_value("MM_ENC_COMP_MAX_POINTS", axis, encoder + 1)))
        for table in tables:
            if int(self.store.active_value("ENC_COMP_ENABLE", table.axis, table.encoder + 1)):
                raise NckPiStateError(f"{source}: axis {table.axis}: tables can be loaded only while "
                                      f"MD32700 ENC_COMP_ENABLE[{table.encoder}] = 0 is active")
        self.set_loaded(tables)
        return tables

    def set_loaded(self, tables: Iterable[LeadscrewTable]) -> None:
        for table in tables:
            self.lec_loaded[(table.axis, table.encoder)] = table

    def activate_leadscrew(self) -> None:
        self._lec_active.clear()
        for (axis, encoder), table in self.lec_loaded.items():
            if encoder == 0 and int(self.store.active_value("ENC_COMP_ENABLE", axis, 1)) \
                    and self.axes.referenced[axis]:
                self._lec_active[axis] = table

    # ------------------------------------------------------------------ power on
    def power_on(self) -> None:
        """Ramps restart from zero, 840C TC data are erased, loaded tables activate."""
        now_s = self.clock.now_s()
        for ramp in self._tc.values():
            ramp.applied_mm = 0.0
            ramp.time_s = now_s
        self._tc_840c.clear()
        self.activate_leadscrew()

    def total_mm(self, axis: int) -> float:
        """Total compensation of the axis: TC + LEC (summed, as the 840C manual says they are)."""
        return self.tc_value_mm(axis) + self.lec_value_mm(axis)
