"""Attribution among correlated terms (issue 42): a spindle lag and a bed temperature that share
drivers are named together as a move (the lag's time constant searched again beside the bed), and
where two time constants of the spindle explain the data as well, the report says so and why the
measured sensor is named."""

from __future__ import annotations

from pathlib import Path

from nckemu.thermal.discovery.discover import discover_runs
from nckemu.thermal.discovery.settings import Settings
from nckemu.thermal.discovery.wording import finding_lines
from nckemu.thermal.synthetic.scenarios import AXIS, make_correlated_family


def test_the_lag_and_the_bed_are_both_named_and_the_equivalent_explanation_is_said() -> None:
    family = make_correlated_family("correlated_lag_bed", 4)
    result = discover_runs(family.runs, AXIS, family.model)
    named = [(m.effect, m.parameters["sensor"]) for m in result.missing_physics]
    assert named == [("thermal_lag", "spindle"), ("temperature", "bed")]
    move = result.missing_physics[0].evidence.move
    assert move is not None and move.terms == ["thermal_lag(spindle)", "temperature(bed)"]
    weighed = [alt.effects for alt in move.equivalent]
    assert "thermal_lag(spindle) alone" in weighed
    assert any("at two time constants" in w for w in weighed)
    assert "cannot tell them apart" in move.why and "measured sensor" in move.why
    # the JSON carries the same record
    document = result.missing_physics[0].to_json()["evidence"]["move"]
    assert document["why"] == move.why and len(document["equivalent"]) == len(weighed)
    line = next(line for line in finding_lines(result) if line.startswith("why thermal_lag(spindle)"))
    assert "weighed:" in line and "at two time constants" in line


def test_the_html_report_says_what_was_weighed(tmp_path: Path) -> None:
    from nckemu.thermal.discovery.report import write_report

    family = make_correlated_family("correlated_lag_bed", 4)
    result = discover_runs(family.runs, AXIS, family.model)
    page = tmp_path / "report.html"
    write_report(page, result, "correlated_lag_bed")
    text = page.read_text()
    assert "cannot tell them apart" in text and "weighed: thermal_lag(spindle) alone" in text


def test_without_the_partner_search_a_stand_in_or_a_longer_lag_takes_the_beds_place() -> None:
    family = make_correlated_family("correlated_lag_bed", 4)
    result = discover_runs(family.runs, AXIS, family.model, Settings(measured_partners=False))
    assert ("temperature", "bed") not in [(m.effect, m.parameters.get("sensor")) for m in result.missing_physics]


def test_the_null_names_nothing() -> None:
    family = make_correlated_family("null_correlated_lag_bed", 4)
    assert not discover_runs(family.runs, AXIS, family.model).missing_physics
