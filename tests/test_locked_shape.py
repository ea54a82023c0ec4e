"""Locked/shape quantities (sms_cli/dynamics/locked.py, Vicariotto 2023 ch. 4) against definitions built
here from Pinocchio's CRBA and centroidal inertia, on a non-orthogonal 4-wheel pyramid mounted off the base
origin (CoM off the base origin, so the translation must be reduced out), on Basilisk's three orthogonal
wheels (A = I), and on models with an arm (Caldera) and with an arm + modes (PULSAR).

Claims: Λ, μ, M_θ, I, G, J equal the definitions to 1e-12; T⁻ᵀ M T⁻¹ is block-diagonal to 1e-12 and
the kinetic energy is the same in both coordinates; R I μ (world angular momentum about the CoM) is
conserved along a torque-free run while μ is not; /momentum/locked is the same in both loops and equals
the module's value at the recorded samples; ``sms compile --json`` reports the locked inertia and |Λ|.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from conftest import MISSIONS, ROOT, compile_path, run_cli

from sms_cli.recording.read import messages as read_messages
from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.dynamics.locked import locked_shape, locked_velocities, locked_velocity, shape_invariant

PYRAMID = """\
extends: basilisk_rw_reference.yaml
name: locked_pyramid
wheels:
  declared: []
  arrays:
    - {name: rw, layout: pyramid, count: 4, beta: "54.7356 deg", azimuth0: "15 deg", mount: hub, position: [0.3, -0.2, 0.15],
       radius: 0.25, rpy: [0.1, -0.2, 0.3], spin_inertia: 0.05, transverse_inertia: 0.03, mass: 6.0,
       max_torque: "0.2 N m", max_speed: "6000 rpm", initial_speed: "500 rpm"}
simulation:
  record_rate: 2 Hz
  engine: ENGINE
  phases:
    - {name: detumble, kind: hold, duration: 120 s, base_mode: rotation-free-floating, attitude: [0, 0, 0]}
"""


def _write_missions(d: Path, engine: str = "auto") -> Path:
    (d / "basilisk_rw_reference.yaml").write_text(
        (MISSIONS / "basilisk_rw_reference.yaml").read_text().replace("../robots/", str(ROOT / "robots") + "/"))
    path = d / f"pyramid_{engine}.yaml"
    path.write_text(PYRAMID.replace("ENGINE", engine))
    return path


@pytest.fixture(scope="module")
def pyramid(tmp_path_factory):
    return compile_path(_write_missions(tmp_path_factory.mktemp("pyr")))


@pytest.fixture(scope="module")
def basilisk():
    return compile_path(MISSIONS / "basilisk_rw_reference.yaml")


@pytest.fixture(scope="module", params=["caldera_s1_slew.yaml", "pulsar_simple.yaml"])
def arm_model(request):
    return compile_path(MISSIONS / request.param)


def _random_state(sm, seed):
    rng = np.random.default_rng(seed)
    q = pin.integrate(sm.model, sm.q0, 0.5 * rng.normal(size=sm.nv))
    return q, rng.normal(size=sm.nx)


def _crba(sm, q):
    """Mass matrix straight from Pinocchio (augmented with the modal blocks when there are modes)."""
    M = sm.mass_matrix(q)
    H = pin.crba(sm.model, sm.model.createData(), q)
    H = np.triu(H) + np.triu(H, 1).T
    assert np.abs(M[: sm.nv, : sm.nv] - H).max() <= 1e-12 * np.abs(H).max()
    M[: sm.nv, : sm.nv] = H
    return M


def _centroidal_inertia_base(sm, q):
    """Locked inertia by another route: Pinocchio's centroidal composite inertia (world axes) in base axes."""
    d = sm.model.createData()
    pin.ccrba(sm.model, d, q, np.zeros(sm.nv))
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    return R.T @ d.Ig.inertia @ R, R


def _close(a, b, tol=1e-12):
    scale = max(1.0, float(np.abs(b).max()))
    assert np.abs(np.asarray(a) - np.asarray(b)).max() <= tol * scale, np.abs(np.asarray(a) - np.asarray(b)).max()


