"""``nckemu machine show``: everything a machine file sets, as text or JSON (passwords of OPC UA users
are never shown; the S7 passwords are the access levels' keys, as the README lists them)."""

from __future__ import annotations

from dataclasses import asdict, fields
from typing import Any

from nckemu.catalogue.edges import EDGE_PARAMETER_NAMES, parameter_unit
from nckemu.catalogue.table import load_table
from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.machine.machine_file import (
    AXIS_DYNAMICS,
    PLC_AREA_BYTES,
    Machine,
    Sensor,
    Settings,
    axis_dynamics,
)
from nckemu.emulator.machine_check import opcua_document
from nckemu.heat_response import HeatTerm
from nckemu.protocol.db41 import CHANNEL_DB

DYNAMICS_NAMES = dict(AXIS_DYNAMICS)


def _edge(values: tuple[float, ...]) -> dict[str, float]:
    """An edge's parameters that are set (non-zero) or named, by P number."""
    return {f"P{number}": value for number, value in enumerate(values, start=1)
            if value or number in (1, 2)}


def _heat(sensor: Sensor) -> dict[str, Any]:
    """What a running machine's heat does to the sensor: its fitted response, or the older keys."""
    if sensor.response:
        return {"response": [term.to_table() for term in sensor.response]}
    return {"heat_spindle_K_per_krpm": sensor.heat_spindle_K_per_krpm,
            "heat_axes_K_per_m_min": sensor.heat_axes_K_per_m_min,
            "heat_time_constant_s": sensor.heat_time_constant_s}


def _heat_words(heat: dict[str, Any]) -> str:
    if "response" in heat:
        return "; ".join(HeatTerm(**{k: v for k, v in t.items()}).words() for t in heat["response"])
    return (f"{heat['heat_spindle_K_per_krpm']:g} K per 1000 rpm of the spindle + {heat['heat_axes_K_per_m_min']:g} K "
            f"per m/min of path speed, tau {heat['heat_time_constant_s']:g} s")


def _dynamics(machine: Machine, axis: int) -> dict[str, dict[str, Any]]:
    """MD32000, MD32060, MD32300 of an axis with their units; a rotary axis' MD32300 also as the
    degrees/s² the planner times with (1000 per unit, UNCONFIRMED: docs/programs.md)."""
    shown: dict[str, dict[str, Any]] = {}
    for number, (value, unit) in axis_dynamics(machine, axis).items():
        shown[number] = {"value": value, "unit": unit}
        if unit == "rev/s^2":
            shown[number]["timed_as_deg_s2"] = value * 1000.0
    return shown


def machine_document(machine: Machine, opcua: OpcUaSettings) -> dict[str, Any]:
    blocks = dict(sorted({**machine.data_blocks, CHANNEL_DB: machine.data_blocks.get(CHANNEL_DB, 64)}.items()))
    builtin = {spec.name: spec for spec in load_table()}
    extra_vars = [spec.name for spec in machine.variables if builtin.get(spec.name) != spec]
    defaults = Settings()
    return {
        "name": machine.name, "source": machine.source, "channels": machine.channels,
        "ipo_cycle_s": machine.ipo_cycle_s, "pdu_size_max": machine.pdu_size_max, "max_amq": machine.max_amq,
        "axes": [{"number": a.number, "name": a.name, "travel_mm": [a.travel_min_mm, a.travel_max_mm],
                  "rotary": a.rotary, "spindle": a.spindle, "referenced": a.referenced,
                  **({} if a.spindle else _dynamics(machine, a.number)),
                  "thermal_um_per_K": dict(a.thermal_um_per_K)}
                 for a in machine.axes],
        "sensors": [{"name": s.name, "plc_input": s.plc_input, "temperature_C": s.temperature_C, "heat": _heat(s)}
                    for s in machine.sensors],
        "drives": [asdict(drive) for drive in machine.drives],
        "drive_settings": asdict(machine.drive_settings),
        "tools": [{"number": tool.number, "ident": tool.ident,
                   "edges": [_edge(edge) for edge in tool.edges]} for tool in machine.tools],
        "tool_settings": {**asdict(machine.tool_settings),
                          "ori_length_components": list(machine.tool_settings.ori_length_components)},
        "work_offsets": {"active": machine.work_offsets.active, "count": machine.work_offsets.count,
                         "shifts_mm": {str(frame): {str(axis): shift for axis, shift in axes.items()}
                                       for frame, axes in machine.work_offsets.shifts_mm.items()}},
        "initial": {name: {str(unit): value for unit, value in units.items()}
                    for name, units in machine.initial.items()},
        "variables_added_or_replaced": extra_vars,
        "settings": {f.name: getattr(machine.settings, f.name) for f in fields(Settings)},
        "settings_changed": [f.name for f in fields(Settings)
                             if getattr(machine.settings, f.name) != getattr(defaults, f.name)],
        "plc": {"data_blocks": {str(n): size for n, size in blocks.items()},
                "inputs_bytes": PLC_AREA_BYTES, "outputs_bytes": PLC_AREA_BYTES,
                "flags_bytes": PLC_AREA_BYTES},
        "passwords": machine.passwords, "connection_access_level": machine.connection_access_level,
        "opcua": opcua_document(opcua),
    }


