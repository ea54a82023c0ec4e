"""The Python API (``import sms_cli as sms``): loading from a path, a string and a mapping, the typed
results of each stage, files written only when asked (and then the CLI's), the CLI's figures,
type hints and ``py.typed``, and the quick-start example run as a user would."""

from __future__ import annotations

import inspect
import json
import math
import os
import subprocess
import sys
import tempfile
import tomllib
import typing
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import DATA, MISSIONS, ROOT, run_cli

import sms_cli as sms

SLEW = MISSIONS / "caldera_s1_slew.yaml"
#: fields that differ between two runs of the same mission (wall-clock times) or name the folder
VOLATILE = {"timing", "total_time_s", "solve_time_s", "build_time_s", "verify_time_s", "mcap", "mission_file"}
FUNCTIONS = ["load_mission", "load_mission_text", "load_mission_dict", "compile", "budget", "analyze", "synthesize",
             "simulate"]


def stable(x):
    """``x`` without the fields that differ between two runs of the same mission."""
    if isinstance(x, dict):
        return {k: stable(v) for k, v in x.items() if k not in VOLATILE}
    if isinstance(x, list):
        return [stable(v) for v in x]
    return x


def short_slew_text(seconds: int = 20) -> str:
    """caldera_s1_slew (the compiled loop under engine: auto) with its slew cut to ``seconds``."""
    text = SLEW.read_text()
    assert "duration: 240 s" in text
    return text.replace("duration: 240 s", f"duration: {seconds} s")


def analysis_mission(tmp_path: Path) -> Path:
    """arm3 (wheels, a flexible panel, a payload) with a small study: a variant, both modal exports, no plots."""
    d = yaml.safe_load((DATA / "arm3.yaml").read_text())
    d["robot"]["urdf"] = str(DATA / "arm3.urdf")
    d["analysis"] = {"sampling": {"method": "grid", "n": 3}, "plots": False,
                     "variants": [{"name": "doubled_wheels", "wheel_inertia_scale": 2}],
                     "modal": {"configurations": [{}, {"j2": "30 deg"}], "export": ["npz", "mat"]}}
    p = tmp_path / "arm3_study.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


def assert_plain_json(x, at: str = "section") -> None:
    """``x`` is plain JSON data, as results.json holds it: no numpy scalar or array, no NaN or infinity."""
    if isinstance(x, dict):
        for k, v in x.items():
            assert type(k) is str, at
            assert_plain_json(v, f"{at}.{k}")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            assert_plain_json(v, f"{at}[{i}]")
    else:
        assert type(x) in (str, int, float, bool, type(None)), f"{at}: {type(x).__name__}"
        assert not (type(x) is float and not math.isfinite(x)), at


def files_in(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir() if p.name != ".sms.lock"}


@pytest.fixture
def empty_cwd_and_tmp(tmp_path, monkeypatch):
    """An empty current folder and an empty temporary folder (TMPDIR and tempfile's cache)."""
    cwd, tmp = tmp_path / "cwd", tmp_path / "tmp"
    cwd.mkdir()
    tmp.mkdir()
    monkeypatch.chdir(cwd)
    monkeypatch.setenv("TMPDIR", str(tmp))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    return cwd, tmp


# ------------------------------------------------------------------ the package surface


def test_every_public_name_resolves_and_is_typed_and_documented():
    for name in sms.__all__:
        assert getattr(sms, name) is not None, name
    for name in FUNCTIONS:
        fn = getattr(sms, name)
        assert fn.__doc__ and len(fn.__doc__) > 80, name
        sig = inspect.signature(fn)
        assert sig.return_annotation is not inspect.Signature.empty, name
        for p in sig.parameters.values():
            assert p.annotation is not inspect.Parameter.empty, (name, p.name)
        hints = typing.get_type_hints(fn)  # the hints resolve (no name only known to a type checker)
        assert "return" in hints, name
    assert typing.get_type_hints(sms.compile)["return"] is sms.SystemModel
    assert typing.get_type_hints(sms.simulate)["return"] is sms.SimulationResult
    assert issubclass(sms.InputError, sms.SmsError) and issubclass(sms.NumericalError, sms.SmsError)
    assert set(sms.__all__) <= set(dir(sms))


