"""The arm in the compiled engine: the arm-law, arm-model and joint-reference kernels against
independent evaluations of their formulas, the compiled joint-space terms (CRBA, RNEA) against
Pinocchio, and missions with an arm run by both loops (trace, metrics and recording equal to 1e-9)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.compiled import arm_laws as K

ROOT = Path(__file__).resolve().parents[1]
ARM_MISSIONS = ["caldera_smallsat.yaml", "astrobee_arm.yaml", "chevallard_chaser.yaml", "demeter_3dof.yaml"]


@pytest.fixture(scope="module", params=ARM_MISSIONS)
def arm_system(request):
    return compile_system(load_mission(ROOT / "missions" / request.param))


def _state(sm, seed):
    rng = np.random.default_rng(seed)
    q = pin.integrate(sm.model, sm.q0, rng.normal(scale=0.7, size=sm.nv))
    return q, rng.normal(scale=0.5, size=sm.nv)


def test_mass_matrix_and_bias_forces_equal_pinocchio(arm_system):
    from sms_cli.sim.compiled.dynamics import bias_forces, joint_transforms, mass_matrix
    from sms_cli.sim.compiled.tree import flatten

    sm = arm_system
    saved = sm.model.armature.copy()
    sm.model.armature[6:] = 0.01 * (1.0 + np.arange(sm.nv - 6))  # rotor inertias on the joints: on M's diagonal
    try:
        T = flatten(sm.model)
        _compare_joint_space_terms(sm, T)
    finally:
        sm.model.armature[:] = saved


def _compare_joint_space_terms(sm, T):
    from sms_cli.sim.compiled.dynamics import bias_forces, joint_transforms, mass_matrix

    n = T.parent.size
    assert T.armature[6:].min() > 0
    for seed in range(3):
        q, v = _state(sm, seed)
        R, p = np.empty((n, 3, 3)), np.empty((n, 3))
        joint_transforms(T.kind, T.axis, T.place_R, T.place_p, T.idx_q, q, R, p)
        M, b = np.empty((sm.nv, sm.nv)), np.empty(sm.nv)
        mass_matrix(T.parent, T.kind, T.axis, T.inertia, T.armature, T.idx_v, R, p, M)
        bias_forces(T.parent, T.kind, T.axis, T.inertia, T.idx_v, R, p, v, b)
        M_ref = sm.rigid_mass_matrix(q)
        b_ref = pin.nonLinearEffects(sm.model, sm.data, q, v)
        assert np.abs(M - M_ref).max() <= 1e-12 * max(1.0, np.abs(M_ref).max())
        assert np.abs(b - b_ref).max() <= 1e-12 * max(1.0, np.abs(b_ref).max())


def _law_case(seed, n=3):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    return dict(q_ref=rng.normal(size=n) * 3, qd_ref=rng.normal(size=n), qdd_ref=rng.normal(size=n),
                q=rng.normal(size=n) * 3, qd=rng.normal(size=n), M=A @ A.T + n * np.eye(n), h=rng.normal(size=n),
                g=[np.abs(rng.normal(size=n)) + 0.1 for _ in range(6)])


def _torque(code, par, wrap, c):
    out = np.empty(len(c["q"]))
    K.arm_torque(code, par, np.asarray(wrap, dtype=np.bool_), c["q_ref"], c["qd_ref"], c["qdd_ref"], c["q"], c["qd"],
                 c["M"], c["h"], out)
    return out


def _par(*rows):
    par = np.zeros((K.ARM_PAR_ROWS, len(rows[0])))
    par[: len(rows)] = rows
    return par


@pytest.mark.parametrize("seed", range(4))
def test_arm_law_kernels_equal_their_formulas(seed):
    c = _law_case(seed)
    g = c["g"]
    wrap = [False, True, False]  # joint 2 continuous: its error modulo 2π into (−π, π]
    e = c["q_ref"] - c["q"]
    e[1] = math.remainder(e[1], 2 * math.pi)
    ed = c["qd_ref"] - c["qd"]
    ok = lambda got, want: np.abs(got - want).max() <= 1e-12 * max(1.0, np.abs(want).max())  # noqa: E731
    # Chevallard 2019 cascaded PD, with and without the rate feedforward
    for ff in (1.0, 0.0):
        want = g[1] * (g[0] * e + ff * c["qd_ref"] - c["qd"])
        assert ok(_torque(K.JOINT_PD, _par(g[0], g[1], np.full(3, ff)), wrap, c), want)
    # Ruggiero 2020 joint SMC, tanh and sign
    sig = -(g[1] * e + ed)
    assert ok(_torque(K.JOINT_SMC, _par(g[0], g[1], g[2], np.zeros(3)), wrap, c), -g[0] * np.tanh(g[2] * sig))
    assert ok(_torque(K.JOINT_SMC, _par(g[0], g[1], g[2], np.ones(3)), wrap, c), -g[0] * np.sign(sig))
    # computed torque
    assert ok(_torque(K.COMPUTED_TORQUE, _par(g[0], g[1]), wrap, c), c["M"] @ (c["qdd_ref"] + g[1] * ed + g[0] * e) + c["h"])
    # Caldera 2019 joint SMC on computed torque, tanh and sign
    s = ed + g[4] * e
    for sign, sw in ((0.0, np.tanh(g[3] * s)), (1.0, np.sign(s))):
        want = c["M"] @ (c["qdd_ref"] + g[0] * ed + g[1] * e + g[2] * sw) + c["h"]
        assert ok(_torque(K.SMC_COMPUTED_TORQUE, _par(g[0], g[1], g[2], g[3], g[4], np.full(3, sign)), wrap, c), want)


def test_arm_model_kernel_is_the_schur_complement():
    rng = np.random.default_rng(3)
    nx = 9
    A = rng.normal(size=(nx, nx))
    M, nb = A @ A.T + nx * np.eye(nx), rng.normal(size=nx)
    a = np.array([6, 7, 8])
    for p in (np.array([0, 1, 2]), np.array([0, 1, 2, 3, 4, 5]), np.zeros(0, dtype=np.int64)):
        Ms, hs = np.empty((3, 3)), np.empty(3)
        K.arm_model_terms(M, nb, a, p.astype(np.int64), Ms, hs)
        if p.size:  # eliminate the free coordinates: with q̈_p = M_pp⁻¹ (τ_p − M_pa q̈_a − n_p) and τ_p = 0
            inv = np.linalg.inv(M[np.ix_(p, p)])
            want_M = M[np.ix_(a, a)] - M[np.ix_(a, p)] @ inv @ M[np.ix_(p, a)]
            want_h = nb[a] - M[np.ix_(a, p)] @ inv @ nb[p]
        else:
            want_M, want_h = M[np.ix_(a, a)], nb[a]
        assert np.abs(Ms - want_M).max() <= 1e-12 * np.abs(want_M).max()
        assert np.abs(hs - want_h).max() <= 1e-12 * max(1.0, np.abs(want_h).max())


def test_joint_reference_kernel_is_the_quintic_through_the_waypoints():
    times = np.array([0.0, 2.0, 5.0])
    points = np.array([[0.0, 1.0], [1.0, -1.0], [3.0, 0.5]])
    for tau, k in ((0.7, 1), (3.1, 2)):
        T = times[k] - times[k - 1]
        s = (tau - times[k - 1]) / T
        d = points[k] - points[k - 1]
        want = (points[k - 1] + (10 * s**3 - 15 * s**4 + 6 * s**5) * d, (30 * s**2 - 60 * s**3 + 30 * s**4) / T * d,
                (60 * s - 180 * s**2 + 120 * s**3) / T**2 * d)
        got = [np.empty(2) for _ in range(3)]
        K.joint_reference(times, points, False, tau, *got)
        for x, y in zip(got, want):
            assert np.abs(x - y).max() <= 1e-12
        K.joint_reference(times, points, True, tau, *got)  # step: the segment's start point, at rest
        assert np.array_equal(got[0], points[k - 1]) and not got[1].any() and not got[2].any()
    got = [np.empty(2) for _ in range(3)]
    K.joint_reference(times, points, False, 9.0, *got)
    assert np.array_equal(got[0], points[-1]) and not got[1].any() and not got[2].any()


# ----------------------------------------------------------------------------- both loops on missions with an arm
def _compare_missions(tmp_path, mission: str):
    """The shipped ``mission`` run by ``engine: python`` (Pinocchio plant and model terms) and by the compiled
    loop: status, steps, metrics, conservation and every recorded message equal to 1e-9 (the joint-stop
    events' numbers included: impulses and rates come from two dynamics implementations)."""
    text = lambda e: (f"extends: {ROOT / 'missions' / mission}\nname: {Path(mission).stem}_{e}\n"  # noqa: E731
                      f"simulation:\n  engine: {e}\n")
    return _compare_missions_text(tmp_path, text)


def _compare_missions_text(tmp_path, text):
    """``_compare_missions`` of the mission text ``text(engine)``."""
    from test_compiled_engine import _messages, _run

    from conftest import assert_tree_close

    (py, py_dir), (cc, cc_dir) = (_run(tmp_path, text(e), e) for e in ("python", "compiled"))
    assert py["timing"]["engine"] == "python" and cc["timing"]["engine"] == "compiled"
    assert (py["status"], py["steps"], py["t_end_s"]) == (cc["status"], cc["steps"], cc["t_end_s"])
    assert_tree_close(py["overall"], cc["overall"], "overall")
    assert_tree_close(py["phases"], cc["phases"], "phases")
    for k, x in py["conservation"].items():
        y = cc["conservation"][k]
        assert (x is None) == (y is None) and (x is None or abs(x - y) <= 1e-9 * max(1.0, abs(x))), k
    a, b = _messages(py_dir / "simulation.mcap"), _messages(cc_dir / "simulation.mcap")
    assert a.keys() == b.keys()
    for topic in a:
        assert [t for t, _ in a[topic]] == [t for t, _ in b[topic]], topic
        if topic == "/robot_description":
            assert [m for _, m in a[topic]] == [m for _, m in b[topic]], topic
            continue
        for (_, x), (_, y) in zip(a[topic], b[topic]):
            if topic == "/log":  # "name {detail as JSON}": the detail's numbers to 1e-9
                x, y = dict(x), dict(y)
                (nx, _, jx), (ny, _, jy) = x.pop("message").partition(" "), y.pop("message").partition(" ")
                assert nx == ny and x == y, topic
                x, y = (json.loads(jx), json.loads(jy)) if jx.startswith("{") else (jx, jy)
            assert_tree_close(x, y, topic)
    return py, a


@pytest.mark.parametrize("mission", ["caldera_s1_slew.yaml", "caldera_s2_arm.yaml", "caldera_s3_slew_arm.yaml",
                                     "astrobee_arm.yaml", "astrobee_slew_twisting.yaml", "astrobee_slew_backstepping.yaml"])
def test_compiled_loop_equals_the_python_loop_on_missions_with_an_arm(tmp_path, mission):
    """computed_torque and smc_computed_torque on the attitude-held model (Caldera S1-S3: M* and h* from the
    compiled CRBA/RNEA against Pinocchio's), the model-free joint smc (Astrobee), step and quintic joint
    references across phases, thrusters and wheels, joint stops (arrivals, contacts, releases), and the
    backstepping law's online inertia J(q) and J̇, which vary with the arm (compiled CRBA against Pinocchio's)."""
    py, msgs = _compare_missions(tmp_path, mission)
    assert py["overall"]["joint_torque_peak"] > 0.0
    events = [m["name"] for _, m in msgs["/events"]]
    assert "joint_stop" in events  # every one of these missions drives a joint onto its stop
    assert py["overall"]["joint_stop_time_s"] > 0.0
    assert any(any(x != 0.0 for x in m.values() if isinstance(x, float)) for _, m in msgs["/joints/torque"])


def test_both_loops_agree_on_an_arm_model_with_an_offset_base_centre_of_mass_and_low_effort_limits():
    """The trace of the two loops (no recording) on caldera_smallsat with its base body's CoM moved off the
    base frame origin and joint effort limits the law exceeds (the shipped robots have the CoM at the origin
    and their arm laws stay below the limits): the base motion (position and base-body momentum
    m₀ R (v + ω × c), ``base_motion.base_kinematics``), the clipped joint torques and the saturation flags,
    and the whole trace, to 1e-9."""
    from sms_cli.sim.engine import Simulation

    loaded = load_mission(ROOT / "missions" / "caldera_smallsat.yaml")
    traces = {}
    for engine in ("python", "compiled"):
        sm = compile_system(loaded)
        Y = sm.model.inertias[1]
        sm.model.inertias[1] = pin.Inertia(Y.mass, np.array([0.05, -0.03, 0.02]), Y.inertia)
        for joint, limit in zip(sm.arm, (0.004, 0.02, 0.01)):  # N m (the URDF's 2 N m are never reached)
            joint.max_effort = limit
        spec = loaded.mission.simulation.model_copy(update={"engine": engine})
        res = Simulation(sm, spec, None, False).run()
        assert res.timing["engine"] == engine and res.status == "completed"
        traces[engine] = res.trace
    a, b = traces["python"], traces["compiled"]
    assert a.keys() == b.keys()
    assert np.abs(a["base_motion"][:, 3:]).max() > 0.01  # kg m/s: the arm pushes the base
    assert a["saturated"].any() and np.abs(a["joint_torque"][:, 0]).max() == 0.004  # clipped to the limit
    for k in a:
        x, y = np.asarray(a[k], float), np.asarray(b[k], float)
        assert x.shape == y.shape, k
        assert np.allclose(x, y, rtol=1e-9, atol=1e-9, equal_nan=True), k


def test_the_compiled_loop_refuses_what_it_does_not_model_of_an_arm():
    """The arm law, the waypoints, the stops, noisy or biased joint sensors (tests/test_compiled_sensors.py)
    and a held base are accepted."""
    from sms_cli.sim.compiled.runner import unsupported_reason
    from sms_cli.sim.schema import NoiseSpec

    loaded = load_mission(ROOT / "missions" / "caldera_s2_arm.yaml")
    sm = compile_system(loaded)
    spec = loaded.mission.simulation
    assert unsupported_reason(sm, spec, spec.attitude) is None
    noisy = spec.model_copy(update={"sensors": spec.sensors.model_copy(update={"joints": NoiseSpec(noise=1e-4)})})
    assert unsupported_reason(sm, noisy, spec.attitude) is None
    biased = spec.model_copy(update={"sensors": spec.sensors.model_copy(update={"joints": NoiseSpec(bias=1e-3)})})
    assert unsupported_reason(sm, biased, spec.attitude) is None
    held = spec.model_copy(update={"phases": [spec.phases[0].model_copy(update={"base_mode": "fixed"}), *spec.phases[1:]]})
    assert unsupported_reason(sm, held, spec.attitude) is None
