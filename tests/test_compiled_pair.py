"""The compiled plant step of the two-spacecraft missions (sms_cli/sim/compiled/pair.py) and its SE(3) logarithm
(sms_cli/sim/compiled/se3.py).

Oracles: Pinocchio (pin.log6, pin.Jlog6, pin.exp6, the combined model's joints and inertias), central differences
of log6 for Jlog6, ``TwoBodyPlant.step`` (Pinocchio's ABA with the interface wrenches as joint forces, the
reference) for one step with each interface kind, the Python engine (``formation.engine: python``) for the four
shipped two-spacecraft missions, and the conservation of the pair's world momentum (Pinocchio's centroidal
momentum) under the internal pair's reaction and the capture interface, to the order of RKMK4.

Measured (this machine): one step vs Pinocchio's ≤ 3e-15 relative; the shipped missions' traces ≤ 5e-12 of each
quantity's scale; the momentum drift of the reaction + capture run 6.7e-8 at dt = 0.04 s, 3.8e-9 at 0.02 s
(ratio 17).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import MISSIONS, compile_path

from sms_cli.formation import capture as C
from sms_cli.formation.plant import TwoBodyPlant
from sms_cli.sim.compiled.pair import PairPlant, unsupported_reason
from sms_cli.sim.compiled.se3 import jlog6, log6

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------------- log6, Jlog6
def _log6(M: pin.SE3) -> np.ndarray:
    out = np.empty(6)
    log6(np.ascontiguousarray(M.rotation), np.array(M.translation), out)
    return out


def _jlog6(M: pin.SE3) -> np.ndarray:
    J = np.empty((6, 6))
    jlog6(np.ascontiguousarray(M.rotation), np.array(M.translation), J, np.empty((3, 3)))
    return J


def _poses(theta: float, seed: int = 0, n: int = 8):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        axis = rng.normal(size=3)
        yield pin.SE3(pin.exp3(theta * axis / np.linalg.norm(axis)), rng.normal(size=3))


# Pinocchio's Jlog6 loses digits to cancellation for 6e-6 < θ < ~0.1 (1e-7 at θ = 1e-3, measured): compared
# with it outside that range only, with central differences everywhere
@pytest.mark.parametrize("theta", [0.0, 1e-9, 1e-4, 1e-3, 0.05, 0.1, 0.3, 1.0, 2.5, math.pi - 0.005, math.pi])
def test_log6_and_jlog6_against_pinocchio_and_their_identities(theta):
    for M in _poses(theta):
        e = _log6(M)
        assert np.abs(pin.exp6(e).homogeneous - M.homogeneous).max() < 1e-13  # exp6(log6(M)) = M
        near_pi = theta > math.pi - 0.01  # Pinocchio's angle from acos loses digits there (1.4e-11, measured)
        assert np.abs(e - pin.log6(M).vector).max() < (1e-10 if near_pi else 1e-12)
        J = _jlog6(M)
        if not 6e-6 < theta < 0.1:
            assert np.abs(J - pin.Jlog6(M)).max() < (1e-10 if near_pi else 1e-12)
        h, fd = 1e-5, np.empty((6, 6))
        for i in range(6):
            d = np.zeros(6)
            d[i] = h
            fd[:, i] = (_log6(M * pin.exp6(d)) - _log6(M * pin.exp6(-d))) / (2 * h)
        if theta < math.pi - 0.01:  # (at π the logarithm jumps between ±axis: no derivative across)
            assert np.abs(J - fd).max() < 1e-8


# ---------------------------------------------------------------------- one step vs TwoBodyPlant.step
@pytest.fixture(scope="module")
def bodies():
    """The Vicariotto servicer (bus + 3 wheels) as body 1 "client", the Astrobee with its arm (revolute and prismatic
    joints) as body 2 "servicer" (tests/test_formation_plant.py's pair)."""
    return compile_path(MISSIONS / "vicariotto_s3a_free_floating.yaml"), compile_path(MISSIONS / "astrobee_arm.yaml")


@pytest.fixture(scope="module")
def setup(bodies):
    """(plant with a capture frame on each body, its PairPlant, frame a, frame b)."""
    plant = TwoBodyPlant.build(*bodies)
    b1, b2 = plant.bodies
    fa = plant.add_frame("servicer/capture_interface", b2.ee_frame_id,
                         pin.SE3(pin.exp3(np.array([0.1, 0.2, -0.1])), np.array([0.05, 0.02, 0.01])))
    fb = plant.add_frame("client/capture_interface", b1.frames["bus"],
                         pin.SE3(pin.exp3(np.array([-0.1, 0.3, 0.2])), np.array([0.5, 0.1, -0.2])))
    assert unsupported_reason(plant) is None
    return plant, PairPlant(plant), fa, fb


def _state(plant, seed):
    """Random base poses and twists, wheels spinning and the arm moving, torques on both."""
    rng = np.random.default_rng(seed)
    pin.seed(seed)
    q = pin.randomConfiguration(plant.model, -np.ones(plant.nq), np.ones(plant.nq))
    for b in plant.bodies:
        q[b.q.start:b.q.start + 7] = pin.SE3ToXYZQUAT(pin.SE3.Random())
    v = 0.1 * rng.normal(size=plant.nv)
    b1, b2 = plant.bodies
    v[b1.wheels_v] = 30.0 * rng.normal(size=b1.wheels_v.size)
    v[b2.arm_v] = 0.3 * rng.normal(size=b2.arm_v.size)
    tau = np.zeros(plant.nv)
    tau[b1.wheels_v] = 0.05 * rng.normal(size=b1.wheels_v.size)
    tau[b2.arm_v] = 0.005 * rng.normal(size=b2.arm_v.size)
    return q, v, tau, rng


def _capture(plant, fa, fb, q, rng):
    """(frame a, frame b, target ~0.2 from the current relative pose, K, D) with the gains of a 0.5 Hz interface."""
    g_ab = plant.frame_pose(q, fa).actInv(plant.frame_pose(q, fb))
    target = g_ab * pin.exp6(0.2 * rng.normal(size=6))
    lam = C.relative_operational_inertia(plant.model, plant.model.createData(), q, fa, fb)
    gains = C.InterfaceGains.from_frequency(lam, 0.5, 0.7)
    return (fa, fb, target, gains.K, gains.D), gains


KINDS = ["none", "reaction", "capture", "reaction+capture"]


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("kind", KINDS)
def test_one_step_equals_the_pinocchio_step(setup, kind, seed):
    """Each interface kind, random states, base wrenches on both bodies: the same (q, v) as ``TwoBodyPlant.step``
    with the Python interface (``FormationSimulation``'s reaction formula, ``capture.interface_wrenches``)."""
    plant, pair, fa, fb = setup
    q, v, tau, rng = _state(plant, seed)
    F1, F2 = rng.normal(size=6), rng.normal(size=6)
    R = rng.normal(size=6)
    cap, gains = _capture(plant, fa, fb, q, rng)
    data = plant.model.createData()

    def reaction(qs, _vs):
        g12 = plant.base_pose(qs, 0).actInv(plant.base_pose(qs, 1))
        return [(plant.bodies[0].base_frame_id, -(g12.dualAction @ R))]

    def capture(qs, vs):
        return C.interface_wrenches(plant.model, data, qs, vs, fa, fb, cap[2], gains)

    python = {"none": None, "reaction": reaction, "capture": capture,
              "reaction+capture": lambda qs, vs: [*reaction(qs, vs), *capture(qs, vs)]}[kind]
    kw = {"reaction": R if "reaction" in kind else None, "capture": cap if "capture" in kind else None}
    dt = 0.02
    qc, vc = pair.step(q, v, dt, tau, (F1, F2), **kw)
    qp, vp = plant.step(q, v, dt, tau, (F1, F2), python)
    assert np.abs(qc - qp).max() < 1e-12 * max(1.0, np.abs(qp).max())
    assert np.abs(vc - vp).max() < 1e-12 * max(1.0, np.abs(vp).max())
    if kind != "none":  # the interface acted: the step differs from one without it
        q0, v0 = plant.step(q, v, dt, tau, (F1, F2))
        assert np.abs(vp - v0).max() > 1e-4


@pytest.mark.parametrize("seed", range(3))
def test_the_monitors_wrench_pair_equals_interface_wrenches(setup, seed):
    """``PairPlant.capture_wrenches`` (what the capture monitor samples every step on the compiled engine) gives the
    frames and wrenches of ``capture.interface_wrenches`` (Pinocchio) at random states, to 1e-12 of their scale."""
    plant, pair, fa, fb = setup
    q, v, _, rng = _state(plant, seed)
    cap, gains = _capture(plant, fa, fb, q, rng)
    want = C.interface_wrenches(plant.model, plant.model.createData(), q, v, fa, fb, cap[2], gains)
    got = pair.capture_wrenches(q, v, cap)
    assert [f for f, _ in got] == [f for f, _ in want] == [fa, fb]
    scale = max(np.abs(F).max() for _, F in want)
    assert scale > 1e-3
    for (_, F), (_, W) in zip(got, want):
        assert np.abs(F - W).max() <= 1e-12 * scale


def test_the_forest_is_the_combined_model(setup):
    """Forest joint i is the combined model's joint i + 1: same placements, inertias, q and v indices; roots at
    both free-flyers."""
    plant, pair, _, _ = setup
    parent, kind, axis, place_R, place_p, inertia, leaf, arm, idx_q, idx_v = pair._tree
    m = plant.model
    for i in range(pair.n):
        j = i + 1
        assert parent[i] == m.parents[j] - 1
        assert np.array_equal(place_R[i], m.jointPlacements[j].rotation)
        assert np.array_equal(place_p[i], m.jointPlacements[j].translation)
        assert np.allclose(inertia[i], m.inertias[j].matrix(), rtol=0, atol=1e-14)
        assert (idx_q[i], idx_v[i]) == (m.idx_qs[j], m.idx_vs[j])
    assert list(pair.roots) == [b.base_joint_id - 1 for b in plant.bodies]
    assert np.array_equal(arm, m.armature)


def test_a_base_inertia_change_is_followed_after_refresh_body(bodies):
    """A thruster tank emptying changes body 2's base inertia in the combined model (``Tank.set_removed``):
    after ``refresh_body`` the compiled step equals Pinocchio's on the changed model, and differs before it."""
    plant = TwoBodyPlant.build(*bodies)
    pair = PairPlant(plant)
    q, v, tau, rng = _state(plant, 7)
    F = (np.zeros(6), np.array([1.0, 2.0, -1.0, 0.1, 0.2, 0.3]))
    j = plant.bodies[1].base_joint_id
    Y = plant.model.inertias[j]
    plant.model.inertias[j] = pin.Inertia(0.6 * Y.mass, Y.lever + 0.01, 0.7 * Y.inertia)
    qp, vp = plant.step(q, v, 0.02, tau, F)
    _, stale = pair.step(q, v, 0.02, tau, F)
    assert np.abs(stale - vp).max() > 1e-6
    pair.refresh_body(j)
    qc, vc = pair.step(q, v, 0.02, tau, F)
    assert np.abs(qc - qp).max() < 1e-12 and np.abs(vc - vp).max() < 1e-12 * max(1.0, np.abs(vp).max())


def test_pair_momentum_is_kept_by_the_reaction_and_the_capture_to_fourth_order(bodies):
    """The internal pair (F2 on body 2's base, its reaction on body 1's) and the capture spring-damper between the
    two bases, with wheel torques and the arm moving: every wrench is internal, so the world momentum (Pinocchio's
    centroidal momentum) is constant up to the step's O(dt⁴) truncation: its drift falls ~16x when dt halves.
    Measured over 2 s: 6.7e-8 of the momentum at dt = 0.04 s, 3.8e-9 at 0.02 s (ratio 17)."""
    plant = TwoBodyPlant.build(*bodies)
    b1, b2 = plant.bodies
    fa = plant.add_frame("servicer/capture_interface", b2.base_frame_id, pin.SE3(np.eye(3), np.array([0.3, 0.0, 0.0])))
    fb = plant.add_frame("client/capture_interface", b1.frames["bus"], pin.SE3(np.eye(3), np.array([0.6, 0.0, 0.0])))
    pair = PairPlant(plant)
    q, v, tau, rng = _state(plant, 3)
    tau[b2.arm_v] = 0.0  # (the Astrobee's 4.5e-5 kg m² finger runs away under a held torque)
    cap, _ = _capture(plant, fa, fb, q, rng)
    F2 = np.array([0.3, -0.2, 0.1, 0.02, 0.05, -0.03])
    h0 = plant.momentum_world(q, v)
    drifts, ends = [], []
    for dt in (0.04, 0.02):
        qs, vs = q, v
        for _ in range(round(2.0 / dt)):
            qs, vs = pair.step(qs, vs, dt, tau, (None, F2), reaction=F2, capture=cap)
        drifts.append(np.linalg.norm(plant.momentum_world(qs, vs) - h0) / np.linalg.norm(h0))
        ends.append(vs)
    free = q, v
    for _ in range(50):
        free = pair.step(*free, 0.04, tau)
    bases = np.r_[b1.base_v, b2.base_v]
    assert np.abs(ends[0][bases] - free[1][bases]).max() > 1e-2  # the interface wrenches did act
    assert drifts[0] < 1e-6
    assert drifts[0] / drifts[1] > 8


def test_other_interfaces_go_to_the_reference_step(tmp_path):
    """A callable interface that is not the simulation's own (``PairInterface``) is evaluated by
    ``TwoBodyPlant.step``: the same state as calling it directly."""
    sim = _simulation(_variant("caldera_capture_tumbling", "engine: auto", tmp_path))
    p = sim.plant
    q, v = sim.q, sim.v + 0.01
    fa, fb = sim.capture.frame_a, sim.capture.frame_b

    def interface(qs, vs):
        return [(fa, np.array([0.5, 0, 0, 0, 0, 0.1])), (fb, np.array([-0.5, 0, 0, 0, 0.1, 0]))]

    tau = np.zeros(p.nv)
    got = sim.step(q, v, 0.005, tau, (None, None), interface)
    want = p.step(q, v, 0.005, tau, (None, None), interface)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


# ---------------------------------------------------------------------- the shipped missions, both engines
def _variant(name: str, extra: str, tmp_path):
    from sms_cli.mission.load import load_mission_text

    base = MISSIONS / f"{name}.yaml"
    return load_mission_text(f"extends: {base}\nformation: {{{extra}}}\n", base_dir=base.parent,
                             name=f"{name}_{tmp_path.name}.yaml")


def _simulation(loaded):
    from sms_cli.formation.simulate import FormationSimulation
    from sms_cli.formation.stage import prepared

    servicer, client = prepared(loaded)
    return FormationSimulation(loaded.mission, servicer, client, None, progress=False)


def assert_traces_close(a: dict, p: dict) -> None:
    """Two runs' trace arrays: the same keys and NaNs, every array to 1e-9 of its own largest value."""
    assert a.keys() == p.keys()
    for key in p:
        x, y = np.asarray(a[key], float), np.asarray(p[key], float)
        assert np.array_equal(np.isnan(x), np.isnan(y)), key
        if np.isnan(y).all():
            continue
        scale = max(np.nanmax(np.abs(y)), 1e-300)
        assert np.nanmax(np.abs(x - y)) <= 1e-9 * scale, (key, np.nanmax(np.abs(x - y)) / scale)


def _numbers(x, path=""):
    """(path, float) of every number in a nested metrics dict."""
    if isinstance(x, dict):
        for k, val in x.items():
            yield from _numbers(val, f"{path}.{k}")
    elif isinstance(x, (list, tuple)):
        for i, val in enumerate(x):
            yield from _numbers(val, f"{path}[{i}]")
    elif isinstance(x, (int, float)) and not isinstance(x, bool):
        yield path, float(x)


@pytest.mark.parametrize("name, extra, interface", [
    ("vicariotto_s6_relative_hil", "", "reaction"),  # the internal pair, both pushes
    ("vicariotto_s4_relative_free_flying", "duration: 100 s", "none"),
    ("vicariotto_s6_thrusters", "duration: 135 s", "none, thrusters"),  # the step cut at every switching, the tank
    ("caldera_capture_tumbling", "", "capture"),
])
def test_shipped_missions_run_the_same_on_both_engines(name, extra, interface, tmp_path):
    """``formation.engine`` auto (the compiled step) and python (Pinocchio's): every trace quantity and every metric
    to 1e-9 of its scale (a trace quantity's largest value, a metrics section's largest number); each run says which engine ran (``timing.engine``, as the single-spacecraft run)."""
    from sms_cli.formation.metrics import formation_metrics

    runs, metrics = {}, {}
    for engine in ("auto", "python"):
        sim = _simulation(_variant(name, ", ".join(x for x in (extra, f"engine: {engine}") if x), tmp_path))
        assert (sim.pair is not None) == (engine == "auto")
        r = runs[engine] = sim.run()
        assert r.status == "completed"
        metrics[engine] = formation_metrics(r.trace, sim.spec, sim.names, r.wall_s, r.steps, r.engine)
        if r.capture is not None:
            metrics[engine]["capture"] = r.capture
    assert runs["auto"].engine == "python, compiled plant" and runs["python"].engine == "python"
    assert metrics["auto"]["timing"]["engine"] == "python, compiled plant"
    a, p = runs["auto"].trace, runs["python"].trace
    assert_traces_close(a, p)
    for section, y_all in metrics["python"].items():  # each metric to 1e-9 of its section's largest (a final error
        if section == "timing":  # is a small difference of large numbers: its scale is the initial error's)
            continue
        mp, ma = dict(_numbers(y_all)), dict(_numbers(metrics["auto"][section]))
        assert ma.keys() == mp.keys()
        scale = max([abs(y) for y in mp.values() if not math.isnan(y)] + [1e-300])
        for k, y in mp.items():
            assert abs(ma[k] - y) <= 1e-9 * scale or (math.isnan(y) and math.isnan(ma[k])), (section + k, ma[k], y)
    if name == "caldera_capture_tumbling":  # the interface engaged and the wrenches acted in both
        assert runs["auto"].capture["engaged"] and runs["auto"].capture["peak_force_N"] > 0.01


def test_the_decomposed_integrator_stays_python(tmp_path):
    sim = _simulation(_variant("vicariotto_s4_relative_free_flying", "integrator: decomposed", tmp_path))
    assert sim.pair is None and sim.engine == "python"
