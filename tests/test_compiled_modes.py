"""The compiled loop of the non-NDI laws (``loop.run_ticks``) with flexible modes on the base, against the Python
loop (``engine: python``, Pinocchio: the reference) and against conservation.

The mission is pulsar_simple's robot (Kraiem 2022: 4 wheels, rail + 4-joint arm, two solar arrays of 5 modes
each, the 150 kg tile carried from the start) under a wheel MRP feedback on the attitude and a computed-torque
arm law whose model (``attitude_held``) frees the modes (so M* and h* come from the augmented mass matrix and
bias, with η and η̇), a move of the arm that excites the arrays, the tile released mid-run and a second move.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from test_compiled_engine import _compare_runs, _run

ROOT = Path(__file__).resolve().parents[1]

MISSION = f"""\
extends: {ROOT / 'missions' / 'pulsar_simple.yaml'}
name: pulsar_simple_mrp_ct
simulation:
  engine: ENGINE
  ndi: null
  attitude: {{law: mrp_feedback, K: 20, P: 400}}
  arm: {{law: computed_torque, kp: 1, kd: 2, model: attitude_held}}
  phases:
    - {{name: hold, kind: hold, duration: 2 s, attitude: [0, 0, 0]}}
    - {{name: transfer, kind: move_payload, duration: 12 s, waypoints: [{{at: 6 s, joints: {{rail_joint_1: 0.05, arm_joint_1: 0.05}}}},
       {{at: 12 s, joints: {{arm_joint_2: -0.05, arm_joint_3: 0.03}}}}]}}
    - {{name: release, kind: release, duration: 3 s, detach: [tile]}}
    - {{name: return, kind: deploy, duration: 10 s, waypoints: [{{at: 10 s, joints: {{arm_joint_2: 0, arm_joint_1: 0}}}}]}}
    - {{name: settle, kind: hold, duration: 3 s}}
"""


def _text(engine: str) -> str:
    return MISSION.replace("ENGINE", engine)


def test_engine_auto_takes_a_mission_with_modes_and_a_payload_release():
    from sms_cli.mission.load import load_mission_text
    from sms_cli.sim.compiled.runner import unsupported_reason
    from sms_cli.sim.stage import prepared_simulation

    sm, spec, _ = prepared_simulation(load_mission_text(_text("auto"), base_dir=ROOT / "missions", name="m.yaml"))
    assert sm.n_modes == 10 and spec.ndi is None and any(p.detach for p in spec.phases)
    assert unsupported_reason(sm, spec, spec.attitude) is None


def test_compiled_loop_with_modes_equals_the_python_loop(tmp_path):
    """Status, steps, metrics (their modal peaks among them), conservation and every recorded topic (the modal
    coordinates on /modes, the momenta with the modal terms, μ at (q, v, η̇)) to 1e-9."""
    py, cc, msgs = _compare_runs(tmp_path, lambda e: _text("auto" if e == "compiled" else e))
    assert py["status"] == "completed" and py["steps"] == 3000
    peak = py["overall"]["modal_amplitude_peak"]
    assert peak > 1e-4  # the modes are excited: their dynamics is what the comparison holds
    assert any("modal" in topic or "mode" in topic for topic in msgs)
    seg = [p["modal_amplitude_peak"] for p in py["phases"]]
    assert seg[1] > seg[0]  # the move excites the arrays


def test_momentum_is_conserved_with_modes_on_the_compiled_loop(tmp_path):
    """Wheels, arm and modes exchange momentum internally: the total (modal terms included) stays constant within
    each segment (the release changes the system), to round-off; a loop that dropped the modal momentum from the
    trace or mis-coupled η would drift far above this."""
    sec, _ = _run(tmp_path, _text("compiled"), "compiled")
    assert sec["timing"]["engine"] == "compiled"
    c = sec["conservation"]
    assert c["angular_momentum_drift_rel"] <= 1e-9  # of the largest wheel momentum (N m s)
    assert c["linear_momentum_drift_abs"] <= 1e-9  # kg m/s, from rest