def test_py_typed_is_shipped():
    assert (Path(sms.__file__).parent / "py.typed").is_file()
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["sms_cli"]
    assert "py.typed" in data


def test_importing_the_package_stays_light():
    code = ("import sys, sms_cli; sms_cli.InputError; sms_cli.__version__; "
            "print(sorted(m for m in ('numpy', 'pinocchio', 'pydantic', 'sms_cli.api') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]"


# ------------------------------------------------------------------ loading


def test_path_text_and_dict_give_the_same_model():
    text = SLEW.read_text()
    by_path = sms.load_mission(SLEW)
    by_text = sms.load_mission_text(text, base_dir=MISSIONS)
    by_dict = sms.load_mission_dict(yaml.safe_load(text), base_dir=MISSIONS)
    assert by_path.mission == by_text.mission == by_dict.mission
    models = [sms.compile(m) for m in (by_path, by_text, by_dict)]
    for sm in models[1:]:
        assert sm.total_mass == models[0].total_mass and sm.nx == models[0].nx
        np.testing.assert_array_equal(sm.q0, models[0].q0)
        np.testing.assert_array_equal(sm.mass_matrix(sm.q0), models[0].mass_matrix(models[0].q0))
    assert by_text.text == text


def test_paths_inside_a_text_or_dict_resolve_against_base_dir(tmp_path, monkeypatch):
    text = (MISSIONS / "basilisk_rw_reference.yaml").read_text()  # robot.urdf: ../robots/basilisk_hub.urdf
    assert sms.compile(sms.load_mission_text(text, base_dir=MISSIONS)).total_mass == pytest.approx(750.0)
    monkeypatch.chdir(tmp_path)  # the default base_dir is the current folder: the URDF is not found there
    with pytest.raises(sms.InputError) as exc:
        sms.compile(sms.load_mission_text(text))
    assert "basilisk_hub.urdf" in exc.value.render() and "no such file" in exc.value.render()


def test_an_error_in_a_text_mission_reports_its_line_and_column():
    text = short_slew_text()
    lines = text.splitlines()
    k = next(i for i, line in enumerate(lines) if line.strip().startswith("dt:"))
    bad = text.replace("dt: 0.05 s", "dt: 0.05 furlong")
    with pytest.raises(sms.InputError) as exc:
        sms.load_mission_text(bad, base_dir=MISSIONS, name="mine.yaml")
    p = exc.value.problems[0]
    assert p.field == "simulation.dt" and "furlong" in p.message
    assert (p.location.line, p.location.column) == (k + 1, lines[k].index("dt:") + 5)
    assert Path(p.location.file) == MISSIONS.resolve() / "mine.yaml"
    assert f"mine.yaml:{k + 1}:" in exc.value.render()
    with pytest.raises(sms.InputError) as exc:  # a YAML syntax error keeps its line too
        sms.load_mission_text("name: x\nrobot: [1,\n", base_dir=MISSIONS)
    assert exc.value.problems[0].location.line == 3


def test_an_error_in_a_dict_mission_names_its_field_not_the_extended_file():
    data = yaml.safe_load(SLEW.read_text())  # extends caldera_smallsat.yaml, which also sets simulation.dt
    data["simulation"]["dt"] = "3 kg"
    data["simulation"]["phases"][0]["duraton"] = 1
    with pytest.raises(sms.InputError) as exc:
        sms.load_mission_dict(data, base_dir=MISSIONS)
    fields = {p.field: p for p in exc.value.problems}
    assert set(fields) == {"simulation.dt", "simulation.phases.0.duraton"}
    for p in fields.values():
        assert Path(p.location.file).name == "<dict>" and p.location.line == 0
    assert "did you mean 'duration'?" in exc.value.render()
    assert data["extends"] == "caldera_smallsat.yaml"  # the caller's mapping is left as it was


# ------------------------------------------------------------------ the example


def test_the_quickstart_example_runs_and_writes_nothing(tmp_path):
    cwd, tmp = tmp_path / "cwd", tmp_path / "tmp"
    cwd.mkdir()
    tmp.mkdir()
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "api_quickstart.py")], cwd=cwd, capture_output=True, check=False,
                       text=True, env={**os.environ, "TMPDIR": str(tmp)}, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "caldera_s1_slew: mass 220.00 kg, 13 DoF (base 6, wheels 4, arm 3, flexible modes 0)" in r.stdout
    assert "budget: ΔV 3644.3 m/s" in r.stdout and "closes" in r.stdout
    assert "simulate: completed, 30.0 s simulated in 600 steps" in r.stdout
    dt_line = next(k for k, line in enumerate(SLEW.read_text().splitlines(), 1) if line.strip().startswith("dt:"))
    assert f"InputError at line {dt_line}, simulation.dt" in r.stdout
    assert list(cwd.iterdir()) == [] and list(tmp.iterdir()) == []


