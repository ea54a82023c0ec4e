"""``sms analyze`` through the CLI: artifacts, results.json, errors with a location and a fix."""

from __future__ import annotations

import json

import pyarrow.parquet as pq
import pytest
import yaml

from conftest import MISSIONS, run_cli

BLOCKS = {
    "demeter_3dof": {"sampling": {"method": "grid", "n": 7, "symmetry": {"joint": "joint_1", "keep": "upper", "about": 0}},
                     "variants": [{"name": "doubled_wheels", "wheel_inertia_scale": 2}]},
    "pulsar_simple": {"sampling": {"method": "sobol", "n": 256}, "modal": {"configurations": [{}, {"arm_joint_2": "30 deg"}]}},
    "caldera_smallsat": {"sampling": {"method": "grid", "n": 6}},
    "astrobee_arm": {"arm_joints": ["proximal_joint", "distal_joint"], "sampling": {"method": "grid", "n": 9}},
    "chevallard_chaser": {"sampling": {"method": "sobol", "n": 256}},
}


def mission_with(name: str, block: dict, tmp_path):
    d = yaml.safe_load((MISSIONS / f"{name}.yaml").read_text())
    d["robot"]["urdf"] = str((MISSIONS / d["robot"]["urdf"]).resolve())
    d["analysis"] = block
    p = tmp_path / f"{name}.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


@pytest.mark.parametrize("name", list(BLOCKS))
def test_analyze_every_robot(name, tmp_path):
    path = mission_with(name, BLOCKS[name], tmp_path)
    out = tmp_path / "out"
    r = run_cli("analyze", path, "-o", out, "--no-plots")
    assert r.exit_code == 0, r.output
    sec = json.loads((out / "results.json").read_text())["analysis"]
    table = pq.read_table(out / "analysis_nominal.parquet")
    assert table.num_rows == sec["samples"] and table.column_names[0] == "sample"
    assert not (out / "analysis_nominal.csv").exists()  # CSV only when asked for (--csv, analysis.table)
    assert sec["variants"]["nominal"]["indices"]["mu_gjm"]["max"] > 0


def test_demeter_study_with_plots_and_variant(tmp_path):
    path = mission_with("demeter_3dof", BLOCKS["demeter_3dof"], tmp_path)
    out = tmp_path / "out"
    r = run_cli("analyze", path, "-o", out)
    assert r.exit_code == 0, r.output
    sec = json.loads((out / "results.json").read_text())["analysis"]
    assert sec["samples"] == 7**3
    assert sec["comparison"]["doubled_wheels"]["K_m"]["fraction_lower"] == 1.0
    assert sec["variants"]["doubled_wheels"]["K_m_worst"] < sec["variants"]["nominal"]["K_m_worst"]
    for f in sec["artifacts"]:
        assert (out / f).stat().st_size > 0, f
    assert "analysis_compare_K_m.png" in sec["artifacts"] and "analysis_nominal_slices.png" in sec["artifacts"]
    assert "K_m lower at 100.0% of samples" in r.stdout


def test_modal_section_and_files(tmp_path):
    path = mission_with("pulsar_simple", BLOCKS["pulsar_simple"], tmp_path)
    out = tmp_path / "out"
    r = run_cli("analyze", path, "-o", out, "--no-plots", "--json")
    assert r.exit_code == 0, r.output
    sec = json.loads(r.stdout)
    assert len(sec["modal"]) == 2
    for m in sec["modal"]:
        assert len(m["modes"]) == 10
        assert all((out / f).exists() for f in m["files"])
    assert sec["modal"][1]["configuration"]["arm_joint_2"] == pytest.approx(0.5235987755982988)


def test_unknown_joint_is_an_input_error_with_a_suggestion(tmp_path):
    path = mission_with("demeter_3dof", {"sampling": {"method": "grid", "n": 3, "joints": ["joint_l"]}}, tmp_path)
    r = run_cli("analyze", path, "-o", tmp_path / "out")
    assert r.exit_code == 2
    assert "analysis.sampling.joints" in r.output and "unknown name 'joint_l'" in r.output
    assert "did you mean 'joint_" in r.output and ".yaml:" in r.output


def test_too_many_samples_is_refused_with_a_fix(tmp_path):
    path = mission_with("chevallard_chaser", {"sampling": {"method": "grid", "n": 19}}, tmp_path)
    r = run_cli("analyze", path, "-o", tmp_path / "out")
    assert r.exit_code == 2 and "max_samples" in r.output and "sobol" in r.output
