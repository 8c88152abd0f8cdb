"""What a machine can have (issue 51): sizes from the structure's expansion over its length, a room
that acts through the structure and never as hysteresis of the air, set in a model file's
[structure] table; a term beyond them fits, but is never named."""

from __future__ import annotations

from dataclasses import replace

import pytest

from nckemu.errors import NckConfigError
from nckemu.thermal.discovery.discover import discover_runs
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.discovery.wording import finding_lines
from nckemu.thermal.model.families import family
from nckemu.thermal.model.structure import Structure
from nckemu.thermal.model.terms import parse_model, render_model
from nckemu.thermal.synthetic.scenarios import AXIS, baseline_model, make_shape_family, make_transient_family


def test_a_room_sensor_never_carries_hysteresis() -> None:
    structure = Structure()
    hysteresis = family("heating_cooling_hysteresis")
    why = hysteresis.cannot_have({"sensor": "temp_hall"}, 2.0, structure)
    assert "the room" in why and "lag" in why
    assert not family("thermal_lag").cannot_have({"sensor": "ambient"}, 2.0, structure)
    assert not hysteresis.cannot_have({"sensor": "spindle"}, 2.0, structure)


def test_sizes_follow_the_structure() -> None:
    # Undeclared: 3 m of steel, 34.5 um/K (1.5 x that for a gradient), generous on purpose.
    assert not family("temperature").cannot_have({"sensor": "spindle_rear"}, 34.0, Structure())
    undeclared = family("temperature").cannot_have({"sensor": "spindle_rear"}, 40.0, Structure())
    assert "more than 34.5 um/K" in undeclared and "3 m of steel (no [structure] declared)" in undeclared
    assert not family("thermal_gradient").cannot_have({"sensors": ["a", "b"]}, 40.0, Structure())
    assert "more than 51.8 um/K" in family("thermal_gradient").cannot_have({"sensors": ["a", "b"]}, 60.0, Structure())
    steel = Structure(length_m=1.0)
    assert not family("temperature").cannot_have({"sensor": "bed"}, 10.3, steel)
    assert "more than 11.5 um/K" in family("temperature").cannot_have({"sensor": "spindle_rear"}, 11.98, steel)
    longer = parse_model('axis = "Z"\n[structure]\nmaterial = "cast_iron"\nlength_m = 2.0\n').structure
    assert longer is not None and longer.um_per_K == pytest.approx(21.0)
    assert not family("temperature").cannot_have({"sensor": "spindle_rear"}, 11.98, longer)
    assert "[structure]" in render_model(parse_model('axis = "Z"\n[structure]\nlength_m = 0.5\n'))
    with pytest.raises(NckConfigError, match="unknown material"):
        parse_model('axis = "Z"\n[structure]\nmaterial = "cheese"\n')
    with pytest.raises(NckConfigError, match="length_m must be a positive number"):
        parse_model('axis = "Z"\n[structure]\nlength_m = -1\n')


def test_a_term_a_machine_cannot_have_is_listed_not_named() -> None:
    """The room's lag at 2.5 um/K on a structure of 0.1 m of steel (1.15 um/K): it fits, and it is
    listed with its figure, never named."""
    shape = make_shape_family("room_acts", 1, runs=12)
    model = baseline_model()
    model.structure = Structure(length_m=0.1)
    result = discover_runs(shape.runs, AXIS, model)
    assert not any(m.parameters.get("sensor") == "ambient" for m in result.missing_physics)
    assert result.cannot_have and all(item.held_back_by == ["physical"] for item in result.cannot_have)
    line = next(line for line in finding_lines(result) if line.startswith("fits, but a machine cannot have it"))
    assert "thermal_lag(" in line and "0.1 m of steel can expand" in line and "median over runs of held-out" in line
    assert result.to_json()["cannot_have"][0]["held_back_by"] == ["physical"]


def test_an_undeclared_structure_still_bounds_sizes() -> None:
    """No [structure]: sizes are bounded by 3 m of steel (34.5 um/K for a lag). The room's lag at 20 x
    room_acts' 2.5 um/K fits, and it is listed with its figure, never named."""
    shape = make_shape_family("room_acts", 1, runs=12)
    model = baseline_model()
    runs = []
    for run in shape.runs:
        given_um = model.predict_um(run)
        runs.append(replace(run, errors_um={AXIS: given_um + 20.0 * (run.errors_um[AXIS] - given_um)}))
    result = discover_runs(runs, AXIS, model)
    assert not any(m.parameters.get("sensor") == "ambient" for m in result.missing_physics)
    line = next(line for line in finding_lines(result) if line.startswith("fits, but a machine cannot have it"))
    assert "thermal_lag(" in line and "3 m of steel (no [structure] declared)" in line


def test_a_term_that_grows_beyond_the_structure_in_the_final_fit_is_withdrawn() -> None:
    """pair_days: the rear at 3 um/K and the front at -1.5 um/K, correlated. The rear named first,
    alone, is smaller than it ends in the joint fit with the front (2.87 um/K); on a structure of
    0.2 m of steel (2.3 um/K) that final size is one a machine cannot have: withdrawn, with its final
    size, and the front, which bought its place only beside it, withdrawn after it."""
    family = make_transient_family("pair_days", 1)
    declared = discover_runs(family.runs, AXIS, family.model, Settings(structure=Structure(length_m=1.0)))
    assert [m.parameters.get("sensor") for m in declared.missing_physics] == ["rear", "front"]
    short = discover_runs(family.runs, AXIS, family.model, Settings(structure=Structure(length_m=0.2)))
    assert not any(m.parameters.get("sensor") == "rear" for m in short.missing_physics)
    rear = next(w for w in short.withdrawn if w.label == "temperature(rear)")
    assert rear.parameters["coeff_um_per_K"] == pytest.approx(2.87, abs=0.05)
    assert rear.why.startswith("fits, but a machine cannot have it at its size in the final fit")
    assert "more than 2.3 um/K" in rear.why and "median over runs of held-out RMS without it" in rear.why
    assert any(line.startswith("withdrawn: temperature(rear): fits, but a machine cannot have it")
               for line in finding_lines(short))
