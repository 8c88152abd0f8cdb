"""Generate an STL compensation program that computes a thermal model in the PLC.

The program has the shape of a hand-written one: OB1 calls an FC that reads the machine's PLC
inputs (each sensor's PIW through its analog scaling), evaluates the model in REAL arithmetic, and
hands K0 (SD43900), tan beta (SD43910) and P0 (SD43920) to the NCK with FB3 "PUT" through an
NCVar-selector address DB, at the rate of a self-restarting timer.

- offset, temperature, quadratic_temperature, thermal_gradient: arithmetic on the scaled inputs;
- thermal_lag: ``S += alpha * (u - S)`` once per cycle with ``alpha = 1 - exp(-cycle / tau)``, exact
  for an input held over the cycle; heating_cooling_hysteresis: the same with alpha of heating or
  cooling; transient_gradient: the same lag, and ``u - S`` is the term; the states live in a DB and
  start settled on the first cycle;
- position_dependent_expansion: tan beta and P0 (needs MD32750 bit 1);
- centrifugal_growth: from the spindle speed, when the machine wires it to the PLC as a
  ``[[sensor]]`` named ``spindle_rpm`` (its "degrees" are rpm); otherwise, when the machine has a
  spindle, from the NCK's actual speed of spindle 1 (actSpeed) read with FB2 "GET" through the same
  address DB at the start of the FC. FB2 answers in the cycle after its request and is asked again in
  the cycle after that, so the speed the model uses is one or two PLC cycles old;
- gain_error: a factor on the whole output.
Effects the PLC cannot compute (time_drift, effects of sensors not wired to the PLC, centrifugal
growth without a speed input or a spindle) are not generated; the header lists them as "not compensable in the PLC".

The sums are kept in um (deviations from the reference temperature), so a 32-bit REAL carries them
to well below 0.1 um; only the outputs are scaled to mm.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from nckemu.catalogue.names import parse_variable
from nckemu.emulator.machine.machine_file import Axis, Machine, Sensor
from nckemu.errors import NckConfigError
from nckemu.protocol.addresses import NckType
from nckemu.protocol.awl import NcVarDb, NcVarEntry, render_ncvar_db
from nckemu.thermal.discovery.plcmodel import why_not_compensable
from nckemu.thermal.model.families import PLC_FORMS, STATEFUL_PLC_FORMS
from nckemu.thermal.model.terms import Term, ThermalModel

from .replay import NCK_SPINDLE, POSITION_DEPENDENT_MARKER, SPINDLE_SPEED_SENSOR, nck_spindle_speed

ADDRESS_DB = 150
STATE_DB = 151
PUT_INSTANCE_DB = 152
GET_INSTANCE_DB = 153
FC_NUMBER = 80
TIMER = 40
FLAG_BYTE = 240
STATE_WORD = 242
GET_FLAG_BYTE = 241
GET_STATE_WORD = 244
# actSpeed: module SSP (0x72), area C (channel 1), column 2, line = spindle; REAL8.
# The NCK's actual speed of the spindle read by FB2 GET (channel 1; line = spindle number).
ACT_SPEED = "ACT_SPEED"
# SD43900 TEMP_COMP_ABS_VALUE, SD43910 TEMP_COMP_SLOPE, SD43920 TEMP_COMP_REF_POSITION (columns).
# The setting data FB3 PUT writes, by catalogue name (their addresses come from the catalogue).
SETTING_DATA = ("TEMP_COMP_ABS_VALUE", "TEMP_COMP_SLOPE", "TEMP_COMP_REF_POSITION")


def lag_coefficient(cycle_s: float, tau_s: float) -> float:
    """alpha of the discrete first-order lag, exact for an input held constant over one cycle."""
    return -math.expm1(-cycle_s / tau_s)


def _real(value: float) -> str:
    mantissa, exponent = f"{value:.9e}".split("e")
    return f"{mantissa}e{int(exponent):+04d}"


@dataclass
class GeneratedProgram:
    text: str
    not_compensable: list[dict[str, Any]] = field(default_factory=list)
    generated: list[dict[str, Any]] = field(default_factory=list)
    position_dependent: bool = False
    inputs: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"generated": self.generated, "not_compensable": self.not_compensable,
                "position_dependent": self.position_dependent, "plc_inputs": self.inputs,
                "needs": "MD32750 bit 1 (position-dependent TC)" if self.position_dependent else None}


class _Emitter:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.state: list[str] = []     # REAL fields of the state DB, in order
        self.labels = 0

    def field(self, name: str) -> str:
        if name not in self.state:
            self.state.append(name)
        return f"DB{STATE_DB}.{name}"

    def label(self) -> str:
        self.labels += 1
        return f"L{self.labels:03d}"

    def op(self, *statements: str) -> None:
        self.lines.extend(f"  {s}" for s in statements)

    def temperature(self, sensor: str) -> str:
        return self.field("T_" + re.sub(r"[^A-Za-z0-9]", "_", sensor).upper())

    def deviation(self, sensor: str, t_ref_C: float) -> None:
        """ACCU1 = T(sensor) - t_ref."""
        self.op(f"L {self.temperature(sensor)}", f"L {_real(t_ref_C)}", "-R")

    def accumulate(self, total: str) -> None:
        self.op(f"L {total}", "+R", f"T {total}")


def _plc_sensors(machine: Machine) -> dict[str, Sensor]:
    """Only what the machine file wires to a PLC input can be read by the program."""
    return {s.name: s for s in machine.sensors if s.plc_input}


def generate_program(model: ThermalModel, machine: Machine, axis: Axis, cycle_s: float = 1.0,
                     write_period_s: float = 10.0, extra_not_compensable: list[dict[str, Any]] | None = None,
                     origin: str = "") -> GeneratedProgram:
    """STL source computing ``model`` (um, in the direction of the error) for machine axis ``axis``."""
    if not cycle_s > 0:
        raise NckConfigError("the PLC cycle must be positive")
    sensors = _plc_sensors(machine)
    spindle_input = SPINDLE_SPEED_SENSOR in sensors
    speed_by_get = not spindle_input and nck_spindle_speed(machine)
    e = _Emitter()
    total, tanb = e.field("TOTAL_UM"), e.field("TANB_UM_PER_M")
    not_compensable = list(extra_not_compensable or [])
    generated: list[dict[str, Any]] = []
    gain = 1.0
    usable: list[Term] = []
    for term in model.terms:
        if term.effect == "gain_error":
            gain *= term.coefficient
            generated.append({"effect": "gain_error", "parameters": dict(term.parameters)})
            continue
        reason = why_not_compensable(term, set(sensors), spindle_input=spindle_input or speed_by_get)
        if reason is None and term.spec.plc_form not in _GENERATORS:
            reason = f"no PLC form for {term.effect}"
        if reason:
            not_compensable.append({"effect": term.effect, "parameters": dict(term.parameters),
                                    "why": f"not compensable in the PLC: {reason}"})
        else:
            usable.append(term)
    if not usable:
        listed = ", ".join(sorted({m["effect"] for m in not_compensable})) or "none"
        raise NckConfigError(f"nothing to generate: no effect of the model can be computed in the PLC "
                             f"(not compensable in the PLC: {listed})", path=model.source)
    used_sensors = sorted({s for t in usable for s in _sensors_of(t)})
    speed_get = speed_by_get and SPINDLE_SPEED_SENSOR in used_sensors
    if speed_get:
        used_sensors.remove(SPINDLE_SPEED_SENSOR)
    inputs = [f"{sensors[s].plc_input} ({s})" for s in used_sensors]
    if speed_get:
        inputs.append(f"FB2 GET actSpeed (NCK spindle {NCK_SPINDLE})")
    # Inputs.
    for name in used_sensors:
        sensor = sensors[name]
        unit = "rpm" if name == SPINDLE_SPEED_SENSOR else "degC"
        e.op(f"// {name}: {sensor.plc_input} = {sensor.raw_offset:g} + {sensor.raw_per_C:g} * value [{unit}]",
             f"L {sensor.plc_input[:3]} {sensor.plc_input[3:]}", "ITD", "DTR", f"L {_real(sensor.raw_offset)}",
             "-R", f"L {_real(sensor.raw_per_C)}", "/R", f"T {e.temperature(name)}")
    # Filters start settled on the first cycle.
    ready = e.field("READY")
    run = e.label()
    e.op(f"L {ready}", f"L {_real(0.0)}", "<>R", f"JC {run}")
    for index, term in enumerate(usable):
        if term.spec.plc_form in STATEFUL_PLC_FORMS:
            e.deviation(term.parameters["sensor"], float(term.parameters.get("t_ref_C", 20.0)))
            e.op(f"T {e.field(f'S{index}')}")
    e.op(f"L {_real(1.0)}", f"T {ready}")
    e.lines.append(f"{run}: NOP 0")
    e.op(f"L {_real(0.0)}", f"T {total}", f"T {tanb}")
    p0_mm: float | None = None
    for index, term in enumerate(usable):
        detail = _GENERATORS[str(term.spec.plc_form)](e, term, index, cycle_s, total, tanb)
        if term.spec.plc_form == "position_slope":
            this_p0 = float(term.parameters.get("p0_mm", 0.0))
            if p0_mm is None:
                p0_mm = this_p0
            elif this_p0 != p0_mm:  # slope (T - tref) (P0 - p0_i) / 1000 um: folded into K0
                e.deviation(term.parameters["sensor"], float(term.parameters.get("t_ref_C", 20.0)))
                e.op(f"L {_real(term.coefficient * (p0_mm - this_p0) / 1000.0)}", "*R")
                e.accumulate(total)
        generated.append({"effect": term.effect, "parameters": dict(term.parameters), "plc": detail})
    position_dependent = p0_mm is not None
    out = -machine.settings.compensation_sign * gain
    k0, slope, p0 = e.field("K0_MM"), e.field("TAN_BETA"), e.field("P0_MM")
    e.op(f"// outputs: K0 [mm] = {out:g} * total / 1000, tan beta = {out:g} * slope [um/m] * 1e-6",
         f"L {total}", f"L {_real(out / 1000.0)}", "*R", f"T {k0}",
         f"L {tanb}", f"L {_real(out * 1e-6)}", "*R", f"T {slope}",
         f"L {_real(p0_mm or 0.0)}", f"T {p0}")
    speed = e.temperature(SPINDLE_SPEED_SENSOR) if speed_get else None
    text = _program_text(e, machine, axis, cycle_s, write_period_s, usable, not_compensable, gain,
                         position_dependent, origin, inputs, k0, slope, p0, speed)
    return GeneratedProgram(text, not_compensable, generated, position_dependent, inputs)


def _sensors_of(term: Term) -> list[str]:
    if term.spec.uses_spindle:
        return [SPINDLE_SPEED_SENSOR]
    p = term.parameters
    if "sensors" in p:
        return [str(s) for s in p["sensors"]]
    return [str(p["sensor"])] if "sensor" in p else []


def _offset(e: _Emitter, term: Term, index: int, cycle_s: float, total: str, tanb: str) -> str:
    e.op(f"// offset {term.coefficient:.6g} um", f"L {_real(term.coefficient)}")
    e.accumulate(total)
    return "constant"


def _temperature(e: _Emitter, term: Term, index: int, cycle_s: float, total: str, tanb: str) -> str:
    p = term.parameters
    e.op(f"// {term.effect} {p['sensor']}: {term.coefficient:.6g} um/K")
    e.deviation(p["sensor"], float(p.get("t_ref_C", 20.0)))
    e.op(f"L {_real(term.coefficient)}", "*R")
    e.accumulate(total)
    return "c * (T - t_ref)"


def _quadratic(e: _Emitter, term: Term, index: int, cycle_s: float, total: str, tanb: str) -> str:
    p = term.parameters
    scratch = e.field("D")
    e.op(f"// {term.effect} {p['sensor']}: {term.coefficient:.6g} um/K^2")
    e.deviation(p["sensor"], float(p.get("t_ref_C", 20.0)))
    e.op(f"T {scratch}", f"L {scratch}", "*R", f"L {_real(term.coefficient)}", "*R")
    e.accumulate(total)
    return "c * (T - t_ref)^2"


def _gradient(e: _Emitter, term: Term, index: int, cycle_s: float, total: str, tanb: str) -> str:
    a, b = term.parameters["sensors"]
    e.op(f"// {term.effect} {a} - {b}: {term.coefficient:.6g} um/K",
         f"L {e.temperature(a)}", f"L {e.temperature(b)}", "-R", f"L {_real(term.coefficient)}", "*R")
    e.accumulate(total)
    return "c * (T_a - T_b)"


def _lag(e: _Emitter, term: Term, index: int, cycle_s: float, total: str, tanb: str) -> str:
    p = term.parameters
    state, scratch = e.field(f"S{index}"), e.field("U")
    if term.spec.plc_form in ("lag", "skin_core"):
        alpha = lag_coefficient(cycle_s, float(p["tau_s"]))
        e.op(f"// {term.effect} {p['sensor']}: tau {float(p['tau_s']):.0f} s, {term.coefficient:.6g} um/K, "
             f"alpha {alpha:.6g} per {cycle_s:g} s cycle")
        e.deviation(p["sensor"], float(p.get("t_ref_C", 20.0)))
        e.op(f"T {scratch}")
        e.op(f"L {scratch}", f"L {state}", "-R", f"L {_real(alpha)}", "*R", f"L {state}", "+R", f"T {state}")
        detail = f"S += {alpha:.6g} * (T - t_ref - S) per cycle"
        if term.spec.plc_form == "skin_core":
            # The skin against the core: the sensor minus its own lag, zero once the structure is even.
            e.op(f"L {scratch}", f"L {state}", "-R", f"L {_real(term.coefficient)}", "*R")
            e.accumulate(total)
            return f"{detail}; c * (T - t_ref - S)"
    else:
        heat = lag_coefficient(cycle_s, float(p["tau_heat_s"]))
        cool = lag_coefficient(cycle_s, float(p["tau_cool_s"]))
        e.deviation(p["sensor"], float(p.get("t_ref_C", 20.0)))
        e.op(f"T {scratch}")
        heating, apply = e.label(), e.label()
        rate = e.field("A")
        e.op(f"// heating_cooling_hysteresis {p['sensor']}: tau heating {float(p['tau_heat_s']):.0f} s, "
             f"cooling {float(p['tau_cool_s']):.0f} s",
             f"L {scratch}", f"L {state}", ">R", f"JC {heating}", f"L {_real(cool)}", f"JU {apply}")
        e.lines.append(f"{heating}: L {_real(heat)}")
        e.lines.append(f"{apply}: T {rate}")
        e.op(f"L {scratch}", f"L {state}", "-R", f"L {rate}", "*R", f"L {state}", "+R", f"T {state}")
        detail = f"S += ({heat:.6g} heating | {cool:.6g} cooling) * (T - t_ref - S) per cycle"
    e.op(f"L {state}", f"L {_real(term.coefficient)}", "*R")
    e.accumulate(total)
    return detail


def _position(e: _Emitter, term: Term, index: int, cycle_s: float, total: str, tanb: str) -> str:
    p = term.parameters
    e.op(f"// position_dependent_expansion {p['sensor']}: {term.coefficient:.6g} um/m/K from P0 = "
         f"{float(p.get('p0_mm', 0.0)):g} mm")
    e.deviation(p["sensor"], float(p.get("t_ref_C", 20.0)))
    e.op(f"L {_real(term.coefficient)}", "*R")
    e.accumulate(tanb)
    return "tan beta += slope * (T - t_ref) * 1e-6"


def _centrifugal(e: _Emitter, term: Term, index: int, cycle_s: float, total: str, tanb: str) -> str:
    e.op(f"// centrifugal_growth: {term.coefficient:.6g} um/krpm^2 from the spindle speed",
         f"L {e.temperature(SPINDLE_SPEED_SENSOR)}", f"L {_real(1000.0)}", "/R", f"T {e.field('D')}",
         f"L {e.field('D')}", "*R", f"L {_real(term.coefficient)}", "*R")
    e.accumulate(total)
    return "c * (rpm / 1000)^2"


# One emitter per PLC form (model/families.py names each family's form: the generator asks the registry).
_GENERATORS = {"constant": _offset, "speed_square": _centrifugal, "linear": _temperature, "square": _quadratic,
               "difference": _gradient, "lag": _lag, "asymmetric_lag": _lag, "skin_core": _lag,
               "position_slope": _position}
assert set(_GENERATORS) == set(PLC_FORMS), "every PLC form of model/families.py has an emitter here"


def _program_text(e: _Emitter, machine: Machine, axis: Axis, cycle_s: float, write_period_s: float,
                  usable: list[Term], not_compensable: list[dict[str, Any]], gain: float, position_dependent: bool,
                  origin: str, inputs: list[str], k0: str, slope: str, p0: str, speed: str | None = None) -> str:
    """The source; with ``speed`` (a state DB REAL) FB2 GET reads the NCK's spindle speed into it first."""
    header = [f"// Generated by nckemu{(' from ' + origin) if origin else ''}: thermal compensation of axis "
              f"{axis.name} (machine axis {axis.number}) of {machine.name}.",
              f"// PLC inputs: {', '.join(inputs)}. Filters are exact for a {cycle_s:g} s PLC cycle.",
              f"// FB3 PUT of SD43900/43910/43920 every {write_period_s:g} s (timer T {TIMER}).",
              "// Model (um, in the direction of the error; the NCK applies it with the opposite sign):"]
    header += [f"//   {t.effect} {_describe(t)}" for t in usable]
    if gain != 1.0:
        header.append(f"//   gain_error: the whole model x {gain:.6g}")
    if position_dependent:
        header.append(f"// {POSITION_DEPENDENT_MARKER}: set MD32750 bit 1 (TEMP_COMP_TYPE = 3) for axis "
                      f"{axis.number}, or the NCK ignores tan beta and P0.")
    for item in not_compensable:
        header.append(f"// not compensable in the PLC: {item['effect']} {_describe(Term(item['effect'], item['parameters']))}"
                      f" ({item['why'].removeprefix('not compensable in the PLC: ')})")
    get: list[str] = []
    get_instance: list[str] = []
    if speed is not None:
        name = ACT_SPEED
        g = GET_FLAG_BYTE
        get = [f"  // the spindle speed: FB2 GET of actSpeed (spindle {NCK_SPINDLE}), asked again in the cycle after "
               "each answer;", "  // the model below uses the last answer (one or two PLC cycles old)",
               f"  AN M {g}.0", f"  = M {g}.1",
               f"  CALL FB 2, DB {GET_INSTANCE_DB} (", f"    Req := M {g}.1,", "    NumVar := 1,",
               f"    Addr1 := DB{ADDRESS_DB}.{name},", f"    Error := M {g}.2,", f"    NDR := M {g}.3,",
               f"    State := MW {GET_STATE_WORD},", f"    RD1 := {speed}", "  )",
               f"  A M {g}.1", f"  S M {g}.0", f"  A M {g}.3", f"  O M {g}.2", f"  R M {g}.0"]
        get_instance = [f"DATA_BLOCK DB {GET_INSTANCE_DB}", "FB 2", "BEGIN", "END_DATA_BLOCK", ""]
    state = [f"  {name} : REAL := 0.0;" for name in e.state]
    seconds = max(1, round(write_period_s))
    timer = f"S5T#{seconds // 60}M{seconds % 60}S" if seconds >= 60 and seconds % 60 else \
        (f"S5T#{seconds // 60}M" if seconds >= 60 else f"S5T#{seconds}S")
    flag = FLAG_BYTE
    body = [
        *header, "",
        *_address_db(axis, with_speed=speed is not None).splitlines(),
        f"DATA_BLOCK DB {STATE_DB}", "STRUCT", *state, "END_STRUCT;", "BEGIN", "END_DATA_BLOCK", "",
        f"DATA_BLOCK DB {PUT_INSTANCE_DB}", "FB 3", "BEGIN", "END_DATA_BLOCK", "", *get_instance,
        f"FUNCTION FC {FC_NUMBER} : VOID", "BEGIN", *get, *e.lines,
        "  // a one-cycle request for FB3 at the write rate",
        f"  AN M {flag}.0", f"  L {timer}", f"  SD T {TIMER}", f"  A T {TIMER}", f"  = M {flag}.0",
        f"  A M {flag}.0", f"  = M {flag}.1",
        f"  CALL FB 3, DB {PUT_INSTANCE_DB} (", f"    Req := M {flag}.1", "    NumVar := 3,",
        *[f"    Addr{i + 1} := DB{ADDRESS_DB}.{name}," for i, name in enumerate(SETTING_DATA)],
        f"    Error := M {flag}.2,", f"    Done := M {flag}.3,", f"    State := MW {STATE_WORD},",
        f"    SD1 := {k0},", f"    SD2 := {slope},", f"    SD3 := {p0}", "  )", "END_FUNCTION", "",
        "ORGANIZATION_BLOCK OB 1", "BEGIN", f"  CALL FC {FC_NUMBER}", "END_ORGANIZATION_BLOCK", ""]
    body[body.index(f"    Req := M {flag}.1")] = f"    Req := M {flag}.1,"
    return "\n".join(body)


def _address_db(axis: Axis, with_speed: bool) -> str:
    """The NCVar-selector address DB of the generated GET/PUT calls, addresses from the catalogue."""
    entries = [NcVarEntry(name, parse_variable(f"{name}[AX{axis.number}]").address, NckType.REAL8, 8)
               for name in SETTING_DATA]
    if with_speed:
        entries.append(NcVarEntry(ACT_SPEED, parse_variable(f"actSpeed[C1,l{NCK_SPINDLE}]").address,
                                  NckType.REAL8, 8))
    return render_ncvar_db(NcVarDb(ADDRESS_DB, tuple(entries)))


def _describe(term: Term) -> str:
    return ", ".join(f"{k} = {v:.6g}" if isinstance(v, float) else f"{k} = {v}" for k, v in term.parameters.items())
