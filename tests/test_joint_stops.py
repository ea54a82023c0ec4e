"""Joint-limit stops (sms_cli.dynamics.joint_stops; the numba lock in sms_cli.sim.compiled.dynamics).

- An impact: world momentum unchanged, the energy lost equals the closed form ½ v²/(M⁻¹)_ii (and
  (1 − e²) × that with restitution e), the rate after is −e × the rate before; two joints at once.
- Contact: a joint driven into its stop stays put (penetration ≤ |v| dt at arrival) with momentum
  conserved, and is released when the drive reverses.
- In a run: the time on stop reported equals the time the recording shows the joint resting on its
  stop; both plant engines (Pinocchio, compiled) give the same run; the known case of issue #11 (the
  backstepping slew throws Astrobee's distal joint past its range) stays in range with the stops.
Each engine on a rigid arm (Astrobee) and on a model with flexible modes (Pulsar).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from conftest import assert_tree_close

from sms_cli.recording.read import messages as read_messages
from sms_cli.dynamics.integrator import State
from sms_cli.dynamics.joint_stops import JointStops, PinocchioPlant, complementarity, stop_table
from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.schema import JointStopsSpec

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
MODELS = {"rigid": "missions/astrobee_arm.yaml", "modes": "missions/pulsar_simple.yaml"}
DT = 0.01


@pytest.fixture(scope="module", params=list(MODELS))
def sm(request):
    return compile_system(load_mission(ROOT / MODELS[request.param]))


def _plant(sm, engine):
    if engine == "pinocchio":
        return PinocchioPlant(sm)
    from sms_cli.sim.compiled.plant import CompiledPlant

    return CompiledPlant(sm)


def _state(sm, rates: dict[int, float], at_upper: dict[int, float], seed=0) -> State:
    """Stop joints mid-range (random small rates), the base moving (non-zero momentum), modes excited;
    joint k of the stop table at ``at_upper[k]`` from its upper limit with rate ``rates[k]``."""
    rng = np.random.default_rng(seed)
    T = stop_table(sm)
    q = sm.q0.copy()
    q[3:7] = pin.Quaternion(pin.exp3(rng.normal(size=3))).coeffs()
    v = 0.05 * rng.normal(size=sm.nv)
    for k in range(T.n):
        lo, hi = T.lower[k], T.upper[k]
        q[T.q_index[k]] = 0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) else (lo if np.isfinite(lo) else hi) + 0.5
    for k, d in at_upper.items():
        q[T.q_index[k]] = T.upper[k] - d
        v[T.v_index[k]] = rates[k]
    return State(q, v, 0.01 * rng.normal(size=sm.n_modes), 0.01 * rng.normal(size=sm.n_modes))


def _momentum(sm, s: State) -> np.ndarray:
    p, _, k = sm.momenta(s.q, s.v, s.etadot)
    return np.concatenate([p, k])


def _rel(a, b) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ----------------------------------------------------------------------------- impacts
@pytest.mark.parametrize("engine", ["pinocchio", "compiled"])
@pytest.mark.parametrize("e", [0.0, 0.5])
def test_impact_conserves_momentum_and_loses_the_closed_form_energy(sm, engine, e):
    """Joint 1 of the stop table crosses its upper limit during the step: the impulse keeps the world
    momentum, takes ½ (1 − e²) v²/(M⁻¹)_ii of energy (M: augmented mass matrix, modes included) and
    leaves the joint at −e × its rate."""
    plant = _plant(sm, engine)
    stops = JointStops(sm, e)
    k, rate = 1, 0.4
    s0 = _state(sm, {k: rate}, {k: 0.3 * rate * DT})
    tau = np.zeros(sm.nv)
    before = plant.step(s0, tau, DT)  # the step without the impulse (deterministic: the same step)
    after = stops.step(plant, s0, tau, DT, 0.0)
    j = stops.table.v_index[k]
    assert [ev[1] for ev in stops.events] == ["joint_stop"]
    assert _rel(_momentum(sm, after), _momentum(sm, before)) <= 1e-10
    v = before.v[j]
    assert v > 0.3  # it arrived moving outward
    assert after.v[j] == pytest.approx(-e * v, abs=1e-12 * abs(v))
    minv = np.linalg.inv(sm.mass_matrix(before.q))[j, j]
    lost = sm.energy(before.q, before.v, before.eta, before.etadot) - sm.energy(after.q, after.v, after.eta, after.etadot)
    assert lost == pytest.approx(0.5 * (1 - e**2) * v**2 / minv, rel=1e-9)
    assert np.array_equal(after.q, before.q)  # an impulse changes no position
    assert stops.side[k] == (1 if e == 0 else 0)  # inelastic: locked; a bounce: free


@pytest.mark.parametrize("engine", ["pinocchio", "compiled"])
def test_two_joints_arriving_together(sm, engine):
    """Two joints arrive in the same step: both stop (inelastic), momentum unchanged, the energy lost is
    ½ uᵀ (M⁻¹_SS)⁻¹ u over the pair (the coupled closed form)."""
    plant = _plant(sm, engine)
    stops = JointStops(sm, 0.0)
    s0 = _state(sm, {0: 0.3, 1: 0.4}, {0: 0.1 * DT, 1: 0.1 * DT}, seed=2)
    tau = np.zeros(sm.nv)
    before = plant.step(s0, tau, DT)
    after = stops.step(plant, s0, tau, DT, 0.0)
    cols = stops.table.v_index[:2]
    assert sorted(ev[2]["joint"] for ev in stops.events) == sorted(stops.table.names[:2])
    assert np.abs(after.v[cols]).max() <= 1e-12
    assert _rel(_momentum(sm, after), _momentum(sm, before)) <= 1e-10
    u = before.v[cols]
    W = np.linalg.inv(sm.mass_matrix(before.q))[np.ix_(cols, cols)]
    lost = sm.energy(before.q, before.v, before.eta, before.etadot) - sm.energy(after.q, after.v, after.eta, after.etadot)
    assert lost == pytest.approx(0.5 * u @ np.linalg.solve(W, u), rel=1e-9)


@pytest.mark.parametrize("engine", ["pinocchio", "compiled"])
def test_a_joint_resting_beyond_its_limit_is_not_thrown_through_it(sm, engine):
    """Joint a is beyond a limit, moving slowly back inside; joint b arrives, and its impulse alone would
    throw joint a outward (the side of a is chosen from the coupling M⁻¹_ab): a takes part in the impact,
    is stopped and locked instead; momentum unchanged."""
    plant = _plant(sm, engine)
    T = stop_table(sm)
    G = np.linalg.inv(sm.mass_matrix(_state(sm, {}, {}).q))[np.ix_(T.v_index, T.v_index)]
    coupling = np.abs(G) / np.sqrt(np.outer(np.diag(G), np.diag(G)))
    np.fill_diagonal(coupling, 0.0)
    a, b = np.unravel_index(np.argmax(coupling), coupling.shape)  # the most coupled pair: a rests, b arrives
    s0 = _state(sm, {b: 0.4}, {b: 0.3 * 0.4 * DT}, seed=4)
    for side in (1, -1):  # the side where b's push (λ_b < 0) moves a (by −G_ab |λ_b|) outward
        s0.q[T.q_index[a]] = (T.upper[a] + 1e-3) if side == 1 else (T.lower[a] - 1e-3)
        G = np.linalg.inv(sm.mass_matrix(s0.q))[np.ix_(T.v_index, T.v_index)]
        if -side * G[a, b] > 0:
            break
    else:
        pytest.fail("no side on which joint b throws joint a outward")
    s0.v[T.v_index[a]] = -side * 0.3 * abs(G[a, b]) * 0.4 / G[b, b]  # inward, 30 % of the throw
    s0.q[T.q_index[a]] += side * 2 * abs(s0.v[T.v_index[a]]) * DT  # still beyond its limit after the step
    stops = JointStops(sm, 0.0)
    before = plant.step(s0, np.zeros(sm.nv), DT)
    assert side * before.v[T.v_index[a]] < 0 and before.v[T.v_index[b]] > 0  # a moving in, b arriving
    after = stops.step(plant, s0, np.zeros(sm.nv), DT, 0.0)
    assert np.abs(after.v[T.v_index[[a, b]]]).max() <= 1e-12
    assert (stops.side[a], stops.side[b]) == (side, 1)
    assert _rel(_momentum(sm, after), _momentum(sm, before)) <= 1e-10


@pytest.mark.parametrize("engine", ["pinocchio", "compiled"])
def test_a_rebound_that_cannot_leave_the_stop_comes_to_rest(sm, engine):
    """Restitution 0.1 under a hard outward drive: the rebound is turned back before the joint is inside
    its range again, so the second arrival is inelastic and the joint rests on its stop (no endless
    bouncing deeper into the stop)."""
    plant = _plant(sm, engine)
    stops = JointStops(sm, 0.1)
    k, rate = 1, 0.4
    s = _state(sm, {k: rate}, {k: 0.1 * rate * DT}, seed=5)
    j = stops.table.v_index[k]
    tau = np.zeros(sm.nv)
    tau[j] = 20.0 / np.linalg.inv(sm.mass_matrix(s.q))[j, j]  # ~20 rad/s² outward: 0.2 rad/s per step
    for i in range(20):
        s = stops.step(plant, s, tau, DT, i * DT)
    arrivals = [ev for ev in stops.events if ev[1] == "joint_stop" and ev[2]["joint"] == stops.table.names[k]]
    assert arrivals[0][2]["rate_after"] == pytest.approx(-0.1 * arrivals[0][2]["rate"])  # a bounce first
    assert len(arrivals) == 2 and arrivals[1][2]["rate_after"] == pytest.approx(0.0, abs=1e-12)  # then at rest
    assert stops.side[k] == 1
    assert s.q[stops.table.q_index[k]] - stops.table.upper[k] <= 2 * rate * DT


def test_impact_with_the_base_held():
    """A held base (phase base_mode fixed): the impulse acts on the free block of M, the base stays at
    rest, and the energy lost is ½ v²/(M_ff⁻¹)_ii."""
    sm = compile_system(load_mission(ROOT / MODELS["rigid"]))
    plant = PinocchioPlant(sm, fixed=True)
    stops = JointStops(sm, 0.0)
    s0 = _state(sm, {1: 0.4}, {1: 0.3 * 0.4 * DT})
    s0.v[:6] = 0.0
    before = plant.step(s0, np.zeros(sm.nv), DT)
    after = stops.step(plant, s0, np.zeros(sm.nv), DT, 0.0)
    j = stops.table.v_index[1]
    assert np.all(after.v[:6] == 0.0) and abs(after.v[j]) <= 1e-12
    minv = np.linalg.inv(sm.mass_matrix(before.q)[6:, 6:])[j - 6, j - 6]
    lost = sm.energy(before.q, before.v, before.eta, before.etadot) - sm.energy(after.q, after.v, after.eta, after.etadot)
    assert lost == pytest.approx(0.5 * before.v[j] ** 2 / minv, rel=1e-9)


def test_complementarity_pushes_only_what_needs_a_push():
    """A coupled pair: joint 0 needs a push, joint 1 would move inward on its own but joint 0's push
    throws it outward: both pushed. Decoupled: only joint 0."""
    W = np.array([[2.0, -1.0], [-1.0, 2.0]])
    mu = complementarity(W, np.array([1.0, -0.2]))
    r = W @ mu - np.array([1.0, -0.2])
    assert np.all(mu >= 0) and np.all(r >= -1e-15) and abs(mu @ r) <= 1e-15
    assert mu[1] > 0
    mu = complementarity(np.eye(2), np.array([1.0, -0.2]))
    assert mu[0] == pytest.approx(1.0) and mu[1] == 0.0


# ----------------------------------------------------------------------------- contact
@pytest.mark.parametrize("engine", ["pinocchio", "compiled"])
def test_contact_holds_the_joint_then_releases_it(sm, engine):
    """Driven into its upper stop by a constant joint torque, the joint stays within |v| dt of the limit,
    at rest, with the world momentum conserved; reversing the torque releases it."""
    plant = _plant(sm, engine)
    stops = JointStops(sm, 0.0)
    k = 1
    s = _state(sm, {k: 0.3}, {k: 0.02}, seed=1)
    j, qj, upper = stops.table.v_index[k], stops.table.q_index[k], stops.table.upper[k]
    minv = np.linalg.inv(sm.mass_matrix(s.q))[j, j]
    tau = np.zeros(sm.nv)
    tau[j] = 0.5 / minv  # about 0.5 rad/s² outward (m/s²)
    h0 = _momentum(sm, s)
    t = 0.0
    vmax = 0.0
    for _ in range(100):
        vmax = max(vmax, abs(s.v[j]))
        s = stops.step(plant, s, tau, DT, t)
        t += DT
        assert _rel(_momentum(sm, s), h0) <= 1e-10
    name = stops.table.names[k]
    events = [ev for ev in stops.events if ev[2]["joint"] == name]  # (a light gripper may hit its stops too)
    assert stops.side[k] == 1 and [ev[1] for ev in events] == ["joint_stop"]
    t_arrival = events[0][0]
    q_stop = s.q[qj]
    assert upper <= q_stop <= upper + vmax * DT
    assert abs(s.v[j]) <= 1e-12
    assert stops.max_penetration[k] == pytest.approx(q_stop - upper)
    # reverse the drive: a torque that makes the free acceleration point inward (the configuration has
    # moved: M⁻¹ at the current state)
    a0 = plant.accel(s, np.zeros(sm.nv))[0][j]
    tau[j] = -(max(a0, 0.0) + 0.5) / np.linalg.inv(sm.mass_matrix(s.q))[j, j]
    stops.events.clear()
    s = stops.step(plant, s, tau, DT, t)
    release = [ev for ev in stops.events if ev[2]["joint"] == name]
    assert stops.side[k] == 0 and [ev[:2] for ev in release] == [(t, "joint_stop_release")]
    assert s.v[j] < 0 and s.q[qj] < q_stop
    assert stops.total_time[k] == pytest.approx(t - t_arrival)
    assert release[0][2]["time_on_stop_s"] == pytest.approx(t - t_arrival)


# ----------------------------------------------------------------------------- in a run
def _run(tmp_path, path: Path, name: str, **simulation):
    """Simulate the mission at ``path`` with the simulation fields changed; (section, recording)."""
    from sms_cli.sim.stage import run_simulation

    loaded = load_mission(path)
    if simulation:
        sim = loaded.mission.simulation.model_copy(update=simulation)
        loaded.mission = loaded.mission.model_copy(update={"simulation": sim})
    section = run_simulation(loaded, tmp_path / name, progress=False)
    return section, _messages(tmp_path / name / "simulation.mcap")


def _messages(mcap: Path) -> dict[str, list]:
    out: dict[str, list] = {}
    for topic, log_time, data in read_messages(mcap):
        out.setdefault(topic, []).append((log_time * 1e-9, data))
    return out


@pytest.fixture(scope="module")
def drive_runs(tmp_path_factory):
    """tests/data/joint_stops_drive.yaml by both plant engines (recorded at every plant step)."""
    tmp = tmp_path_factory.mktemp("drive")
    path = DATA / "joint_stops_drive.yaml"
    return {e: _run(tmp, path, e, engine=e) for e in ("python", "auto")}


def test_a_run_reports_the_time_the_recording_shows_on_the_stop(drive_runs):
    """The distal joint, commanded to 120 deg, rests on its +90 deg stop: the time on stop reported
    (per joint, per phase) is the time the every-step recording shows it at rest beyond the limit;
    it never goes further than one step's travel; it is released when the command comes back."""
    sec, msgs = drive_runs["python"]
    upper = 1.57079
    pos = np.array([m["distal_joint"] for _, m in msgs["/joints/position"]])
    rate = np.array([m["distal_joint"] for _, m in msgs["/joints/rate"]])
    t = np.array([tt for tt, _ in msgs["/joints/position"]])
    dt = 0.004
    resting = (np.abs(rate) <= 1e-12) & (pos >= upper)
    held = resting[:-1] & resting[1:]  # the step from sample i to i + 1 spent on the stop
    shown = held.sum() * dt
    reported = sec["overall"]["joint_stop_time_per_joint_s"]["distal_joint"]
    assert reported > 2.0
    assert reported == pytest.approx(shown, abs=1e-9)
    assert sec["overall"]["joint_stop_time_s"] == pytest.approx(sum(sec["overall"]["joint_stop_time_per_joint_s"].values()))
    by_phase = [p["joint_stop_time_per_joint_s"]["distal_joint"] for p in sec["phases"]]
    in_phase = [held[(t[:-1] >= a - 1e-9) & (t[:-1] < b - 1e-9)].sum() * dt for a, b in ((0, 6), (6, 10))]
    assert by_phase == pytest.approx(in_phase, abs=1e-9)
    events = [m for _, m in msgs["/events"] if m["name"].startswith("joint_stop") and m["detail"]["joint"] == "distal_joint"]
    # arrivals and releases alternate (the first impact's braking torque, held until the next control tick,
    # pulls the joint off at once; the next tick pushes it back on), the last release in the second phase
    assert [e["name"] for e in events] == ["joint_stop", "joint_stop_release"] * (len(events) // 2) and events
    for arrival, release in zip(events[::2], events[1::2]):
        assert release["detail"]["time_on_stop_s"] == pytest.approx(release["t"] - arrival["t"])
    first = events[0]["detail"]  # the first arrival: inside the range one step before
    assert 0 <= first["penetration"] <= abs(first["rate"]) * dt
    assert events[-1]["t"] > 6.0 and sum(e["detail"]["time_on_stop_s"] for e in events[1::2]) == pytest.approx(reported)
    assert pos.max() <= upper + np.abs(rate).max() * dt
    assert sec["overall"]["joint_stop_penetration_max"] >= pos.max() - upper > 0
    assert pos[-1] < 0.1  # back at 0 deg
    drift = sec["conservation"]
    assert drift["linear_momentum_drift_rel"] <= 1e-10 and drift["angular_momentum_drift_rel"] <= 1e-10


def test_both_plant_engines_give_the_same_run(drive_runs):
    """Pinocchio (engine: python) and the compiled loop with its stop law (auto, ``sms_cli.sim.compiled.stops``):
    the same metrics, stop events and joint trajectories, to 1e-9."""
    (py, a), (cc, b) = drive_runs["python"], drive_runs["auto"]
    assert py["timing"]["engine"] == "python" and cc["timing"]["engine"] == "compiled"
    assert py["overall"]["joint_stop_time_s"] > 0
    assert_tree_close(py["overall"], cc["overall"], "overall", abs_=1e-9)
    assert_tree_close(py["phases"], cc["phases"], "phases", abs_=1e-9)
    for topic in ("/events", "/joints/position", "/joints/rate", "/momentum"):
        assert [t for t, _ in a[topic]] == [t for t, _ in b[topic]], topic
        assert_tree_close([m for _, m in a[topic]], [m for _, m in b[topic]], topic, abs_=1e-9)


def test_the_backstepping_slew_keeps_the_distal_joint_in_range(tmp_path):
    """Issue #11 item 4: under the backstepping slew (no torque limit) the distal joint ran past its
    ±90 deg range (to 1.94 rad); with the stops it stays within one step's travel of it, and the run
    reports the time on stop."""
    path = DATA / "joint_stops_backstepping.yaml"
    lo, hi = -1.57079, 1.57079
    off, msgs_off = _run(tmp_path, path, "off", joint_stops=JointStopsSpec(enabled=False))
    x_off = np.array([m["distal_joint"] for _, m in msgs_off["/joints/position"]])
    assert x_off.max() > hi + 0.2  # the known case: without the stops the joint runs past
    assert off["overall"]["joint_stop_time_s"] == 0.0 and off["overall"]["joint_stop_penetration_max"] > 0.2
    on, msgs = _run(tmp_path, path, "on")
    x = np.array([m["distal_joint"] for _, m in msgs["/joints/position"]])
    v = np.array([m["distal_joint"] for _, m in msgs["/joints/rate"]])
    bound = np.abs(v).max() * 0.004
    assert lo - bound <= x.min() and x.max() <= hi + bound
    arrivals = [m["detail"] for _, m in msgs["/events"] if m["name"] == "joint_stop"]
    assert "distal_joint" in {a["joint"] for a in arrivals}
    # every joint (the light gripper is thrown hardest) within one step's travel at its fastest arrival
    assert 0 < on["overall"]["joint_stop_penetration_max"] <= max(abs(a["rate"]) for a in arrivals) * 0.004
    assert on["overall"]["joint_stop_time_s"] > 0


def test_schema_option():
    from pydantic import ValidationError

    assert JointStopsSpec().enabled and JointStopsSpec().restitution == 0.0
    with pytest.raises(ValidationError):
        JointStopsSpec(restitution=1.5)