@pytest.mark.parametrize("which", ["pyramid", "basilisk"])
def test_definitions_against_crba(which, request):
    sm = request.getfixturevalue(which)
    wheels = np.asarray(sm.idx.wheels)
    if which == "pyramid":  # the array is non-orthogonal and off the base origin: a real test of G and the reduction
        axes = np.array([w.axis for w in sm.wheels]).T
        assert len(sm.wheels) == 4 and np.abs(axes.T @ axes - np.eye(4)).max() > 0.1
    for seed in range(3):
        q, x = _random_state(sm, seed)
        M = _crba(sm, q)
        ls = locked_shape(sm, q)
        Mbb = M[:6, :6]
        I_ref, R = _centroidal_inertia_base(sm, q)
        _close(ls.I, I_ref)
        G_ref = np.array([w.axis for w in sm.wheels]).T
        J_ref = np.array([w.spin_inertia for w in sm.wheels])
        _close(ls.G, G_ref)
        _close(ls.J, J_ref)
        # Λ: the angular rows of the 6-D connection M_bb⁻¹ M_bθ, and the thesis's I⁻¹ G J with the declared axes
        _close(ls.Lambda, np.linalg.solve(Mbb, M[:6, wheels])[3:6])
        _close(ls.Lambda, np.linalg.solve(I_ref, G_ref * J_ref))
        # μ: the angular part of the locked 6-twist M_bb⁻¹ (M x)_b, and I⁻¹ × angular momentum about the CoM
        mu = ls.locked_velocity(x)
        _close(mu, np.linalg.solve(Mbb, (M @ x)[:6])[3:6])
        _, k_com, _ = sm.momenta(q, x[: sm.nv], x[sm.nv:])
        _close(mu, np.linalg.solve(I_ref, R.T @ k_com))
        _close(locked_velocity(sm, q, x[: sm.nv]), mu)
        # M_θ: Schur complement of the base block, and the thesis's J − J Gᵀ I⁻¹ G J
        Mbw = M[:6, wheels]
        _close(ls.M_theta, M[6:, 6:] - M[:6, 6:].T @ np.linalg.solve(Mbb, M[:6, 6:]))
        _close(ls.M_theta_wheels, np.diag(J_ref) - (G_ref * J_ref).T @ np.linalg.solve(I_ref, G_ref * J_ref))
        _close(ls.M_theta_wheels, M[np.ix_(wheels, wheels)] - Mbw.T @ np.linalg.solve(Mbb, Mbw))
        c_base = R.T @ (sm.com(q) - q[:3])
        _close(ls.com_base, c_base)
        assert ls.mass == pytest.approx(sm.total_mass, rel=1e-12)
    if which == "pyramid":
        assert np.linalg.norm(c_base) > 0.01  # the CoM is off the base origin: M_ωω alone is not I
        assert np.abs(M[3:6, 3:6] - I_ref).max() > 0.05  # parallel-axis terms, 1e10 × the tolerance


def _block_diagonal_and_energy(sm, seeds=range(3)):
    for seed in seeds:
        q, x = _random_state(sm, seed)
        M = _crba(sm, q)
        ls = locked_shape(sm, q)
        Ti = np.linalg.inv(ls.T)
        D = Ti.T @ M @ Ti
        scale = np.abs(M).max()
        B = ls.block_diagonal()
        assert np.abs(D - B).max() <= 1e-12 * scale
        for a, b in ((slice(0, 3), slice(3, None)), (slice(3, 6), slice(6, None))):  # the off-diagonal blocks
            assert np.abs(D[a, b]).max() <= 1e-12 * scale
        assert np.abs(D[:3, :3] - sm.total_mass * np.eye(3)).max() <= 1e-12 * scale
        zeta = ls.T @ x
        _close(zeta[3:6], ls.locked_velocity(x))
        assert 0.5 * zeta @ B @ zeta == pytest.approx(0.5 * x @ M @ x, rel=1e-12)
        # ζ's first block is the CoM velocity in base axes (the linear momentum over the mass)
        p, _, _ = sm.momenta(q, x[: sm.nv], x[sm.nv:])
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        _close(sm.total_mass * zeta[:3], R.T @ p)


@pytest.mark.parametrize("which", ["pyramid", "basilisk"])
def test_locked_shape_form_is_block_diagonal_and_keeps_the_energy(which, request):
    _block_diagonal_and_energy(request.getfixturevalue(which))


def test_arm_and_modes_are_shape_coordinates(arm_model):
    """With an arm (Caldera) and with an arm + 10 modes (PULSAR) the same identities hold: the arm joints and
    modal rates are shape coordinates, μ = I⁻¹ H_c includes their momentum."""
    sm = arm_model
    assert sm.arm and sm.wheels
    _block_diagonal_and_energy(sm, seeds=range(2))
    for seed in range(2):
        q, x = _random_state(sm, seed)
        M = _crba(sm, q)
        ls = locked_shape(sm, q)
        I_ref, R = _centroidal_inertia_base(sm, q)
        _close(ls.I, I_ref)
        _close(ls.Lambda_shape, np.linalg.solve(M[:6, :6], M[:6, 6:])[3:6])
        _, k_com, _ = sm.momenta(q, x[: sm.nv], x[sm.nv:])
        _close(ls.locked_velocity(x), np.linalg.solve(I_ref, R.T @ k_com))
        _close(locked_velocity(sm, q, x[: sm.nv], x[sm.nv:]), ls.locked_velocity(x))
    assert not shape_invariant(sm)