# ------------------------------------------------------------------ stages: nothing written without out


def test_without_out_no_stage_writes_a_file(tmp_path_factory, empty_cwd_and_tmp):
    cwd, tmp = empty_cwd_and_tmp
    study = analysis_mission(tmp_path_factory.mktemp("missions"))
    b = sms.budget(MISSIONS / "hipparcos_leo.yaml")
    a = sms.analyze(study, plots=True)
    s = sms.synthesize(MISSIONS / "caldera_s1_synthesized.yaml", plots=True)
    r = sms.simulate(MISSIONS / "basilisk_rw_reference.yaml")
    assert list(cwd.iterdir()) == [] and list(tmp.iterdir()) == []
    assert b.files == a.files == s.files == r.files == []
    for res in (b, a, s, r):
        assert_plain_json(res.section)
    assert b.section["artifacts"] == [] and a.section["artifacts"] == []
    assert s.section["files"] == {} and r.section["files"] == {}
    assert isinstance(b, sms.BudgetResult) and isinstance(a, sms.AnalysisResult)
    assert isinstance(s, sms.SynthesisResult) and isinstance(r, sms.SimulationResult)
    assert r.trace["t"].size == 6001 and r.trace["wheel_speed"].shape == (6001, 3)
    assert len(a.linear_models) == 2 and a.linear_models[0].A.shape[0] == a.section["modal"][0]["states"]


def test_a_diverged_simulation_raises_with_what_ran_and_writes_nothing(empty_cwd_and_tmp):
    cwd, tmp = empty_cwd_and_tmp
    data = yaml.safe_load((MISSIONS / "basilisk_rw_reference.yaml").read_text())
    data["simulation"]["divergence"] = {"max_rate": 0.02}  # the initial 0.03 rad/s is already beyond
    with pytest.raises(sms.NumericalError) as exc:
        sms.simulate(sms.load_mission_dict(data, base_dir=MISSIONS))
    res = exc.value.result
    assert res.status == "diverged" and "limit 0.02" in res.divergence and res.files == []
    assert "diverged at t = " in str(exc.value) and "What ran is in" not in str(exc.value)
    assert list(cwd.iterdir()) == [] and list(tmp.iterdir()) == []
    with pytest.raises(sms.NumericalError) as exc:  # with out=, as the CLI: everything written, then the error
        sms.simulate(sms.load_mission_dict(data, base_dir=MISSIONS), out=tmp / "out")
    assert f"What ran is in {tmp / 'out' / 'simulation.mcap'}" in str(exc.value)
    assert {p.name for p in exc.value.result.files} == files_in(tmp / "out") >= {"simulation.mcap", "results.json"}
    assert json.loads((tmp / "out" / "results.json").read_text())["simulate"]["status"] == "diverged"


