"""One home per family: a family registered once reaches the model file, the candidates of a round,
the detectable sizes and the STL generator (or is refused there with a clear reason)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from nckemu.emulator.machine.machine_file import load_machine
from nckemu.plcsim.replay import recording_axis
from nckemu.plcsim.stlgen import generate_program
from nckemu.thermal import stats
from nckemu.thermal.discovery.explain import detectable_um
from nckemu.thermal.discovery.library import Library, bounded, present_key
from nckemu.thermal.discovery.problem import Problem
from nckemu.thermal.discovery.readings import prepare
from nckemu.thermal.discovery.records import Evaluation
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.model import families
from nckemu.thermal.model.families import CandidateSource, Family
from nckemu.thermal.model.terms import Term, ThermalModel, parse_model
from nckemu.thermal.recordings.recording import Recording
from nckemu.thermal.synthetic.scenarios import make_scenario

FIXTURES = Path(__file__).resolve().parents[3] / "fixtures"


def _cube(recording: Recording, _axis: str, p: dict[str, Any]) -> np.ndarray:
    return (recording.sensor(p["sensor"]) - float(p.get("t_ref_C", 20.0))) ** 3


def _cubes(source: CandidateSource, present: set[str]):  # noqa: ANN202 - a generator of proposals
    for sensor in source.sensors():
        if f"cubic_temperature:{sensor}" not in present:
            yield "cubic_temperature", {"sensor": sensor, "t_ref_C": source.t_ref(sensor), "coeff_um_per_K3": 0.0}, 1


def _toy(plc_form: str | None = None) -> Family:
    return Family("cubic_temperature", "coeff_um_per_K3", ("sensor",), {"t_ref_C": 20.0}, 3,
                  "a toy: the cube of one sensor", _cube, _cubes, plc_form=plc_form)


def _library() -> Library:
    scenario = make_scenario("thermal_lag", 1)
    problem = Problem([("r", prepare(scenario.recording, Settings()))], "Z", scenario.baseline)
    return Library(problem, Settings())


def test_a_registered_family_is_a_model_term_and_a_candidate_and_has_a_detectable_size() -> None:
    with families.registered(_toy()):
        model = parse_model('axis = "Z"\n[[term]]\neffect = "cubic_temperature"\nsensor = "spindle"\n'
                            'coeff_um_per_K3 = 0.01\n')
        term = model.terms[0]
        recording = make_scenario("thermal_lag", 1).recording
        assert np.allclose(model.predict_um(recording), 0.01 * (recording.sensor("spindle") - 20.0) ** 3)
        assert present_key(term) == "cubic_temperature:spindle" and bounded(term)

        library = _library()
        design = np.column_stack([library.problem.feature(t) for t in library.problem.base_terms])
        candidates = library.candidates(design, set())
        cubes = [c for c in candidates if c.term.effect == "cubic_temperature"]
        assert {c.term.parameters["sensor"] for c in cubes} == set(library.sensors())
        # ... and it is not offered again once found for that sensor
        again = library.candidates(design, {"cubic_temperature:spindle"})
        assert "cubic_temperature(spindle)" not in {c.label for c in again}

        folds = stats.blocked_folds(len(library.problem.y))
        evaluations = [Evaluation(c, stats.CrossValidation(1.0, tuple(1.0 for _ in folds)), 2.0, 0.5, 3, 1.0,
                                  own_rms=1.0) for c in candidates]
        sizes = detectable_um(evaluations, 1.0, 3.0, 0.1)
        assert "cubic_temperature" in sizes
        # in the registry's order: after every built-in family (registered last)
        assert list(sizes)[-1] == "cubic_temperature"
    assert "cubic_temperature" not in families.names()
    with pytest.raises(Exception, match="unknown effect 'cubic_temperature'"):
        parse_model('axis = "Z"\n[[term]]\neffect = "cubic_temperature"\nsensor = "spindle"\n')


def test_the_stl_generator_asks_the_registry_for_a_family_s_plc_form() -> None:
    machine = load_machine(FIXTURES / "machines" / "loop_mill.toml")
    axis = recording_axis(machine, "Z")
    sensor = "bed"  # on PIW of the loop mill
    cube = Term("cubic_temperature", {"sensor": sensor, "t_ref_C": 20.0, "coeff_um_per_K3": 0.01})
    plain = Term("temperature", {"sensor": sensor, "t_ref_C": 20.0, "coeff_um_per_K": 2.0})
    with families.registered(_toy()):  # no PLC form: refused, with the reason
        program = generate_program(ThermalModel("Z", [plain, cube]), machine, axis)
        assert program.not_compensable == [{"effect": "cubic_temperature", "parameters": cube.parameters,
                                            "why": "not compensable in the PLC: no PLC form for cubic_temperature"}]
    # A family whose feature is a form the PLC writes (here: linear in a sensor) is generated.
    linear = Family("bed_expansion", "coeff_um_per_K", ("sensor",), {"t_ref_C": 20.0}, 1, "a toy: linear",
                    lambda r, _a, p: r.sensor(p["sensor"]) - float(p.get("t_ref_C", 20.0)), plc_form="linear")
    with families.registered(linear):
        term = Term("bed_expansion", {"sensor": sensor, "t_ref_C": 20.0, "coeff_um_per_K": 1.5})
        program = generate_program(ThermalModel("Z", [term]), machine, axis)
        assert program.not_compensable == []
        assert program.generated[0]["plc"] == "c * (T - t_ref)"
        assert f"// bed_expansion {sensor}: 1.5 um/K" in program.text


def test_a_family_must_be_unique_and_name_a_known_plc_form() -> None:
    with pytest.raises(ValueError, match="registered already"):
        families.register(families.family("temperature"))
    with pytest.raises(ValueError, match="unknown PLC form 'cubic'"):
        families.register(_toy(plc_form="cubic"))
    assert "cubic_temperature" not in families.names()