def test_stack_path_equals_the_per_sample_path(pyramid, arm_model):
    for sm in (pyramid, arm_model):
        rng = np.random.default_rng(3)
        qs = np.array([pin.integrate(sm.model, sm.q0, 0.4 * rng.normal(size=sm.nv)) for _ in range(4)])
        if sm is pyramid:
            assert shape_invariant(sm)  # balanced rotors on the base: one mass matrix for the stack
        vs = rng.normal(size=(4, sm.nv))
        _close(locked_velocities(sm, qs, vs), np.array([locked_velocity(sm, q, v) for q, v in zip(qs, vs)]))


def test_compiled_recording_path_equals_the_module(pyramid, arm_model):
    """The compiled loops' μ for the recording (``SampleKinematics.locked`` on rigid samples: the tree's own mass
    matrix at each q; ``momentum_control.locked_velocities_of`` on augmented mass matrices with modal rates) equal
    ``locked_velocity`` at random states of a non-orthogonal pyramid, Caldera's arm and PULSAR's arm + modes."""
    from sms_cli.sim.compiled.kinematics import SampleKinematics
    from sms_cli.sim.compiled.momentum_control import locked_velocities_of

    for sm in (pyramid, arm_model):
        states = [_random_state(sm, seed) for seed in range(4)]
        qs = np.array([q for q, _ in states])
        xs = np.array([x for _, x in states])
        mu = SampleKinematics(sm).locked(qs, xs[:, : sm.nv])
        _close(mu, np.array([locked_velocity(sm, q, x[: sm.nv]) for q, x in states]))
        out = np.empty((len(states), 3))
        locked_velocities_of(np.array([sm.mass_matrix(q) for q in qs]), xs, out)
        _close(out, np.array([locked_velocity(sm, q, x[: sm.nv], x[sm.nv:]) for q, x in states]))
        if sm.n_modes:  # the modal rates count: the rigid μ differs
            assert np.abs(out - mu).max() > 1e-6 * np.abs(out).max()


def test_world_angular_momentum_R_I_mu_is_conserved_torque_free(pyramid):
    """Free base, wheels driven by internal torques: μ (base frame) changes as the base turns, R I μ does not."""
    sm = pyramid
    rng = np.random.default_rng(5)
    v = np.zeros(sm.nv)
    v[:6] = [0.01, -0.02, 0.005, 0.02, -0.03, 0.05]
    v[sm.idx.wheels] = rng.normal(scale=30.0, size=len(sm.wheels))
    s = State(sm.q0.copy(), v, np.zeros(0), np.zeros(0))
    tau = np.zeros(sm.nv)
    tau[sm.idx.wheels] = [0.2, -0.1, 0.15, -0.05]
    h0 = mu0 = None
    dh = dmu = 0.0
    for _ in range(400):
        s = rkmk4_step(sm.model, s, 0.05, lambda q, v_, e, ed: sm.forward_dynamics(q, v_, e, ed, tau))
        ls = locked_shape(sm, s.q)
        R = pin.Quaternion(s.q[6], s.q[3], s.q[4], s.q[5]).toRotationMatrix()
        mu = locked_velocity(sm, s.q, s.v)
        h = R @ ls.I @ mu
        if h0 is None:
            h0, mu0 = h, mu
        dh, dmu = max(dh, np.abs(h - h0).max()), max(dmu, np.abs(mu - mu0).max())
    assert dh <= 1e-9 * np.linalg.norm(h0)
    assert dmu > 1e-3 * np.linalg.norm(mu0)


def _messages(path: Path) -> dict[str, list]:
    out: dict[str, list] = {}
    for topic, _, data in read_messages(path):
        out.setdefault(topic, []).append(data)
    return out


def _run(path: Path, out: Path):
    from sms_cli.mission.load import load_mission
    from sms_cli.sim.stage import run_simulation

    section = run_simulation(load_mission(path), out, progress=False)
    return section, _messages(out / "simulation.mcap")