def _parameters(edge: dict[str, float]) -> str:
    shown = []
    for key, value in edge.items():
        number = int(key[1:])
        unit = parameter_unit(number)
        name = EDGE_PARAMETER_NAMES.get(number, key)
        shown.append(f"{name} {value:g}{' ' + unit if unit else ''}")
    return ", ".join(shown)


def print_machine(doc: dict[str, Any]) -> None:
    print(f"machine '{doc['name']}' ({doc['source']}): {doc['channels']} channel(s), IPO cycle "
          f"{doc['ipo_cycle_s'] * 1000:g} ms, PDU up to {doc['pdu_size_max']} bytes, AMQ {doc['max_amq']}")
    for axis in doc["axes"]:
        low, high = axis["travel_mm"]
        kind = "spindle" if axis["spindle"] else "rotary" if axis["rotary"] else f"travel {low:g}..{high:g} mm"
        # how fast its moves are: the machine data the planner takes (a rotary axis: degrees for mm)
        dynamics = "".join(f", {number} {DYNAMICS_NAMES[number]} {axis[number]['value']:g} {axis[number]['unit']}"
                           + (f" (timed as {axis[number]['timed_as_deg_s2']:g} deg/s^2)"
                              if "timed_as_deg_s2" in axis[number] else "")
                           for number in DYNAMICS_NAMES if number in axis)
        print(f"  axis {axis['number']} {axis['name']}: {kind}{dynamics}"
              f"{'' if axis['referenced'] else ', not referenced'}")
        if axis.get("thermal_um_per_K"):
            print("    thermal error: " + ", ".join(f"{k:g} um/K of {name}" for name, k in axis["thermal_um_per_K"].items()))
    for sensor in doc["sensors"]:
        print(f"  sensor {sensor['name']}: {sensor['plc_input'] or 'no PLC input'}, {sensor['temperature_C']:g} degC")
        print(f"    heat: {_heat_words(sensor['heat'])}")
    for drive in doc["drives"]:
        axis = f"axis {drive['axis']}" if drive["axis"] is not None else "no axis"
        sensor = f", motor sensor {drive['motor_sensor']}" if drive["motor_sensor"] else ""
        print(f"  drive V{drive['number']}: {axis}, {drive['rated_power_kW']:g} kW, {drive['rated_current_A']:g} A, "
              f"{drive['rated_speed_rpm']:g} rpm{sensor}")
    settings = doc["drive_settings"]
    print(f"  drives: DC link {settings['dc_link_V']:g} V, ambient {settings['ambient_C']:g} degC, motor rise "
          f"{settings['motor_rise_K']:g} K, power unit rise {settings['power_unit_rise_K']:g} K")
    tools = doc["tool_settings"]
    print(f"  tools: {tools['cutting_edge_params']} parameters per cutting edge (numCuttEdgeParams), active "
          f"T{tools['active_t']} D{tools['active_d']}")
    for tool in doc["tools"]:
        print(f"  tool T{tool['number']} {tool['ident'] or '(no name)'}: {len(tool['edges'])} edge(s)")
        for number, edge in enumerate(tool["edges"], start=1):
            print(f"    D{number}: {_parameters(edge)}")
    offsets = doc["work_offsets"]
    shifts = "; ".join(f"frame {frame}: " + ", ".join(f"axis {axis} {shift:g} mm" for axis, shift in axes.items())
                       for frame, axes in offsets["shifts_mm"].items())
    print(f"  work offsets: {offsets['count']} settable frames, frame {offsets['active']} active"
          + (f"; {shifts}" if shifts else ""))
    for name, units in doc["initial"].items():
        print(f"  initial {name}: " + ", ".join(f"unit {unit} = {value}" for unit, value in units.items()))
    if doc["variables_added_or_replaced"]:
        print(f"  [[var]] rows: {', '.join(doc['variables_added_or_replaced'])}")
    if doc["settings_changed"]:
        print("  settings: " + ", ".join(f"{name} = {doc['settings'][name]}" for name in doc["settings_changed"]))
    blocks = doc["plc"]["data_blocks"]
    print("  PLC data blocks (number: bytes): " + ", ".join(f"DB{n}: {size}" for n, size in blocks.items())
          + "; no other DB (a read of one is refused)")
    print(f"  PLC inputs, outputs, flags: {PLC_AREA_BYTES} bytes each (I/Q/M 0..{PLC_AREA_BYTES - 1})")
    passwords = ", ".join(f"{name} -> {level}" for name, level in doc["passwords"].items())
    print(f"  access level of a new connection: {doc['connection_access_level']}; passwords: "
          + (passwords or "none (every connection keeps that level)"))
    ua = doc["opcua"]
    anonymous = (", ".join(ua["anonymous_rights"]) or "no rights") if ua["allow_anonymous"] else "refused"
    print(f"  OPC UA (with serve --opcua): security {', '.join(ua['security'])}; anonymous: {anonymous}; "
          f"models: {', '.join(ua['models']) or 'none'}; at most {ua['max_sessions']} sessions, "
          f"{ua['max_subscriptions']} subscriptions, {ua['max_samples_per_s']} samples/s")
    for name, user in ua["users"].items():
        admin = " (admin: manages users)" if user["admin"] else ""
        print(f"    user {name}: {', '.join(user['rights']) or 'no rights'}{admin}")
    print("  NCK variables: the variable table (nckemu vars); e.g. nckemu get SD43900[AX4]")
