"""RKMK4 is 4th order on the world angular momentum alone, on a case where the dexp⁻¹ correction
matters: a tumbling asymmetric free body with spinning wheels and a translating base.

Angular momentum about a fixed world point is exactly conserved by the flow, so its drift is the
integrator's error. Rates: |ω| = 3.5 rad/s, mostly about the intermediate axis (tumbling), wheels at
10-30 rad/s, base speed 0.6 m/s. Measured relative drift of k_O over 4 s, dt 0.02 / 0.01 / 0.005 /
0.0025 (0.07-0.009 rad of rotation per step): 2.0e-5, 1.2e-6, 7.6e-8, 4.8e-9, ratios 16.10, 16.07,
16.04 (Python and compiled alike). With the 1/12 [θ, [θ, v]] terms of dexp⁻¹ dropped (the mutation
that passed every other test, in ``sms_cli/dynamics/integrator.py:_dexpinv_neg`` or
``sms_cli/sim/compiled/dynamics.py:dexpinv_neg``) the method is 3rd order: 4.0e-5, 3.9e-6, 4.3e-7,
5.0e-8, ratios 10.2, 9.2, 8.6 → 8, and this test fails (the matching parameter). The ratio is
asserted in [13, 19] on each halving: 16 with room for the measured spread, above 3rd order."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from conftest import compile_path

from sms_cli.dynamics.integrator import State, rkmk4_step

DTS = (0.02, 0.01, 0.005, 0.0025)


@pytest.fixture(scope="module")
def tumbler(tmp_path_factory):
    d = tmp_path_factory.mktemp("tumbler")
    (d / "hub.urdf").write_text(
        '<robot name="hub"><link name="hub"><inertial><mass value="50"/>'
        '<inertia ixx="2" iyy="6" izz="10" ixy="0.3" ixz="-0.2" iyz="0.5"/></inertial></link></robot>')
    wheel = "spin_inertia: 0.1, transverse_inertia: 0.05, mass: 1.0, max_torque: 0.5, max_speed: 1000"
    (d / "m.yaml").write_text(
        "name: tumbler\nrobot: {urdf: hub.urdf, arm_joints: []}\nwheels:\n  declared:\n"
        f"    - {{name: rw1, axis: [1, 0, 0], position: [0.3, 0, 0], {wheel}}}\n"
        f"    - {{name: rw2, axis: [0, 1, 0], position: [0, 0.3, 0], {wheel}}}\n"
        f"    - {{name: rw3, axis: [0, 0, 1], position: [0, 0, 0.3], {wheel}}}\n")
    return compile_path(d / "m.yaml")


def _k_drift(sm, dt, compiled, T=4.0):
    v0 = np.zeros(sm.nv)
    v0[:6] = [0.5, -0.3, 0.2, 1.0, 3.0, -1.5]
    v0[sm.idx.wheels] = [20.0, -30.0, 10.0]
    s = State(sm.q0.copy(), v0, np.zeros(0), np.zeros(0))
    z = np.zeros(sm.nv)
    if compiled:
        from sms_cli.sim.compiled.plant import CompiledPlant

        plant = CompiledPlant(sm)
        step = lambda s: plant.step(s, z, dt)
    else:
        accel = lambda q, v, e, ed: sm.forward_dynamics(q, v, e, ed, z)
        step = lambda s: rkmk4_step(sm.model, s, dt, accel)
    _, k0 = sm.momentum(sm.q0, v0, about="origin")
    for _ in range(round(T / dt)):
        s = step(s)
    _, k1 = sm.momentum(s.q, s.v, about="origin")
    return float(np.linalg.norm(k1 - k0) / np.linalg.norm(k0))


@pytest.mark.parametrize("compiled", [False, True], ids=["python", "compiled"])
def test_angular_momentum_error_is_fourth_order(tumbler, compiled):
    assert np.linalg.norm([1.0, 3.0, -1.5]) * DTS[0] > 0.05  # rotation per step at the coarsest dt (rad)
    errs = [_k_drift(tumbler, dt, compiled) for dt in DTS]
    assert errs[-1] > 1e-10  # far above round-off: the ratios are the truncation error's
    ratios = [a / b for a, b in pairwise(errs)]
    assert all(13.0 <= r <= 19.0 for r in ratios), (errs, ratios)