def test_recorded_locked_velocity_in_both_loops(tmp_path, pyramid):
    runs = {}
    for engine in ("python", "compiled"):
        section, msgs = _run(_write_missions(tmp_path, engine), tmp_path / engine)
        assert section["timing"]["engine"] == engine
        runs[engine] = msgs
    a, b = runs["python"]["/momentum/locked"], runs["compiled"]["/momentum/locked"]
    assert len(a) == len(b) == 241
    mu_py = np.array([[m["x"], m["y"], m["z"]] for m in a])
    mu_cc = np.array([[m["x"], m["y"], m["z"]] for m in b])
    assert np.abs(mu_py - mu_cc).max() <= 1e-9 * np.abs(mu_py).max()
    assert np.allclose([m["norm"] for m in a], np.linalg.norm(mu_py, axis=1), rtol=1e-11)
    # the module's μ at the recorded states (μ does not depend on the base pose, position or velocity, nor,
    # for these balanced rotors, on the wheel angles): ω and the wheel rates from the recording
    sm = pyramid
    ls = locked_shape(sm, sm.q0)
    msgs = runs["compiled"]
    for i in range(0, len(a), 20):
        x = np.zeros(sm.nv)
        x[3:6] = [msgs["/base/rate"][i][c] for c in "xyz"]
        x[sm.idx.wheels] = [msgs["/wheels/speed"][i][w.name] for w in sm.wheels]
        _close(mu_cc[i], ls.locked_velocity(x), 1e-10)
    # R I μ is the recorded world angular momentum about the CoM (/momentum k), constant over the run
    k = np.array([[m[c] for c in ("kx", "ky", "kz")] for m in msgs["/momentum"]])
    for i in range(0, len(a), 20):
        m = msgs["/attitude"][i]
        R = pin.Quaternion(m["qw"], m["qx"], m["qy"], m["qz"]).toRotationMatrix()
        _close(R @ ls.I @ mu_cc[i], k[i], 1e-9)
    assert np.abs(k - k[0]).max() <= 1e-8 * np.abs(k[0]).max()
    assert np.abs(mu_cc - mu_cc[0]).max() > 1e-2 * np.abs(mu_cc[0]).max()  # μ itself is not conserved


def test_python_loop_records_mu_with_an_arm(tmp_path):
    """Caldera S1 (pyramid + 3-joint arm, Python loop): R I(q) μ equals the recorded world angular momentum
    about the CoM at every sample, with I from the recorded arm configuration."""
    text = (MISSIONS / "caldera_s1_slew.yaml").read_text().replace("duration: 240 s", "duration: 20 s")
    (tmp_path / "caldera_smallsat.yaml").write_text(
        (MISSIONS / "caldera_smallsat.yaml").read_text().replace("../robots/", str(ROOT / "robots") + "/"))
    (tmp_path / "s1.yaml").write_text(text)
    _, msgs = _run(tmp_path / "s1.yaml", tmp_path / "out")
    sm = compile_path(tmp_path / "s1.yaml")
    mus = msgs["/momentum/locked"]
    assert len(mus) == len(msgs["/attitude"]) > 100
    for i in range(0, len(mus), 25):
        q = sm.q0.copy()
        m = msgs["/attitude"][i]
        q[3:7] = [m["qx"], m["qy"], m["qz"], m["qw"]]
        for a in sm.arm:
            q[a.q_index] = msgs["/joints/position"][i][a.name]
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        k = np.array([msgs["/momentum"][i][c] for c in ("kx", "ky", "kz")])
        mu = np.array([mus[i][c] for c in "xyz"])
        assert np.abs(R @ locked_shape(sm, q).I @ mu - k).max() <= 1e-9 * max(1e-6, np.abs(k).max()) + 1e-12


def test_compile_reports_the_locked_inertia(pyramid, tmp_path):
    path = _write_missions(tmp_path)
    res = run_cli("compile", path, "--json")
    assert res.exit_code == 0, res.output
    s = json.loads(res.output)["locked"]
    I_ref, _ = _centroidal_inertia_base(pyramid, pyramid.q0)
    _close(s["principal_inertia_kgm2"], np.linalg.eigvalsh(I_ref))
    assert s["coupling_norm"] == pytest.approx(np.linalg.norm(np.linalg.solve(I_ref, locked_shape(pyramid, pyramid.q0).G
                                                                              * 0.05), 2), rel=1e-12)
    text = run_cli("compile", path).output
    assert "locked    inertia about the CoM" in text and "|Λ|" in text
    assert json.loads(run_cli("compile", MISSIONS / "astrobee_arm.yaml", "--json").output)["locked"] is None
