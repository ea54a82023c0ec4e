"""``sms budget`` through the CLI: shipped missions, artifacts, and the error contract."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from conftest import MISSIONS, run_cli

SHIPPED = ["hipparcos_geo", "hipparcos_leo", "budget_tradeoff"]


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_missions_run(tmp_path, name):
    out = tmp_path / name
    r = run_cli("budget", MISSIONS / f"{name}.yaml", "-o", out)
    assert r.exit_code == 0, r.output
    assert "ΔV [m/s]" in r.output and "CLOSES" in r.output
    data = json.loads((out / "results.json").read_text())["budget"]
    assert data["scenarios"] and all(sc["steps"] for sc in data["scenarios"])
    csv_lines = (out / "budget.csv").read_text().splitlines()
    assert csv_lines[0].startswith("scenario,index,phase,name,type,propulsion,dv_impulsive_m_s")
    assert len(csv_lines) == 1 + sum(len(sc["steps"]) for sc in data["scenarios"])
    for png in ("budget_mass.png", "budget_dv.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob("*.part"))


def test_json_output(tmp_path):
    r = run_cli("budget", MISSIONS / "hipparcos_leo.yaml", "-o", tmp_path, "--json")
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    aero = next(s for s in data["scenarios"][0]["steps"] if s["type"] == "aerobraking")
    assert aero["coast_duration_s"] is None and aero["duration_tbd"] and aero["dv_m_s"] == 0.0
    assert data["totals"]["duration_tbd_steps"] == 1


def _write(tmp_path, text: str):
    p = tmp_path / "m.yaml"
    p.write_text(text)
    return p


BASE = """name: t
budget:
  propulsion:
    chem: {kind: chemical, isp: 300 s, thrust: 100 N}
  spacecraft: {dry_mass: 500 kg}
  initial_orbit: {perigee: 300 km, apogee: 300 km, inclination: 28.5 deg}
  sequence:
    - {type: hohmann, altitude: 35786 km}
"""


def test_small_mission_sizes_the_wet_mass(tmp_path):
    r = run_cli("budget", _write(tmp_path, BASE), "-o", tmp_path / "o", "--json")
    assert r.exit_code == 0, r.output
    m = json.loads(r.stdout)["mass"]
    assert m["wet_mass_source"] == "sized" and m["closes"]
    assert m["final_mass_kg"] == pytest.approx(500.0, rel=1e-9)


def test_bad_key_gives_location_and_suggestion(tmp_path):
    bad = BASE.replace("{type: hohmann, altitude: 35786 km}", "{type: hohmann, altitud: 35786 km}")
    r = run_cli("budget", _write(tmp_path, bad), "-o", tmp_path / "o")
    assert r.exit_code == 2
    assert "m.yaml:8" in r.stderr and "did you mean 'altitude'" in r.stderr
    assert "Traceback" not in r.output + r.stderr


def test_unknown_step_type(tmp_path):
    bad = BASE.replace("type: hohmann", "type: hohman")
    r = run_cli("budget", _write(tmp_path, bad), "-o", tmp_path / "o")
    assert r.exit_code == 2 and "m.yaml:8" in r.stderr and "hohmann" in r.stderr


def test_missing_budget_section(tmp_path):
    r = run_cli("budget", _write(tmp_path, "name: nothing\n"), "-o", tmp_path / "o")
    assert r.exit_code == 2
    assert "no 'budget:' section" in r.stderr
    assert not (tmp_path / "o" / "results.json").exists()


@pytest.mark.parametrize("orbit,msg", [
    ("{perigee: 800 km, apogee: 300 km}", "above apogee"),
    ("{perigee: -100 km, apogee: 300 km}", "below the surface"),
    ("{semi_major_axis: 6000 km, eccentricity: 0.01}", "below the surface"),
])
def test_impossible_orbits(tmp_path, orbit, msg):
    bad = BASE.replace("{perigee: 300 km, apogee: 300 km, inclination: 28.5 deg}", orbit)
    r = run_cli("budget", _write(tmp_path, bad), "-o", tmp_path / "o")
    assert r.exit_code == 2, r.output
    assert msg in r.stderr and "m.yaml:6" in r.stderr


def test_step_below_surface_is_located(tmp_path):
    bad = BASE.replace("{type: hohmann, altitude: 35786 km}", "{type: deorbit, perigee: -7000 km}")
    r = run_cli("budget", _write(tmp_path, bad), "-o", tmp_path / "o")
    assert r.exit_code == 2 and "m.yaml:8" in r.stderr


def test_budget_that_cannot_close(tmp_path):
    bad = BASE.replace("  spacecraft: {dry_mass: 500 kg}\n", "  spacecraft: {dry_mass: 500 kg}\n  margins: {propellant: 0.3}\n")
    bad = bad.replace("{type: hohmann, altitude: 35786 km}", "{type: allowance, dv: 6 km/s}")
    r = run_cli("budget", _write(tmp_path, bad), "-o", tmp_path / "o")
    assert r.exit_code == 2
    assert "cannot close" in r.stderr and "exceeds what the Isp allows" in r.stderr
    assert "Traceback" not in r.stderr


def test_unknown_propulsion_name(tmp_path):
    bad = BASE.replace("{type: hohmann, altitude: 35786 km}", "{type: hohmann, altitude: 35786 km, propulsion: chen}")
    r = run_cli("budget", _write(tmp_path, bad), "-o", tmp_path / "o")
    assert r.exit_code == 2 and "did you mean 'chem'" in r.stderr


def test_cli_start_stays_light():
    code = "import sys, sms_cli.cli, sms_cli.mission.load; print(any(m in sys.modules for m in ('numpy', 'scipy', 'matplotlib')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "False"
