"""Smooth attitude profiles, held-base phases and resolved-rate end-effector tracking in the compiled loop:
their kernels against closed forms and Pinocchio, and the shipped missions that use them
(caldera_eo, chevallard_deploy_track) run by both loops, trace, metrics and recording equal to 1e-9."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.attitude_math import quat_conj, quat_mul

ROOT = Path(__file__).resolve().parents[1]


# ----------------------------------------------------------------------------- attitude profile
def test_smooth_profile_is_the_quintic_eigen_axis_slew_and_its_rates_are_its_derivatives():
    """q(τ) = q_0 ⊗ exp(p(τ/T) r) (closed form through scipy's rotation vectors), q(T) = the target, and
    ω_ref, ω̇_ref equal the derivatives of the attitude: 2 (q⁻¹ q̇)_v and dω/dτ by central differences."""
    from scipy.spatial.transform import Rotation

    from sms_cli.sim.references import AttitudeProfile

    q0 = Rotation.from_euler("zyx", [0.3, -0.2, 0.1]).as_quat()
    prof = AttitudeProfile(q0, [0.35, -0.17, 0.4], "smooth", 40.0)
    for tau in (0.0, 7.0, 20.0, 33.0, 40.0, 55.0):
        s = min(tau / 40.0, 1.0)
        p = 10 * s**3 - 15 * s**4 + 6 * s**5
        want = (Rotation.from_quat(q0) * Rotation.from_rotvec(p * prof.rotvec)).as_quat()
        got = prof.at(tau).quat
        assert min(np.abs(got - want).max(), np.abs(got + want).max()) <= 1e-14
    assert np.abs(prof.at(40.0).quat - prof.q_target).max() <= 1e-14 or np.abs(prof.at(40.0).quat + prof.q_target).max() <= 1e-14
    h = 1e-4
    for tau in (5.0, 18.0, 31.0):
        r, rp, rm = prof.at(tau), prof.at(tau + h), prof.at(tau - h)
        qdot = (rp.quat - rm.quat) / (2 * h)
        omega = 2.0 * quat_mul(quat_conj(r.quat), qdot)[:3]  # reference frame
        assert np.abs(omega - r.omega).max() <= 1e-8
        assert np.abs((rp.omega - rm.omega) / (2 * h) - r.omega_dot).max() <= 1e-8
    step = AttitudeProfile(q0, [0.35, -0.17, 0.4], "step", None)
    assert np.array_equal(step.at(3.0).quat, step.q_target) and not step.at(3.0).omega.any()


def test_reference_rates_are_the_reference_rates_in_the_base_frame():
    """ω_r = Cᵀ ω_ref with C = R(q_e) base → reference (q_e = q_R⁻¹ ⊗ q_B): by scipy, R_Rᵀ R_B ... transposed."""
    from scipy.spatial.transform import Rotation

    from sms_cli.sim.compiled.control import error_quaternion
    from sms_cli.sim.compiled.profiles import reference_rates

    rng = np.random.default_rng(4)
    for _ in range(5):
        qb, qr = Rotation.random(random_state=rng).as_quat(), Rotation.random(random_state=rng).as_quat()
        w, wd = rng.normal(size=3), rng.normal(size=3)
        qe = np.empty(4)
        error_quaternion(qb, qr, qe)
        C = Rotation.from_quat(qr).as_matrix().T @ Rotation.from_quat(qb).as_matrix()  # base → reference
        out, outd = np.empty(3), np.empty(3)
        reference_rates(qe, w, wd, out, outd)
        assert np.abs(out - C.T @ w).max() <= 1e-14 and np.abs(outd - C.T @ wd).max() <= 1e-14


# ----------------------------------------------------------------------------- Jacobians, held base
@pytest.fixture(scope="module", params=["chevallard_chaser.yaml", "caldera_smallsat.yaml"])
def arm_system(request):
    """A 7-joint arm without wheels and a 3-joint arm with wheels."""
    return compile_system(load_mission(ROOT / "missions" / request.param))


def _placements(sm, q):
    from sms_cli.sim.compiled import dynamics as D
    from sms_cli.sim.compiled.tree import flatten

    T = flatten(sm.model)
    n = T.parent.size
    R, p, oR, op = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3))
    D.joint_transforms(T.kind, T.axis, T.place_R, T.place_p, T.idx_q, q, R, p)
    D.world_placements(T.parent, R, p, oR, op)
    M = np.empty((sm.nv, sm.nv))
    D.mass_matrix(T.parent, T.kind, T.axis, T.inertia, T.armature, T.idx_v, R, p, M)
    return T, R, p, oR, op, M


def test_end_effector_jacobians_equal_pinocchio(arm_system):
    """The frame Jacobian (Pinocchio's LOCAL_WORLD_ALIGNED, rows [ω; v]) and the generalized Jacobians
    J_mEE, J_rEE (``SystemModel.generalized_jacobians``, through Kraiem 2022's seed-convention blocks)."""
    from sms_cli.sim.compiled.resolved_rate import frame_jacobian, generalized_jacobians
    from sms_cli.sim.compiled.tree import frame_table

    sm = arm_system
    fj, fR, fp = frame_table(sm.model, [sm.ee_frame_id])
    rng = np.random.default_rng(2)
    for _ in range(3):
        q = pin.integrate(sm.model, sm.q0, rng.normal(size=sm.nv))
        T, _, _, oR, op, M = _placements(sm, q)
        J, pf = np.empty((6, sm.nv)), np.empty(3)
        frame_jacobian(T.parent, T.kind, T.axis, T.idx_v, oR, op, fj[0], fR[0], fp[0], pf, J)
        pin.computeJointJacobians(sm.model, sm.data, q)
        pin.updateFramePlacements(sm.model, sm.data)
        Jp = pin.getFrameJacobian(sm.model, sm.data, sm.ee_frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        assert np.abs(J - np.vstack([Jp[3:6], Jp[0:3]])).max() <= 1e-13
        assert np.abs(pf - sm.ee_pose(q).translation).max() <= 1e-13
        a, w = np.asarray(sm.idx.arm, dtype=np.int64), np.asarray(sm.idx.wheels, dtype=np.int64)
        Jm, Jr = np.empty((6, a.size)), np.empty((6, w.size))
        generalized_jacobians(M, J, a, w, Jm, Jr)
        G = sm.generalized_jacobians(q)
        assert np.abs(Jm - G["J_mEE"]).max() <= 1e-12 * np.abs(G["J_mEE"]).max()
        if w.size:
            assert np.abs(Jr - G["J_rEE"]).max() <= 1e-12 * max(1.0, np.abs(G["J_rEE"]).max())


def test_held_base_reaction_and_held_inverse_mass_equal_the_fixed_base_model(arm_system):
    """The support's wrench (``SystemModel.base_reaction`` after ``forward_dynamics_fixed_base``) and the
    stop law's columns of the held plant's inverse mass (``PinocchioPlant(fixed=True)``)."""
    from sms_cli.dynamics.joint_stops import PinocchioPlant
    from sms_cli.sim.compiled.dynamics import bias_forces, workspace
    from sms_cli.sim.compiled.held_base import held_base_reaction
    from sms_cli.sim.compiled.stops import _minv

    sm = arm_system
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = pin.integrate(sm.model, sm.q0, rng.normal(size=sm.nv))
        v = rng.normal(size=sm.nv)
        v[:6] = 0.0
        tau = rng.normal(size=sm.nv)
        tau[:6] = 0.0
        T, R, p, _, _, M = _placements(sm, q)
        b = np.empty(sm.nv)
        bias_forces(T.parent, T.kind, T.axis, T.inertia, T.idx_v, R, p, v, b)
        out = np.empty(6)
        held_base_reaction(M, b, tau, out)
        e = np.zeros(0)
        vd, ed = sm.forward_dynamics_fixed_base(q, v, e, e, tau)
        want = sm.base_reaction(q, v, e, e, vd, ed)
        assert np.abs(out - want).max() <= 1e-10 * max(1.0, np.abs(want).max())
        cols = np.asarray(sm.idx.arm[:2], dtype=np.int64)
        tree_a = (T.parent, T.kind, T.axis, T.place_R, T.place_p, T.inertia, T.leaf_IA, T.armature, T.idx_q, T.idx_v)
        G = _minv(tree_a, np.zeros((6, 0)), q, cols, workspace(T.parent.size, sm.nq, sm.nv, 0), True)
        G_ref = PinocchioPlant(sm, fixed=True).inverse_mass_columns(q, cols)
        assert np.abs(G - G_ref).max() <= 1e-10 * np.abs(G_ref).max()


# ----------------------------------------------------------------------------- both loops on the shipped missions
def test_caldera_eo_runs_compiled_and_equals_the_python_loop(tmp_path):
    """Caldera 2019 Earth observation, its first two passes (440 s of the 1100 s; the five passes are alike and
    the mission's requirements hold the whole run in CI): two smooth slews (the SMC law with ω_r, ω̇_r), the
    second from the first's pointing, with arm moves. The recorded reference is the slew's (between the start
    and the target mid-slew)."""
    from test_compiled_arm import _compare_missions_text

    passes = yaml.safe_load((ROOT / "missions" / "caldera_eo.yaml").read_text())["simulation"]["phases"][:2]
    text = lambda e: yaml.safe_dump({"extends": str(ROOT / "missions" / "caldera_eo.yaml"),  # noqa: E731
                                     "name": f"caldera_eo_{e}",
                                     "simulation": {"engine": e, "phases": passes}}, sort_keys=False)
    py, msgs = _compare_missions_text(tmp_path, text)
    assert py["status"] == "completed" and len(py["phases"]) == 2 and py["t_end_s"] == pytest.approx(440.0)
    refs = {round(t / 1e9, 2): m for t, m in msgs["/attitude/reference"]}
    angles = [_ref_angle(refs[t]) for t in (0.0, 50.0, 100.0, 150.0)]
    # the sample at 50 s carries the reference of the tick at 49.9 s (held over the period): the quintic's p(0.499)
    # of the eigen-axis angle; the target from the slew's end (float32 on the topic)
    p = 10 * 0.499**3 - 15 * 0.499**4 + 6 * 0.499**5
    assert angles[0] < 1e-12 and abs(angles[1] - p * angles[3]) < 1e-6 and abs(angles[2] - angles[3]) < 1e-6
    assert 0.025 < py["overall"]["attitude_error_rad"]["max"] < 0.05  # the thesis's band, with the arm moves


def _ref_angle(msg) -> float:
    """The rotation angle (rad) of a recorded /attitude/reference quaternion."""
    return 2.0 * math.atan2(math.sqrt(msg["qx"] ** 2 + msg["qy"] ** 2 + msg["qz"] ** 2), abs(msg["qw"]))


def test_chevallard_deploy_track_runs_compiled_and_equals_the_python_loop(tmp_path):
    """Chevallard 2019: the deployment with the base held (the support's wrench in the trace and on
    /base/reaction, momentum conservation measured without it), then the free-floating resolved-rate
    approach of the drifting grasp point (the generalized Jacobian, the end-effector error)."""
    from test_compiled_arm import _compare_missions

    py, msgs = _compare_missions(tmp_path, "chevallard_deploy_track.yaml")
    deploy, track = py["phases"]
    assert deploy["base_reaction_force_peak_N"] > 0.1 and "base_reaction_force_peak_N" not in track
    assert deploy["end_effector_error_m"]["max"] is None
    assert 0.0 < track["end_effector_error_m"]["final"] < 0.5 * track["end_effector_error_m"]["max"]
    assert "/base/reaction" in msgs and len(msgs["/base/reaction"]) == 70 * 50  # every recorded sample of the held phase
    assert py["overall"]["joint_rate_error_rel_max"] is not None


def test_both_loops_agree_on_a_base_held_after_it_moved_and_tracking_after_it():
    """The whole trace of the two loops (no recording), to 1e-9, on Chevallard's chaser: a free-floating
    deployment step (the arm sets the base moving), the base then held (its velocity taken by the support at
    the phase start, the support's wrench, the momentum segments), then the resolved-rate approach with a
    constant gain per axis (the end-effector error, the tracked joint reference)."""
    from sms_cli.sim.engine import Simulation
    from sms_cli.sim.schema import PhaseSpec

    loaded = load_mission(ROOT / "missions" / "chevallard_deploy_track.yaml")
    spec = loaded.mission.simulation
    deploy, track = spec.phases
    free = PhaseSpec(name="free", kind="deploy", base_mode="free-floating", duration=6.0,
                     waypoints=[{"at": 5.0, "joints": {"joint_2": 0.4, "joint_1": -0.3}}])
    held = deploy.model_copy(update={"duration": 8.0, "waypoints": [w.model_copy(update={"at": 4.0}) for w in deploy.waypoints[:1]]})
    track = track.model_copy(update={"duration": 8.0})
    traces = {}
    for engine in ("python", "compiled"):
        sm = compile_system(loaded)
        res = Simulation(sm, spec.model_copy(update={"engine": engine, "phases": [free, held, track]}), None, False).run()
        assert res.timing["engine"] == engine and res.status == "completed"
        traces[engine] = res.trace
    a, b = traces["python"], traces["compiled"]
    assert a.keys() == b.keys() and "base_motion" not in a  # none while the base is held, so none at all
    held_rows = a["phase"] == 1
    assert np.isfinite(a["base_reaction"][held_rows]).all() and np.isnan(a["base_reaction"][~held_rows]).all()
    assert list(np.unique(a["segment"])) == [0, 1, 2]
    tracking = a["phase"] == 2
    tracking[-1] = False  # the final state's row has no target
    assert np.isfinite(a["ee_err"][tracking]).all() and np.isnan(a["ee_err"][~tracking]).all()
    for k in a:
        x, y = np.asarray(a[k], float), np.asarray(b[k], float)
        assert x.shape == y.shape, k
        assert np.allclose(x, y, rtol=1e-9, atol=1e-9, equal_nan=True), k


# ----------------------------------------------------------------------------- disturbances
def test_disturbance_wrench_is_the_sum_of_the_active_ones_in_the_base_frame():
    """Constant and pulse (start ≤ t < start + duration) wrenches, an inertial one rotated into the base frame
    by Rᵀ (scipy's rotation of the base quaternion)."""
    from scipy.spatial.transform import Rotation

    from sms_cli.sim.compiled.disturbances import disturbance_table, disturbance_wrench
    from sms_cli.sim.schema import DisturbanceSpec

    specs = [DisturbanceSpec(kind="constant", frame="inertial", force=[1.0, -2.0, 0.5], torque=[0.1, 0.2, -0.3]),
             DisturbanceSpec(kind="pulse", frame="base", force=[0.0, 3.0, 0.0], torque=[0.0, 0.0, 0.7], start=2.0, duration=1.5)]
    table = disturbance_table(specs)
    quat = Rotation.from_euler("zyx", [0.4, -0.3, 1.1]).as_quat()
    q = np.concatenate([[1.0, 2.0, 3.0], quat])
    R = Rotation.from_quat(quat).as_matrix()
    const = np.concatenate([R.T @ [1.0, -2.0, 0.5], R.T @ [0.1, 0.2, -0.3]])
    for t, pulse in ((1.99, False), (2.0, True), (3.49, True), (3.5, False)):
        out = np.empty(6)
        disturbance_wrench(table, t, q, out)
        want = const + (np.array([0.0, 3.0, 0.0, 0.0, 0.0, 0.7]) if pulse else 0.0)
        assert np.abs(out - want).max() <= 1e-14, t


def test_compiled_loop_equals_the_python_loop_with_disturbances(tmp_path):
    """tests/data/compiled_disturbances.yaml: constant and pulsed wrenches (base and inertial frames) through a
    wheel slew, a coast and a thruster phase; /base/wrench carries them (plus the thrusters' torque)."""
    from test_compiled_engine import _compare_runs

    text = (ROOT / "tests" / "data" / "compiled_disturbances.yaml").read_text().replace(
        "extends: ../../missions/", f"extends: {ROOT / 'missions'}/")
    py, cc, msgs = _compare_runs(tmp_path, lambda e: text.replace("  record_rate: 2 Hz", f"  record_rate: 2 Hz\n  engine: {e}"))
    wrench = {round(t / 1e9, 2): m for t, m in msgs["/base/wrench"]}
    assert abs(wrench[30.0]["fx"]) > 0.05 and abs(wrench[50.0]["fx"]) < 0.05  # the base-frame pulse, 20.07-35.17 s
    assert py["conservation"]["linear_momentum_drift_abs"] > 0.1  # the external force changed the momentum
