"""``sms check`` through the CLI: shipped baselines pass; tightened requirements and perturbed
parameters fail with exit 1; JUnit XML parses; missing metrics are failures, not crashes."""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conftest import MISSIONS, ROOT, run_cli

BASELINES = ROOT / "baselines"


def _run(mission: Path, out: Path, *extra: str):
    r = run_cli("run", mission, "-o", out, "--no-progress", *extra)
    assert r.exit_code in (0, 1), r.output
    return r


def _junit(path: Path) -> ET.Element:
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    assert int(root.get("tests")) == len(root.findall(".//testcase"))
    return root


@pytest.mark.parametrize("name", ["hipparcos_geo", "hipparcos_leo"])
def test_shipped_budget_missions_pass_their_baselines(tmp_path, name):
    out = tmp_path / name
    r = _run(MISSIONS / f"{name}.yaml", out, "--no-report")
    assert r.exit_code == 0, r.output
    junit = tmp_path / "j.xml"
    r = run_cli("check", out, "--baseline", BASELINES / f"{name}.json", "--junit", junit)
    assert r.exit_code == 0, r.output
    assert "4/4 requirements met" in r.output and "metrics within tolerance" in r.output
    root = _junit(junit)
    assert root.get("failures") == "0" and int(root.get("tests")) > 100
    assert {s.get("name") for s in root.findall("testsuite")} == {f"{name}.requirements", f"{name}.baseline"}


@pytest.fixture(scope="module")
def geo_results(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("geo") / "hipparcos_geo"
    _run(MISSIONS / "hipparcos_geo.yaml", out, "--no-report")
    return out


def _mission_copy(tmp_path: Path, parent: str, body: str) -> Path:
    m = tmp_path / f"{parent}_variant.yaml"
    m.write_text(f"extends: {MISSIONS / (parent + '.yaml')}\nname: {parent}\n{body}")
    return m


def test_tightened_requirement_fails(tmp_path, geo_results):
    # the smallest closing wet mass is 980.9 kg: a 950 kg cap must fail, a 1000 kg cap pass
    for cap, code in ((1000, 0), (950, 1)):
        m = _mission_copy(tmp_path, "hipparcos_geo", f"requirements:\n  - {{name: wet, metric: budget.mass.required_wet_mass_kg, max: {cap} kg}}\n")
        junit = tmp_path / f"j{cap}.xml"
        r = run_cli("check", geo_results, "--mission", m, "--junit", junit)
        assert r.exit_code == code, r.output
        root = _junit(junit)
        assert root.get("failures") == str(code)
        if code:
            assert "FAIL" in r.output and "violates <= 950 kg" in r.output
            assert "required_wet_mass_kg" in root.find(".//failure").get("message")


def test_perturbed_isp_fails_the_baseline(tmp_path):
    # hydrazine Isp 225 s -> 230 s: same ΔV (the baseline keeps it), less propellant (it catches it)
    m = _mission_copy(tmp_path, "hipparcos_geo", "budget:\n  propulsion:\n    hydrazine: {isp: 230 s}\n")
    out = tmp_path / "perturbed"
    _run(m, out, "--no-report")
    junit = tmp_path / "j.xml"
    r = run_cli("check", out, "--baseline", BASELINES / "hipparcos_geo.json", "--junit", junit)
    assert r.exit_code == 1, r.output
    fails = {tc.get("name") for tc in _junit(junit).findall(".//testcase") if tc.find("failure") is not None}
    assert "budget.propulsion.hydrazine.isp_s" in fails
    assert "budget.scenarios[hipparcos_geo].totals.propellant_kg" in fails
    assert "budget.scenarios[hipparcos_geo].by_propulsion.hydrazine.dv_m_s" not in fails


def test_perturbed_wheel_inertia_fails_the_baseline(tmp_path):
    # Caldera S1 slew with 10 % more wheel spin inertia: different wheel speeds and model figures
    src = (MISSIONS / "caldera_smallsat.yaml").read_text()
    assert 'spin_inertia: "0.0796 kg m^2"' in src
    parent = tmp_path / "caldera_smallsat.yaml"
    parent.write_text(src.replace('spin_inertia: "0.0796 kg m^2"', 'spin_inertia: "0.08756 kg m^2"').replace(
        "../robots/", str(ROOT / "robots") + "/"))
    child = tmp_path / "caldera_s1_slew.yaml"
    child.write_text((MISSIONS / "caldera_s1_slew.yaml").read_text())
    out = tmp_path / "out"
    _run(child, out, "--no-report")
    junit = tmp_path / "j.xml"
    r = run_cli("check", out, "--baseline", BASELINES / "caldera_s1_slew.json", "--junit", junit)
    assert r.exit_code == 1, r.output
    fails = {tc.get("name") for tc in _junit(junit).findall(".//testcase") if tc.find("failure") is not None}
    assert "compile.wheels[rw1].spin_inertia_kgm2" in fails
    assert "simulate.overall.wheel_speed_peak_rad_s" in fails  # same momentum, 10 % slower wheels
    assert "compile.total_mass_kg" not in fails


def test_missing_metric_is_a_failure_not_a_crash(tmp_path, geo_results):
    m = _mission_copy(tmp_path, "hipparcos_geo",
                      "requirements:\n  - {name: sim, metric: simulate.overall.attitude_error_deg.max, max: 1 deg}\n")
    r = run_cli("check", geo_results, "--mission", m)
    assert r.exit_code == 1, r.output
    assert "MISSING" in r.output and "no section 'simulate'" in r.output
    base = json.loads((BASELINES / "hipparcos_geo.json").read_text())
    base["metrics"]["budget.totals.no_such_s"] = {"value": 1.0, "rel_tol": 0.0, "abs_tol": 0.0}
    bf = tmp_path / "b.json"
    bf.write_text(json.dumps(base))
    r = run_cli("check", geo_results, "--baseline", bf)
    assert r.exit_code == 1 and "MISSING budget.totals.no_such_s" in r.output, r.output


def test_write_baseline_then_pass_and_usage_errors(tmp_path, geo_results):
    bf = tmp_path / "new.json"
    r = run_cli("check", geo_results, "--write-baseline", bf)
    assert r.exit_code == 0 and bf.exists(), r.output
    assert run_cli("check", geo_results, "--baseline", bf).exit_code == 0
    empty = tmp_path / "empty"
    empty.mkdir()
    shutil.copy(geo_results / "results.json", empty / "results.json")
    data = json.loads((empty / "results.json").read_text())
    data.pop("requirements")
    (empty / "results.json").write_text(json.dumps(data))
    r = run_cli("check", empty)
    assert r.exit_code == 2 and "nothing to check" in r.output
    r = run_cli("check", tmp_path / "nowhere")
    assert r.exit_code == 2 and "no results.json" in r.output
