"""Every shipped mission loads; every mission with a robot compiles through the CLI."""

import json

import pytest
import yaml

from conftest import MISSIONS, run_cli

ALL = sorted(MISSIONS.glob("*.yaml"))
WITH_ROBOT = [p for p in ALL if "robot" in (yaml.safe_load(p.read_text()) or {})]


def test_missions_are_shipped():
    assert ALL, "missions/ is empty"


@pytest.mark.parametrize("path", WITH_ROBOT, ids=[p.stem for p in WITH_ROBOT])
def test_mission_compiles(path):
    r = run_cli("compile", path, "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["total_mass_kg"] > 0
    assert s["dof"]["base"] == 6
    assert s["dof"]["arm"] >= 0
    clamped = sorted(f for a in s["appendages"] for f in a["clamped_frequencies_hz"])
    # Interlacing: freeing the base only lowers each mode's effective mass, so coupled >= clamped, with equality
    # (to round-off) for combinations of identical appendages that do not move the hub (pulsar_full's beams).
    assert all(c >= k * (1 - 1e-12) for c, k in zip(s["coupled_frequencies_hz"], clamped))
