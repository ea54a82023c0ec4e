"""Requirements, metric paths, unit conversion, baselines and JUnit: unit tests with closed-form oracles."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import pytest

from sms_cli.check.baseline import compare, make_baseline, read_baseline, tolerance_for
from sms_cli.check.junit import junit_xml
from sms_cli.check.metric_units import convert, metric_unit
from sms_cli.check.metrics import MetricMissing, numeric_leaves, resolve
from sms_cli.check.requirements import evaluate
from sms_cli.check.schema import RequirementSpec
from sms_cli.errors import InputError

RESULTS = {
    "compile": {"total_mass_kg": 220.0, "dof": {"total": 13}},
    "budget": {"mass": {"closes": True, "final_mass_kg": 835.9}, "scenarios": [
        {"name": "geo", "by_propulsion": {"hydrazine": {"dv_m_s": 248.58375}}}]},
    "analysis": {"variants": {"nominal": {"indices": {"K_m": {"max": 0.7}}, "K_m_worst": 0.7}}},
    "simulate": {
        "overall": {"attitude_error_rad": {"final": math.radians(0.5)}, "settling_time_s": 102.0,
                    "wheel_speed_peak_rad_s": 2 * math.pi * 100 / 60, "end_effector_error_m": {"max": None}},
        "phases": [{"name": "slew", "settling_time_s": 102.0}, {"name": "hold", "settling_time_s": 3.0}],
        "timing": {"wall_s": 2.3},
    },
    "run": {"mission": "m", "date": "2026-01-01T00:00:00Z"},
}


def req(**kw) -> RequirementSpec:
    return RequirementSpec.model_validate({"name": "r", **kw})


# ----------------------------------------------------------------- units


def test_metric_units_from_key_suffixes():
    assert metric_unit("simulate.overall.attitude_error_deg.max") == "deg"
    assert metric_unit("budget.totals.dv_m_s") == "m/s"
    assert metric_unit("simulate.overall.wheel_speed_peak_rad_s") == "rad/s"
    assert metric_unit("simulate.phases[slew].settling_time_s") == "s"
    # a symbol is not a unit: K_m is an index, not metres
    assert metric_unit("analysis.variants.nominal.indices.K_m.max") is None
    assert metric_unit("analysis.variants.nominal.K_m_worst") is None


def test_conversions_match_definitions():
    assert convert(1.0, "deg", "rad") == pytest.approx(math.pi / 180, rel=1e-15)
    assert convert(0.5, "deg", "arcsec") == pytest.approx(1800.0, rel=1e-12)
    assert convert(2 * math.pi, "rad/s", "rpm") == pytest.approx(60.0, rel=1e-12)
    assert convert(2.4, "km/s", "m/s") == pytest.approx(2400.0)
    assert convert(90.0, "s", "min") == pytest.approx(1.5)


def test_bound_with_unit_against_si_metric():
    # 0.5 deg final error: passes "<= 1 deg", fails "<= 0.4 deg"; shown in arcsec it is exactly 1800
    ok = evaluate(req(metric="simulate.overall.attitude_error_rad.final", max="1 deg"), RESULTS)
    assert ok.passed and ok.unit == "rad" and ok.value == pytest.approx(math.radians(0.5))
    bad = evaluate(req(metric="simulate.overall.attitude_error_rad.final", max="0.4 deg"), RESULTS)
    assert bad.status == "fail" and "violates" in bad.message
    shown = evaluate(req(metric="simulate.overall.attitude_error_rad.final", max=1801, unit="arcsec"), RESULTS)
    assert shown.passed and shown.value == pytest.approx(1800.0) and shown.margin == pytest.approx(1.0)
    assert not evaluate(req(metric="simulate.overall.attitude_error_rad.final", max=1799, unit="arcsec"), RESULTS).passed


def test_display_unit_rpm_and_minutes():
    v = evaluate(req(metric="simulate.overall.wheel_speed_peak_rad_s", max=100.0001, unit="rpm"), RESULTS)
    assert v.passed and v.value == pytest.approx(100.0)
    assert evaluate(req(metric="simulate.overall.settling_time_s", max=1.7001, unit="min"), RESULTS).passed
    assert not evaluate(req(metric="simulate.overall.settling_time_s", max=1.69, unit="min"), RESULTS).passed
    both = evaluate(req(metric="simulate.overall.settling_time_s", min="90 s", max="160 s"), RESULTS)
    assert both.passed and both.margin == pytest.approx(12.0)


def test_equals_tolerance_and_flags():
    assert evaluate(req(metric="compile.total_mass_kg", equals=220, tol=0), RESULTS).passed
    assert not evaluate(req(metric="compile.total_mass_kg", equals="220.5 kg", tol="0.4 kg"), RESULTS).passed
    assert evaluate(req(metric="compile.total_mass_kg", equals="220.5 kg", tol="0.5 kg"), RESULTS).passed
    assert evaluate(req(metric="budget.mass.closes", equals=True), RESULTS).passed
    assert evaluate(req(metric="budget.mass.closes", equals=False), RESULTS).status == "fail"
    mixed = evaluate(req(metric="budget.mass.closes", max=1), RESULTS)
    assert mixed.status == "error" and "equals: true/false" in mixed.message


def test_paths_by_name_index_and_stage():
    assert evaluate(req(metric="simulate.phases[hold].settling_time_s", max=3), RESULTS).passed
    assert evaluate(req(metric="simulate.phases[1].settling_time_s", max=3), RESULTS).passed
    assert evaluate(req(metric="simulate.phases.0.settling_time_s", equals=102), RESULTS).passed
    rel = req(metric="overall.settling_time_s", stage="simulate", max=110)
    assert rel.full_metric() == "simulate.overall.settling_time_s" and evaluate(rel, RESULTS).passed
    assert req(metric="variants.nominal.K_m_worst", stage="analyze", max=1).full_metric().startswith("analysis.")
    v = evaluate(req(metric="budget.scenarios[geo].by_propulsion.hydrazine.dv_m_s", equals="248.5837 m/s", tol="0.001 m/s"),
                 RESULTS)
    assert v.passed


def test_missing_metrics_fail_with_clear_messages():
    typo = evaluate(req(metric="simulate.overall.setling_time_s", max=1), RESULTS)
    assert typo.status == "missing" and not typo.passed and "did you mean 'settling_time_s'" in typo.message
    absent = evaluate(req(metric="synthesis.gamma", max=1), RESULTS)
    assert absent.status == "missing" and "did its stage run" in absent.message
    null = evaluate(req(metric="simulate.overall.end_effector_error_m.max", max=1), RESULTS)
    assert null.status == "missing" and "null" in null.message
    listy = evaluate(req(metric="simulate.phases", max=1), RESULTS)
    assert listy.status == "missing" and "list" in listy.message
    with pytest.raises(MetricMissing, match="names: slew, hold"):
        resolve(RESULTS, "simulate.phases[cruise].settling_time_s")
    with pytest.raises(MetricMissing, match="out of range"):
        resolve(RESULTS, "simulate.phases[5]")


def test_schema_rejects_bad_requirements(tmp_path):
    with pytest.raises(ValueError, match="needs a bound"):
        req(metric="compile.total_mass_kg")
    with pytest.raises(ValueError, match="not both"):
        req(metric="compile.total_mass_kg", equals=1, max=2)
    with pytest.raises(ValueError, match="different dimensions"):
        req(metric="simulate.overall.settling_time_s", max="3 kg")
    with pytest.raises(ValueError, match="unknown unit"):
        req(metric="compile.total_mass_kg", max="3 kgs")
    # through the loader: file, line and field
    from sms_cli.mission.load import load_mission

    m = tmp_path / "m.yaml"
    m.write_text("name: x\nrequirements:\n  - {name: a, metric: budget.totals.dv_m_s, max: 2 kg}\n")
    with pytest.raises(InputError) as exc:
        load_mission(m)
    text = exc.value.render()
    assert "m.yaml:3" in text and "requirements.0" in text and "m/s" in text
    m.write_text("name: x\nrequirements:\n  - {name: a, metric: budget.totals.dv_m_s, maxx: 2}\n")
    with pytest.raises(InputError) as exc:
        load_mission(m)
    assert "did you mean 'max'" in exc.value.render()


# ----------------------------------------------------------------- baselines


def test_baseline_selection_and_tolerances():
    b = make_baseline(RESULTS)
    keys = set(b["metrics"])
    assert "simulate.phases[slew].settling_time_s" in keys and "budget.mass.closes" in keys
    assert not any(k.startswith("run.") or ".timing." in k for k in keys)
    assert "simulate.overall.end_effector_error_m.max" not in keys  # null is not a number
    assert tolerance_for("compile.dof.total") == (0.0, 0.0)
    assert tolerance_for("budget.totals.dv_m_s") == (1e-9, 1e-9)
    assert all(isinstance(v, (bool, float)) for _, v in numeric_leaves(RESULTS))


def test_baseline_compare_semantics():
    base = {"format": "sms-baseline/1", "metrics": {
        "compile.total_mass_kg": {"value": 220.0 * (1 + 0.9e-6), "rel_tol": 1e-6, "abs_tol": 0.0},
        "simulate.overall.settling_time_s": {"value": 102.3, "rel_tol": 0.0, "abs_tol": 0.25},
        "budget.mass.closes": {"value": True, "rel_tol": 0, "abs_tol": 0},
        "simulate.overall.gone_s": {"value": 1.0, "rel_tol": 0.1, "abs_tol": 0},
    }}
    d = {x.metric: x for x in compare(RESULTS, base)}
    assert d["compile.total_mass_kg"].passed  # 0.9e-6 relative < 1e-6
    assert not d["simulate.overall.settling_time_s"].passed and "off by 0.3" in d["simulate.overall.settling_time_s"].message
    assert d["budget.mass.closes"].passed
    assert d["simulate.overall.gone_s"].status == "missing"
    base["metrics"]["compile.total_mass_kg"]["value"] = 220.0 * (1 + 1.1e-6)
    assert not {x.metric: x for x in compare(RESULTS, base)}["compile.total_mass_kg"].passed


def test_read_baseline_errors(tmp_path):
    with pytest.raises(InputError, match="no such baseline"):
        read_baseline(tmp_path / "none.json")
    f = tmp_path / "b.json"
    f.write_text("{\"metrics\": {}}")
    with pytest.raises(InputError, match="not an sms baseline"):
        read_baseline(f)
    f.write_text("{\"format\": \"sms-baseline/1\", \"metrics\": {\"a\": {\"value\": 1, \"rel_tol\": -1}}}")
    with pytest.raises(InputError, match="rel_tol"):
        read_baseline(f)
    f.write_text("{oops")
    with pytest.raises(InputError) as exc:
        read_baseline(f)
    assert "b.json:1:2" in exc.value.render() and "not JSON" in exc.value.render()


def test_junit_xml_parses_and_counts():
    verdicts = [evaluate(req(metric="compile.total_mass_kg", max=300), RESULTS),
                evaluate(req(metric="compile.total_mass_kg", max=100), RESULTS),
                evaluate(req(metric="compile.nothing", max=1), RESULTS)]
    base = {"format": "sms-baseline/1", "metrics": {"compile.total_mass_kg": {"value": 220.0, "rel_tol": 0, "abs_tol": 0},
                                                    "compile.dof.total": {"value": 12, "rel_tol": 0, "abs_tol": 0}}}
    root = ET.fromstring(junit_xml("m & <x>", verdicts, compare(RESULTS, base)))
    assert root.tag == "testsuites" and root.get("tests") == "5" and root.get("failures") == "3"
    suites = root.findall("testsuite")
    assert [s.get("tests") for s in suites] == ["3", "2"]
    assert len(root.findall(".//testcase/failure")) == 3
    assert suites[0].get("name") == "m & <x>.requirements"