def test_an_unverified_synthesis_raises_with_its_gains(empty_cwd_and_tmp):
    cwd, tmp = empty_cwd_and_tmp
    data = yaml.safe_load(SLEW.read_text())
    data["synthesis"]["smc"]["max_joint_acceleration"] = 10.0  # a disturbance the wheels cannot reject
    with pytest.raises(sms.NumericalError) as exc:
        sms.synthesize(sms.load_mission_dict(data, base_dir=MISSIONS))
    res = exc.value.result
    assert not res.verified and [c.name for c in res.checks if not c.passed] == ["wheel_authority"]
    assert res.gains.smc is not None and "gains are unverified" in str(exc.value)
    assert list(cwd.iterdir()) == [] and list(tmp.iterdir()) == []


# ------------------------------------------------------------------ stages: out= writes what the CLI writes


def cli_results(cli_args: list, out: Path) -> dict:
    """results.json after ``sms <cli_args> -o out``."""
    r = run_cli(*cli_args, "-o", out)
    assert r.exit_code == 0, r.output
    return json.loads((out / "results.json").read_text())


def _cli_and_api(cli_args: list, api_call, tmp_path: Path, name: str) -> tuple[Path, Path, dict, object]:
    cli, api = tmp_path / f"{name}_cli", tmp_path / f"{name}_api"
    return cli, api, cli_results(cli_args, cli), api_call(api)


@pytest.mark.parametrize("stage", ["budget", "analyze", "synthesize", "simulate"])
def test_out_writes_the_files_the_cli_writes(stage, tmp_path):
    if stage == "budget":
        mission = MISSIONS / "hipparcos_leo.yaml"
        cli, api, cli_json, res = _cli_and_api(["budget", mission], lambda o: sms.budget(mission, out=o), tmp_path, stage)
        same_bytes = ["budget.csv"]
    elif stage == "analyze":
        mission = analysis_mission(tmp_path)
        cli, api, cli_json, res = _cli_and_api(["analyze", mission, "--no-progress", "--csv"],
                                               lambda o: sms.analyze(mission, out=o, csv=True), tmp_path, stage)
        same_bytes = ["analysis_nominal.parquet", "analysis_doubled_wheels.parquet", "analysis_nominal.csv",
                      "analysis_doubled_wheels.csv", "modal_0.npz", "modal_1.npz"]
    elif stage == "synthesize":
        mission = MISSIONS / "caldera_s1_synthesized.yaml"
        cli, api, cli_json, res = _cli_and_api(["synthesize", mission], lambda o: sms.synthesize(mission, out=o),
                                               tmp_path, stage)
        same_bytes = ["gains.yaml"]
    else:
        mission = MISSIONS / "basilisk_rw_reference.yaml"
        cli, api, cli_json, res = _cli_and_api(["simulate", mission, "--no-progress"], lambda o: sms.simulate(mission, out=o),
                                               tmp_path, stage)
        same_bytes = ["simulation.csv"]
    assert files_in(api) == files_in(cli)
    assert sorted(p.name for p in res.files) == sorted(files_in(api)) and all(p.is_file() for p in res.files)
    for f in same_bytes:
        assert (api / f).read_bytes() == (cli / f).read_bytes(), f
    api_json = json.loads((api / "results.json").read_text())
    assert stable(api_json) == stable(cli_json)
    assert json.dumps(stable(res.section)) == json.dumps(stable(next(iter(api_json.values()))))  # same keys, same order


def test_out_records_what_the_cli_records(tmp_path):
    from mcap.reader import make_reader

    mission = MISSIONS / "basilisk_rw_reference.yaml"
    cli, api, _, _ = _cli_and_api(["simulate", mission, "--no-progress"], lambda o: sms.simulate(mission, out=o),
                                  tmp_path, "rec")

    def messages(path: Path) -> list:
        with open(path, "rb") as fh:
            return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(fh).iter_messages()]

    a, c = messages(api / "simulation.mcap"), messages(cli / "simulation.mcap")
    assert len(a) > 6000 and a == c


# ------------------------------------------------------------------ stages: the CLI's figures


