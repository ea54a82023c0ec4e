"""Real thrusters through the CLI (issue #12 item 1): ``sms compile`` reports the capability and refuses
bad thruster input (exit 2, file:line, a fix, no exception name); ``sms simulate`` runs a thruster
mission in the Python loop with propellant metrics and the /thrusters topics."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from conftest import EXCEPTION_TEXT, ROOT, run_cli

MISSION = ROOT / "tests" / "data" / "thrusters_cube.yaml"

GOOD_A = "{name: a, position: [0, 1, 0], direction: [1, 0, 0], max_force: 22 N, isp: 291 s}"


def _write(tmp_path: Path, thrusters: str, simulation: str = "") -> Path:
    p = tmp_path / "bad.yaml"
    p.write_text(f"extends: {MISSION}\nname: bad\nthrusters:\n{thrusters}{simulation}")
    return p


def _refused(path: Path, *texts: str) -> str:
    r = run_cli("compile", path)
    out = r.stdout + r.stderr
    assert r.exit_code == 2, out
    assert re.search(rf"{re.escape(path.name)}:\d+", out), out
    assert "fix:" in out, out
    assert not EXCEPTION_TEXT.search(out), out
    for t in texts:
        assert t in out, out
    return out


LIST = "  layout: list\n  tank: {propellant: 5 kg}\n  entries:\n"


@pytest.mark.parametrize("entry,text", [
    ("{name: b, link: hubb, position: [0, -1, 0], direction: [-1, 0, 0], max_force: 22 N, isp: 291 s}", "no link named 'hubb'"),
    ("{name: b, position: [0, -1, 0], direction: [0, 0, 0], max_force: 22 N, isp: 291 s}", "zero vector"),
    ("{name: b, position: [0, -1, 0], direction: [-1, 1, 0], max_force: 22 N, isp: 291 s}", "not 1"),
    ("{name: b, position: [0, -1, 0], direction: [-1, 0, 0], max_force: -22 N, isp: 291 s}", "max_force"),
    ("{name: b, position: [0, -1, 0], direction: [-1, 0, 0], max_force: 22 N, isp: -291 s}", "isp"),
])
def test_bad_thruster_is_exit_2_with_location(tmp_path, entry, text):
    _refused(_write(tmp_path, LIST + f"    - {GOOD_A}\n    - {entry}\n"), text)


def test_layout_without_authority_is_refused_with_the_direction(tmp_path):
    """Two thrusters making a couple about z only: the attitude law needs x and y torques."""
    out = _refused(_write(tmp_path, LIST + f"    - {GOOD_A}\n"
                          "    - {name: b, position: [0, -1, 0], direction: [-1, 0, 0], max_force: 22 N, isp: 291 s}\n"),
                   "+x torque", "-y torque")
    assert "+z torque" in out and "-z torque" not in out  # the couple turns about -z only (thrusters cannot pull)


def test_firing_cycle_must_divide_the_control_period(tmp_path):
    out = _refused(_write(tmp_path, "  firing_cycle: 0.3 s\n"), "firing cycles")
    assert "control_rate" in out


def test_unused_thrusters_are_a_compile_warning(tmp_path):
    p = _write(tmp_path, "  size: 1.5 m\n", "simulation:\n  attitude_actuator: wheels\n")
    r = run_cli("compile", p)
    assert r.exit_code == 0, r.output
    assert "no phase uses the thrusters" in r.stdout and re.search(r"bad.yaml:\d+", r.stdout), r.stdout


def test_compile_reports_the_cube_capability():
    r = run_cli("compile", MISSION, "--json")
    assert r.exit_code == 0, r.output
    cap = json.loads(r.stdout)["thrusters"]
    assert cap["count"] == 24
    assert all(v == pytest.approx(88.0, rel=1e-9) for v in cap["pure_force_N"].values())  # 4 F
    assert all(v == pytest.approx(132.0, rel=1e-9) for v in cap["pure_torque_Nm"].values())  # 4 F s, s = 1.5 m
    assert 0 < cap["min_pure_torque_Nm"]["value"] <= 132.0 + 1e-9


def test_simulate_runs_thrusters_in_the_compiled_loop(tmp_path):
    r = run_cli("simulate", MISSION, "-o", tmp_path / "out")
    assert r.exit_code == 0, r.output
    sim = json.loads((tmp_path / "out" / "results.json").read_text())["simulate"]
    assert sim["timing"]["engine"] == "compiled"  # the Python loop's equals it: tests/test_compiled_momentum.py
    used = sim["overall"]["propellant_used_kg"]
    assert used > 0
    assert sum(p["propellant_used_kg"] for p in sim["phases"]) == pytest.approx(used, rel=1e-12)
    assert sim["overall"]["propellant_used_by_law_kg"] == {"mrp_feedback": used}
    from sms_cli.recording.read import messages

    rows: dict[str, list[dict]] = {}
    for topic, _, data in messages(tmp_path / "out" / "simulation.mcap"):
        if topic.startswith(("/thrusters/", "/base/wrench")):
            rows.setdefault(topic, []).append(data)
    assert set(rows) == {"/thrusters/commanded", "/thrusters/delivered", "/thrusters/thrust", "/thrusters/propellant",
                         "/base/wrench"}
    # the plant's base wrench is the thrusters' delivered one, not the ideal command (no disturbances here)
    for wrench, delivered in zip(rows["/base/wrench"], rows["/thrusters/delivered"]):
        assert all(abs(wrench[k] - delivered[k]) <= 1e-9 for k in ("fx", "fy", "fz", "nx", "ny", "nz"))
    assert any(abs(c["nx"]) > 1.0 for c in rows["/thrusters/commanded"])
    assert rows["/thrusters/propellant"][-1]["used_kg"] == pytest.approx(used, rel=1e-9)
    assert len(rows["/thrusters/thrust"][0]) == 24


def test_compiled_engine_runs_real_thrusters(tmp_path):
    p = _write(tmp_path, "  size: 1.5 m\n", "simulation:\n  engine: compiled\n")
    r = run_cli("simulate", p, "-o", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "out" / "results.json").read_text())["simulate"]["timing"]["engine"] == "compiled"
