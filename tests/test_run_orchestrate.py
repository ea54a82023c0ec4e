"""``sms run``: configured stages in order, verdict table, a failing stage does not stop the others,
the exit code is the worst met, stale sections are dropped, absent stage modules are reported."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import MISSIONS, ROOT, run_cli


def test_budget_mission_end_to_end(tmp_path):
    out = tmp_path / "geo"
    # a stale section of an earlier run must not survive (it would reach the report and the check)
    out.mkdir()
    (out / "results.json").write_text(json.dumps({"simulate": {"status": "completed"}, "other": {"kept": 1}}))
    r = run_cli("run", MISSIONS / "hipparcos_geo.yaml", "-o", out, "--no-progress")
    assert r.exit_code == 0, r.output
    data = json.loads((out / "results.json").read_text())
    assert "simulate" not in data and data["other"] == {"kept": 1}
    assert set(data) >= {"budget", "run", "requirements"}
    run = data["run"]
    assert run["state"] == "done" and run["exit_code"] == 0 and len(run["mission_sha256"]) == 64
    statuses = {s["name"]: s["status"] for s in run["stages"]}
    assert statuses == {"compile": "not configured", "budget": "ok", "analyze": "not configured",
                        "synthesize": "not configured", "simulate": "not configured", "report": "ok"}
    assert data["requirements"]["passed"] and len(data["requirements"]["verdicts"]) == 4
    assert (out / "report.html").stat().st_size > 10_000
    # verdict table on stdout, progress on stderr
    assert "budget      ok" in r.stdout and "4/4 met" in r.stdout and "verdict: PASS" in r.stdout
    assert "[1/1] budget" in r.stderr


def test_failing_stage_reported_others_continue(tmp_path):
    # robot + budget + an analysis whose modal configuration names no joint: analyze fails (exit 2),
    # compile and budget still run, the report is written, the exit code is 2
    m = tmp_path / "mixed.yaml"
    m.write_text(
        f"extends: {MISSIONS / 'hipparcos_geo.yaml'}\nname: mixed\n"
        f"robot: {{urdf: {ROOT / 'robots' / 'caldera_smallsat.urdf'}}}\n"
        "analysis:\n  sampling: {method: grid, n: 3}\n  plots: false\n  table: false\n"
        "  modal: {configurations: [{no_such_joint: 0.1}]}\n"
        "requirements:\n  - {name: closes, metric: budget.mass.closes, equals: true}\n"
        "  - {name: modes, metric: 'analysis.modal[0].states', min: 1}\n")
    out = tmp_path / "out"
    r = run_cli("run", m, "-o", out, "--no-progress")
    assert r.exit_code == 2, r.output
    data = json.loads((out / "results.json").read_text())
    statuses = {s["name"]: (s["status"], s["exit_code"]) for s in data["run"]["stages"]}
    assert statuses["compile"] == ("ok", 0) and statuses["budget"] == ("ok", 0)
    assert statuses["analyze"] == ("failed", 2) and statuses["report"] == ("ok", 0)
    assert "no_such_joint" in r.stderr and "FAILED (2)" in r.stdout
    verdicts = {v["name"]: v["status"] for v in data["requirements"]["verdicts"]}
    assert verdicts == {"closes": "pass", "modes": "missing"}
    assert (out / "robot.png").read_bytes()[:4] == b"\x89PNG" and (out / "report.html").exists()


def test_absent_stage_module_is_reported_not_fatal(tmp_path, monkeypatch):
    from sms_cli.run import orchestrate
    from sms_cli.run.stages import STAGES, Stage

    ghost = Stage("budget", "budget", "budget", "sms_cli.no_such_stage_module", "run_it", ())
    monkeypatch.setattr(orchestrate, "STAGES", [ghost] + [s for s in STAGES if s.name != "budget"])
    lines: list[str] = []
    summary = orchestrate.run_mission(MISSIONS / "hipparcos_geo.yaml", tmp_path / "o", report=False, echo=lines.append)
    (stage,) = [s for s in summary.stages if s.name == "budget"]
    assert stage.status == "failed" and stage.exit_code == 2 and "not available" in stage.message
    assert summary.exit_code == 2  # worst of: stage 2, requirements missing 1
    assert all(not v.passed for v in summary.verdicts)
    assert any("not available" in line for line in lines)


def test_invalid_mission_is_an_input_error(tmp_path):
    m = tmp_path / "bad.yaml"
    m.write_text("name: bad\nbudgett: {}\n")
    r = run_cli("run", m, "-o", tmp_path / "o")
    assert r.exit_code == 2 and "did you mean 'budget'" in r.output
    assert not (tmp_path / "o").exists()


def test_stage_order_and_sections():
    from sms_cli.run.stages import STAGES

    assert [s.name for s in STAGES] == ["compile", "budget", "analyze", "synthesize", "simulate"]
    assert [s.section for s in STAGES] == ["compile", "budget", "analysis", "synthesis", "simulate"]
    from sms_cli.check.schema import STAGE_SECTIONS

    assert all(STAGE_SECTIONS[s.name] == s.section for s in STAGES)


def test_help_stays_light():
    import subprocess
    import sys

    code = ("import sys, sms_cli.cli; heavy = {'numpy', 'scipy', 'pinocchio', 'matplotlib', 'cvxpy'} & set(sys.modules); "
            "print(sorted(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"
    assert Path(ROOT / "scripts" / "ci_missions.sh").stat().st_mode & 0o111