def test_budget_figures_are_the_clis(tmp_path):
    mission = MISSIONS / "hipparcos_leo.yaml"
    cli = cli_results(["budget", mission], tmp_path)["budget"]
    b = sms.budget(mission)
    assert b.dv_m_s == cli["totals"]["dv_m_s"] and b.propellant_kg == cli["totals"]["propellant_kg"]
    assert b.wet_mass_kg == cli["mass"]["wet_mass_kg"] and b.closes is cli["mass"]["closes"] is True
    sc = b.scenarios[0]
    assert sc.mission_duration_s == cli["totals"]["mission_duration_s"]
    assert sc.required_wet_mass_kg == cli["mass"]["required_wet_mass_kg"]
    assert sc.steps == cli["scenarios"][0]["steps"]
    assert stable(b.section) == stable({**cli, "artifacts": []})


def test_a_budget_with_several_scenarios_asks_for_one():
    b = sms.budget(MISSIONS / "budget_tradeoff.yaml")
    assert len(b.scenarios) > 1 and all(isinstance(s.dv_m_s, float) for s in b.scenarios)
    with pytest.raises(ValueError, match="scenarios"):
        _ = b.dv_m_s


def test_analysis_figures_are_the_clis(tmp_path):
    mission = analysis_mission(tmp_path)
    cli = cli_results(["analyze", mission, "--no-progress"], tmp_path / "cli")["analysis"]
    a = sms.analyze(mission)
    assert a.samples == cli["samples"] == 27 and a.method == "grid"
    nominal = cli["variants"]["nominal"]
    assert a.nominal.name == "nominal" and a.nominal.K_m_worst == nominal["K_m_worst"]
    assert a.nominal.indices["mu_gjm"].max == nominal["indices"]["mu_gjm"]["max"]
    assert a.nominal.indices["K_m"].p50 == nominal["indices"]["K_m"]["p50"]
    assert a.variants["doubled_wheels"].h_ratio_worst == cli["variants"]["doubled_wheels"]["h_ratio_worst"]
    assert [m["frequency_hz"] for m in a.modal[1]["modes"]] == [m["frequency_hz"] for m in cli["modal"][1]["modes"]]
    npz = np.load(tmp_path / "cli" / "modal_1.npz")
    np.testing.assert_array_equal(a.linear_models[1].A, npz["A"])
    np.testing.assert_array_equal(a.linear_models[1].B, npz["B"])
    assert stable(a.section) == stable({**cli, "artifacts": [], "modal": [{**m, "files": []} for m in cli["modal"]]})


def test_synthesis_figures_are_the_clis(tmp_path):
    mission = MISSIONS / "caldera_s1_synthesized.yaml"
    cli = cli_results(["synthesize", mission], tmp_path)["synthesis"]
    s = sms.synthesize(mission)
    assert s.law == "smc" and s.verified and s.gamma is None
    assert [c.name for c in s.checks] == [c["name"] for c in cli["verification"]["checks"]]
    assert s.gains.smc.c == [g["c_rad_s2"] for g in cli["gains"]]
    assert stable(s.section) == stable({**cli, "files": {}})


