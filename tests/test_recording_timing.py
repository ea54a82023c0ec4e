"""The timing of a recording (metadata ``sms.timing``, ``sms_cli.sim.timing``) and that another
engine can replay a run from it.

Oracle: an independent replay. The plant is re-integrated from the mission's initial state with
Pinocchio (``SystemModel.forward_dynamics`` and ``rkmk4_step``), fed only the torques read back from
the MCAP file with the ``mcap`` reader and held as the metadata says (the torque stamped at t_(k+1)
over [t_k, t_(k+1)]); the states it reaches must be the recorded ones to 1e-9. The same replay with
the torques one control period early (stamped at t_k applied over [t_k, t_(k+1)]) must be far off:
that is what shows the documented convention is the one that holds. Missions: shortened copies of
two shipped ones, written to tmp_path — astrobee_arm (62.5 Hz control, 4 ms plant step, joint
torques, Python loop) and basilisk_rw_reference (reaction wheels; both loops, plant step dt/4).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from sms_cli.recording.read import messages as read_messages
from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.recording.inspect import format_inspection, inspect_recording
from sms_cli.sim.schema import SimulationSpec
from sms_cli.sim.stage import record_simulation
from sms_cli.sim.timing import TIMING_METADATA

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = str(ROOT / "robots") + "/"


def _arm_mission(tmp_path: Path, record_rate: str | None = "") -> Path:
    """astrobee_arm shortened to 2 s (deploy waypoint at 1.5 s), the arm starting off its stops (the
    stowed 180° and the closed gripper are URDF limits: a stop's impulse or holding force is not a
    recorded input); ``record_rate`` "" = the default."""
    text = (ROOT / "missions" / "astrobee_arm.yaml").read_text()
    text = (text.replace("../robots/", ROBOTS).replace("duration: 40 s", "duration: 2 s").replace("{at: 30 s,", "{at: 1.5 s,")
            .replace('proximal_joint: "180 deg"', 'proximal_joint: "170 deg"').replace("gripper_joint: 0.0", "gripper_joint: 0.1"))
    text = _set_simulation_keys(text, "" if record_rate == "" else f"  record_rate: {record_rate}\n")
    path = tmp_path / "arm.yaml"
    path.write_text(text)
    return path


WHEELS, THRUSTERS = "  engine: {engine}\n", "  engine: {engine}\n  attitude_actuator: thrusters\n"
# a pulse and an inertial-frame force (turning with the base in its frame): they change within a control
# period, so this one records every plant step
DISTURBED = ("  engine: {engine}\n  record_rate: null\n  disturbances:\n"
             "    - {{kind: pulse, frame: base, torque: [0.3, -0.2, 0.1], start: 1.01 s, duration: 0.6 s}}\n"
             "    - {{kind: constant, frame: inertial, force: [2, -1, 0.5], torque: [0, 0, 0.05]}}\n")


def _wheel_mission(tmp_path: Path, engine: str, variant: str = WHEELS) -> Path:
    """basilisk_rw_reference shortened to 5 s, plant step 25 ms (4 per control period), default record
    rate; ``variant``: the attitude law through the wheels, through thrusters, or disturbed."""
    text = (ROOT / "missions" / "basilisk_rw_reference.yaml").read_text()
    assert "dt: 0.1 s" in text and "duration: 600 s" in text
    text = _set_simulation_keys(text, variant.format(engine=engine))
    text = text.replace("../robots/", ROBOTS).replace("dt: 0.1 s", "dt: 0.025 s").replace("duration: 600 s", "duration: 5 s")
    path = tmp_path / f"rw_{engine}_{abs(hash(variant)) % 1000}.yaml"
    path.write_text(text)
    return path


def _set_simulation_keys(text: str, lines: str) -> str:
    """The mission text without its record_rate (whatever the file says) and with ``lines`` after its control_rate."""
    text = re.sub(r"(?m)^  record_rate:.*\n", "", text)
    text, n = re.subn(r"(?m)^(  control_rate:.*\n)", lambda m: m.group(1) + lines, text)
    assert n == 1
    return text


def _record(path: Path, tmp_path: Path) -> Path:
    section, _ = record_simulation(load_mission(path), tmp_path / f"out_{path.stem}", progress=False)
    return Path(section["files"]["mcap"])


def _read(mcap: Path) -> tuple[dict, dict]:
    """(metadata, topic → (times in s, [field dicts])) read with the mcap reader."""
    with open(mcap, "rb") as f:
        reader = make_reader(f)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        topics: dict[str, tuple[list, list]] = {}
    for topic, log_time, data in read_messages(mcap):
        if topic not in ("/tf", "/events", "/log", "/robot_description"):
            times, values = topics.setdefault(topic, ([], []))
            times.append(log_time / 1e9)
            values.append(data)
    return metadata, topics


def _column(topics, topic: str, names) -> np.ndarray:
    return np.array([[v[n] for n in names] for v in topics[topic][1]], dtype=float).reshape(len(topics[topic][1]), len(names))


def replay(mission: Path, mcap: Path, shift: int = 0) -> float:
    """Largest difference between the recorded states and a Pinocchio re-integration from the initial
    state under the recorded torques (and base wrench), held as ``sms.timing`` says (shift 1: one
    sample early)."""
    sm = compile_system(load_mission(mission))
    metadata, topics = _read(mcap)
    timing = metadata[TIMING_METADATA]
    T, dt = float(timing["control_period_s"]), float(timing["plant_dt_s"])
    assert abs(int(timing["plant_steps_per_control_period"]) * dt - T) < 1e-12
    period = float(timing["record_period_s"])
    n_sub = round(period / dt)  # plant steps per sample: per control period, or 1 (every step recorded)
    times = np.array(topics["/attitude"][0])
    assert np.allclose(times, period * np.arange(times.size), atol=1e-9, rtol=0), "one sample per record period"
    wheels, arm = [w.name for w in sm.wheels], [a.name for a in sm.arm]
    tau_w = _column(topics, "/wheels/torque", wheels) if wheels else np.zeros((times.size, 0))
    tau_m = _column(topics, "/joints/torque", arm) if arm else np.zeros((times.size, 0))
    wrench = (_column(topics, "/base/wrench", ["fx", "fy", "fz", "nx", "ny", "nz"]) if "/base/wrench" in topics
              else np.zeros((times.size, 6)))
    assert not np.any(tau_w[0]) and not np.any(tau_m[0]), "the t = 0 sample holds no torque"
    recorded = np.hstack([_column(topics, "/attitude", ["qx", "qy", "qz", "qw"]), _column(topics, "/base/rate", "xyz"),
                          _column(topics, "/base/position", "xyz")]
                         + ([_column(topics, "/wheels/speed", wheels)] if wheels else [])
                         + ([_column(topics, "/joints/position", arm), _column(topics, "/joints/rate", arm)] if arm else []))

    def observed(s: State) -> np.ndarray:
        return np.concatenate([s.q[3:7], s.v[3:6], s.q[0:3], s.v[sm.idx.wheels], s.q[[a.q_index for a in sm.arm]],
                               s.v[sm.idx.arm]])

    s = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
    err = np.max(np.abs(observed(s) - recorded[0]))
    for k in range(times.size - 1):  # over [t_k, t_(k+1)]: the torque stamped at t_(k+1) (shift 1: at t_k)
        j = k + 1 - shift
        tau = np.zeros(sm.nv)
        tau[sm.idx.wheels] = tau_w[j]
        tau[sm.idx.arm] = tau_m[j]
        tau[:6] = wrench[j]
        for _ in range(n_sub):
            s = rkmk4_step(sm.model, s, dt, lambda q, v, e, ed: sm.forward_dynamics(q, v, e, ed, tau))
        err = max(err, float(np.max(np.abs(observed(s) - recorded[k + 1]))))
    return err


@pytest.fixture(scope="module")
def arm_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("arm")
    mission = _arm_mission(tmp)
    return mission, _record(mission, tmp)


def test_timing_metadata_is_in_the_recording_and_decodes_with_the_mcap_reader(arm_run):
    metadata, _ = _read(arm_run[1])
    timing = metadata[TIMING_METADATA]
    assert float(timing["control_rate_hz"]) == 62.5 and float(timing["plant_dt_s"]) == 0.004
    assert float(timing["control_period_s"]) == pytest.approx(0.016, abs=1e-15)
    assert timing["plant_steps_per_control_period"] == "4"
    assert float(timing["record_rate_hz"]) == 62.5  # the default: the control rate
    assert timing["integrator"].startswith("rkmk4")
    assert "[t_k - control_period_s, t_k]" in timing["command_stamp"]
    assert "zero torques" in timing["initial_sample"]
    assert timing["replayable"] == "yes" and timing["not_replayable_because"] == ""


def test_default_record_rate_is_the_control_rate():
    phases = [{"name": "a", "duration": 1}]
    assert SimulationSpec(phases=phases, control_rate="62.5 Hz", dt=0.004).record_rate == 62.5
    assert SimulationSpec(phases=phases, control_rate=50, dt=0.01, record_rate="control").record_rate == 50
    assert SimulationSpec(phases=phases, record_rate=None).record_rate is None
    assert SimulationSpec(phases=phases, record_rate="5 Hz").record_rate == 5


def test_arm_run_replays_from_its_recording_with_the_documented_hold(arm_run):
    mission, mcap = arm_run
    exact, early = replay(mission, mcap), replay(mission, mcap, shift=1)
    assert exact <= 1e-13, exact  # the recording holds the doubles: replay meets it to round-off (≤ 4e-15 measured)
    assert early > 1e3 * max(exact, 1e-13), (exact, early)
    assert inspect_recording(mcap)["replay"]["replayable"] is True


@pytest.mark.parametrize("engine,variant", [("compiled", WHEELS), ("python", WHEELS), ("compiled", THRUSTERS),
                                            ("python", THRUSTERS), ("python", DISTURBED)],
                         ids=["wheels-compiled", "wheels-python", "thrusters-compiled", "thrusters-python",
                              "disturbed-every-step"])
def test_wheel_and_thruster_runs_replay_from_their_recording_in_both_loops(tmp_path, engine, variant):
    mission = _wheel_mission(tmp_path, engine, variant)
    mcap = _record(mission, tmp_path)
    metadata, topics = _read(mcap)
    assert ("/base/wrench" in topics) == (variant != WHEELS)  # recorded when something but the wheels acts on the base
    assert metadata[TIMING_METADATA]["replayable"] == "yes"
    exact, early = replay(mission, mcap), replay(mission, mcap, shift=1)
    assert exact <= 1e-13, exact  # the recording holds the doubles: replay meets it to round-off (≤ 4e-15 measured)
    assert early > 1e3 * max(exact, 1e-13), (exact, early)


def test_disturbances_recorded_at_the_control_rate_are_flagged(tmp_path):
    from sms_cli.sim.timing import not_replayable_reasons

    spec = load_mission(_wheel_mission(tmp_path, "python", DISTURBED.replace("  record_rate: null\n", ""))).mission.simulation
    assert spec.record_rate == 10.0
    assert any("disturbance" in r for r in not_replayable_reasons(spec))


def test_inspect_says_a_10_hz_recording_of_a_62_5_hz_controller_cannot_be_replayed(tmp_path, capsys):
    mcap = _record(_arm_mission(tmp_path, "10 Hz"), tmp_path)
    assert "cannot be replayed" in capsys.readouterr().err  # the warning at simulate time
    info = inspect_recording(mcap)
    assert info["replay"]["replayable"] is False
    text = format_inspection(info)
    assert "replay: NO, this recording cannot be replayed" in text
    assert "10 Hz) is below the control rate (62.5 Hz)" in text
    assert "control ticks up to the last sample have no sample" in text  # checked on the sample times too
    metadata, _ = _read(mcap)
    assert metadata[TIMING_METADATA]["replayable"] == "no"


def test_inspect_checks_the_sample_times_even_when_the_metadata_says_yes(arm_run, tmp_path):
    """A recording whose metadata claims every tick but whose samples skip some is still flagged."""
    from sms_cli.recording.inspect import replay_check

    metadata, _ = _read(arm_run[1])

    class Ch:
        topic = "/attitude"

    T = 0.016
    stamps = {int(round(k * T * 1e9)) for k in range(0, 20, 2)}  # every other tick
    check = replay_check(metadata, {1: Ch()}, {1: [len(stamps), 0, max(stamps), stamps]})
    assert check["replayable"] is False and "control ticks" in check["reasons"][0]
    full = {int(round(k * T * 1e9)) for k in range(20)}
    assert replay_check(metadata, {1: Ch()}, {1: [20, 0, max(full), full]})["replayable"] is True
    assert replay_check({}, {}, {})["replayable"] is None


def test_inspect_says_a_run_that_hit_a_joint_stop_cannot_be_replayed(tmp_path):
    """The shipped start (arm stowed on its 180° limit, gripper closed on its lower limit) touches the
    stops; their impulses and holding forces are not in the recording."""
    text = _arm_mission(tmp_path).read_text().replace('proximal_joint: "170 deg"', 'proximal_joint: "180 deg"')
    text = text.replace("gripper_joint: 0.1", "gripper_joint: 0.0")
    path = tmp_path / "stowed.yaml"
    path.write_text(text)
    mcap = _record(path, tmp_path)
    assert any('"joint_stop"' in m.decode() for m in _events(mcap))
    info = inspect_recording(mcap)
    assert info["replay"]["replayable"] is False
    assert "reached its stop" in format_inspection(info)
    assert replay(path, mcap) > 1e-6  # and indeed the replay without the stops does not hold


def _events(mcap: Path) -> list[bytes]:
    with open(mcap, "rb") as f:
        return [m.data for _, _, m in make_reader(f).iter_messages(topics=["/events"])]


def test_held_base_reaction_recorded_is_the_one_of_the_recorded_torques(tmp_path):
    """/base/reaction of a held-base phase (Chevallard 2019's deployment) equals the support wrench
    recomputed from the recorded state and joint torques (it once ignored the torques)."""
    mission = tmp_path / "held.yaml"
    mission.write_text(f"extends: {ROOT / 'missions' / 'chevallard_deploy_track.yaml'}\n"
                       "simulation:\n  phases:\n    - name: deployment\n      kind: deploy\n      base_mode: fixed\n"
                       "      duration: 6 s\n      waypoints: [{at: 5 s, joints: {joint_2: 30 deg}}]\n")
    sm = compile_system(load_mission(mission))
    _, topics = _read(_record(mission, tmp_path))
    arm = [a.name for a in sm.arm]
    q_arm, v_arm = _column(topics, "/joints/position", arm), _column(topics, "/joints/rate", arm)
    tau_m = _column(topics, "/joints/torque", arm)
    reaction = _column(topics, "/base/reaction", ["fx", "fy", "fz", "nx", "ny", "nz"])
    at = {round(t, 9): k for k, t in enumerate(topics["/joints/position"][0])}
    rows = [at[round(t, 9)] for t in topics["/base/reaction"][0]]  # the t = 0 sample precedes the held phase
    assert len(rows) == q_arm.shape[0] - 1 > 100
    worst, scale = 0.0, 0.0
    for i, k in enumerate(rows):
        q, v = sm.q0.copy(), np.zeros(sm.nv)
        q[[a.q_index for a in sm.arm]], v[sm.idx.arm] = q_arm[k], v_arm[k]
        tau = np.zeros(sm.nv)
        tau[sm.idx.arm] = tau_m[k]
        vd, ed = sm.forward_dynamics_fixed_base(q, v, sm.eta0, sm.etadot0, tau)
        expected = sm.base_reaction(q, v, sm.eta0, sm.etadot0, vd, ed)
        worst, scale = max(worst, float(np.max(np.abs(reaction[i] - expected)))), max(scale, float(np.max(np.abs(expected))))
    assert scale > 1e-3 and worst <= 1e-9 * scale