def test_lmi_synthesis_result_and_infeasible_lmi(tmp_path):
    import shutil

    shutil.copy(DATA / "hub_hinge.urdf", tmp_path / "hub_hinge.urdf")
    from test_synthesis_stage import HUB

    ok = sms.load_mission_text(HUB.format(decay=0.5, radius=5), base_dir=tmp_path)
    s = sms.synthesize(ok, plots=False)
    assert s.law == "lmi" and s.verified and s.gamma == s.section["gamma"] > 0
    assert s.gains.controller.units == "acceleration" and len(s.gains.controller.kp) == len(s.gains.actuators)
    assert np.asarray(s.gains.observer.L).ndim == 2
    assert isinstance(s.poles[0]["controller"], np.ndarray)
    bad = sms.load_mission_text(HUB.format(decay=10, radius=20), base_dir=tmp_path)
    with pytest.raises(sms.NumericalError, match="infeasible"):
        sms.synthesize(bad)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hub_hinge.urdf"]
    with pytest.raises(sms.NumericalError):
        sms.synthesize(bad, out=tmp_path / "out")
    assert json.loads((tmp_path / "out" / "results.json").read_text())["synthesis"]["status"] == "infeasible"


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_simulation_figures_and_trace_are_the_clis(engine, tmp_path):
    if engine == "compiled":  # Basilisk's scenario: the compiled loop
        mission = MISSIONS / "basilisk_rw_reference.yaml"
    else:  # a shortened Caldera 2019 S1 slew, forced onto the Python loop (with the compiled plant)
        mission = tmp_path / "s1_short.yaml"
        mission.write_text(short_slew_text(20).replace("extends: caldera_smallsat.yaml",
                                                       f"extends: {MISSIONS / 'caldera_smallsat.yaml'}")
                           .replace("simulation:\n", "simulation:\n  engine: python\n", 1))
    cli = cli_results(["simulate", mission, "--no-progress"], tmp_path / "cli")["simulate"]
    res = sms.simulate(mission)
    assert res.section["timing"]["engine"].startswith(engine) and cli["timing"]["engine"] == res.section["timing"]["engine"]
    o = cli["overall"]
    assert res.status == "completed" and res.steps == cli["steps"] and res.t_end_s == cli["t_end_s"]
    assert res.settling_time_s == o["settling_time_s"]
    assert res.attitude_error_final_deg == o["attitude_error_deg"]["final"]
    assert res.attitude_error_max_deg == o["attitude_error_deg"]["max"]
    assert res.wheel_speed_peak_rad_s == o["wheel_speed_peak_rad_s"] and res.wheel_torque_peak_Nm == o["wheel_torque_peak_Nm"]
    assert res.joint_error_max == o["joint_error_max"]
    assert res.angular_momentum_drift_rel == cli["conservation"]["angular_momentum_drift_rel"]
    assert stable(res.section) == stable({**cli, "files": {}})
    with open(tmp_path / "cli" / "simulation.csv") as fh:
        rows = [line.split(",") for line in fh.read().splitlines()[1:]]
    assert len(rows) == res.trace["t"].size
    np.testing.assert_array_equal([float(row[0]) for row in rows], [float(f"{x:.9g}") for x in res.trace["t"]])
    np.testing.assert_array_equal([float(row[2]) for row in rows], [float(f"{x:.9g}") for x in res.trace["att_err"]])
    final = math.degrees(res.trace["att_err"][-1])
    assert final == pytest.approx(res.attitude_error_final_deg, rel=1e-12)


def test_a_simulation_reads_the_gains_a_synthesis_wrote_into_gains_dir(tmp_path):
    data = yaml.safe_load((MISSIONS / "caldera_s1_synthesized.yaml").read_text())  # attitude: from_gains
    data["simulation"]["phases"] = [{"name": "slew", "kind": "slew", "duration": "5 s", "attitude": ["60 deg"] * 3}]
    mission = sms.load_mission_dict(data, base_dir=MISSIONS)
    assert mission.mission.simulation.attitude == "from_gains"
    with pytest.raises(sms.InputError, match="gains.yaml"):
        sms.simulate(mission)
    s = sms.synthesize(mission, out=tmp_path / "gains")
    r = sms.simulate(mission, gains_dir=tmp_path / "gains")
    assert r.status == "completed" and r.t_end_s == pytest.approx(5.0)
    assert r.trace["base_torque"].any() and s.gains.simulation["attitude"]["law"] == "smc"
    assert files_in(tmp_path / "gains") == {"gains.yaml", "results.json", "synthesis_poles.png"}


def test_stage_functions_take_a_path_or_a_loaded_mission():
    leo = MISSIONS / "hipparcos_leo.yaml"
    assert sms.budget(str(leo)).dv_m_s == sms.budget(sms.load_mission(leo)).dv_m_s == sms.budget(leo).dv_m_s
    with pytest.raises(TypeError, match="LoadedMission or the path"):
        sms.budget(yaml.safe_load(leo.read_text()))
    with pytest.raises(sms.InputError, match="no 'budget:' section"):
        sms.budget(MISSIONS / "basilisk_rw_reference.yaml")


def test_out_is_checked_before_any_work(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(sms.InputError, match="must be a folder"):
        sms.budget(MISSIONS / "hipparcos_leo.yaml", out=blocker)
