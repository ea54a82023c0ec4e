"""``sms export hil`` (Vicariotto 2023 §6.2, (6.2)): the relative motion of two spacecraft replayed by
two facility robots.

Oracles: Pinocchio's SE3 algebra (``g1_HW⁻¹ g2_HW = g12`` at every sample, computed with ``pin.SE3``,
not with the module's vectorised quaternions), a central finite difference of the commanded poses
(``log6``) for the commanded twist, Pinocchio's forward kinematics for the inverse kinematics, closed
forms of an analytic motion (a spin at 0.02 rad/s leaves a 30 deg envelope at t = 30 deg / 0.02 rad/s),
an independent MCAP/protobuf decoder (``mcap`` + ``mcap_protobuf``) and ``csv`` for the files.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from conftest import EXCEPTION_TEXT, ROOT, run_cli

FACILITY = ROOT / "missions" / "facilities" / "oos_sim.yaml"
SPIN = 0.02  # rad/s about y (Vicariotto 2023 §6.2: the locked system's spin, thesis L1175)


# ----------------------------------------------------------------- an analytic two-body motion

def _se3(row) -> pin.SE3:
    return pin.XYZQUATToSE3(np.asarray(row, dtype=float))


def _row(g: pin.SE3) -> np.ndarray:
    return np.asarray(pin.SE3ToXYZQUAT(g), dtype=float)


class Analytic:
    """g1(t) = g1(0) exp(t V1) (constant body twist V1), g12(t) = h0 exp(t ξ) (constant body twist ξ),
    g2 = g1 g12; then V2 = Ad(g12⁻¹) V1 + ξ exactly (computed with Pinocchio's ``actInv``)."""

    def __init__(self, V1, xi, g10=None, h0=None):
        self.V1 = np.asarray(V1, dtype=float)
        self.xi = np.asarray(xi, dtype=float)
        self.g10 = g10 if g10 is not None else pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.2, 0.3), np.array([3.0, -1.0, 2.0]))
        self.h0 = h0 if h0 is not None else pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, math.pi), np.array([2.0, 0.1, -0.05]))

    def g1(self, t: float) -> pin.SE3:
        return self.g10 * pin.exp6(pin.Motion(self.V1 * t))

    def g12(self, t: float) -> pin.SE3:
        return self.h0 * pin.exp6(pin.Motion(self.xi * t))

    def g2(self, t: float) -> pin.SE3:
        return self.g1(t) * self.g12(t)

    def V2(self, t: float) -> np.ndarray:
        return self.g12(t).actInv(pin.Motion(self.V1)).vector + self.xi

    def arrays(self, ts):
        g1 = np.array([_row(self.g1(t)) for t in ts])
        g2 = np.array([_row(self.g2(t)) for t in ts])
        V1 = np.tile(self.V1, (len(ts), 1))
        V2 = np.array([self.V2(t) for t in ts])
        return np.asarray(ts, dtype=float), g1, g2, V1, V2


DRIFT = Analytic(V1=[0.0, 0.0, 0.0, 0.0, SPIN, 0.0], xi=[0.01, 0.002, -0.003, 0.001, 0.02, -0.004])
RIGID = Analytic(V1=[0.0, 0.0, 0.0, 0.0, SPIN, 0.0], xi=np.zeros(6))


def write_run(folder: Path, motion: Analytic, ts, *, formation=True, name="relative_motion.csv") -> Path:
    """A results folder as the two-spacecraft simulation writes it (floats in repr precision)."""
    from sms_cli.hil.motion import COLUMNS

    folder.mkdir(parents=True, exist_ok=True)
    t, g1, g2, V1, V2 = motion.arrays(ts)
    with open(folder / name, "w", newline="") as fh:
        fh.write(",".join(COLUMNS) + "\n")
        for row in np.column_stack([t, g1, g2, V1, V2]):
            fh.write(",".join(repr(float(x)) for x in row) + "\n")
    sim = {"formation": {"master": "client", "other": "servicer", "relative_motion": name}} if formation else {"metrics": {}}
    (folder / "results.json").write_text(json.dumps({"simulate": sim}, indent=2) + "\n")
    return folder


# ----------------------------------------------------------------- the mapping (6.2)

MOUNT1 = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.0), np.array([0.0, 0.0, 1.5]))
MOUNT2 = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, math.pi), np.array([3.0, 0.2, 1.4]))


@pytest.mark.parametrize("moving", ["master", "other"])
def test_commanded_pair_keeps_the_relative_pose_at_every_sample(moving):
    from sms_cli.hil.poses import hil_commands

    ts = np.linspace(0.0, 200.0, 401)
    t, g1, g2, V1, V2 = DRIFT.arrays(ts)
    cmd = hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(MOUNT2), moving)
    h1, h2 = cmd.pair()
    worst = 0.0
    for k, tk in enumerate(ts):
        want = (DRIFT.g1(tk).inverse() * DRIFT.g2(tk)).homogeneous  # g12 by Pinocchio
        got = (_se3(h1[k]).inverse() * _se3(h2[k])).homogeneous
        worst = max(worst, float(np.abs(got - want).max()))
    assert worst < 1e-12, worst
    # the held robot does not move: it sits at its own mount
    held = MOUNT2 if moving == "master" else MOUNT1
    assert np.abs(_se3(cmd.held).homogeneous - held.homogeneous).max() < 1e-15


@pytest.mark.parametrize("moving", ["master", "other"])
def test_start_pose_is_the_mount_when_the_mounts_hold_the_initial_geometry(moving):
    from sms_cli.hil.poses import hil_commands

    ts = np.linspace(0.0, 10.0, 11)
    t, g1, g2, V1, V2 = DRIFT.arrays(ts)
    m2 = MOUNT1 * DRIFT.g12(0.0)  # mount1⁻¹ mount2 = g12(0)
    cmd = hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(m2), moving)
    own = MOUNT1 if moving == "master" else m2
    assert np.abs(_se3(cmd.poses[0]).homogeneous - own.homogeneous).max() < 1e-12
    assert cmd.start_offset[0] < 1e-12 and cmd.start_offset[1] < 1e-7
    # the held mount off the initial geometry by 5 cm and 2 deg: the start offset says so
    shifted = pin.SE3(m2.rotation @ pin.rpy.rpyToMatrix(0.0, math.radians(2.0), 0.0),
                      m2.translation + np.array([0.03, 0.0, 0.04]))
    cmd = hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(shifted), moving)
    own = MOUNT1 if moving == "master" else shifted
    d = own.inverse() * _se3(cmd.poses[0])
    assert cmd.start_offset[0] == pytest.approx(np.linalg.norm(d.translation), abs=1e-12)
    assert cmd.start_offset[1] == pytest.approx(math.radians(2.0), abs=1e-9)
    assert cmd.start_offset[0] > 0.04


@pytest.mark.parametrize("moving", ["master", "other"])
def test_commanded_twist_is_the_derivative_of_the_commanded_pose(moving):
    """Central difference of the commanded pose, log6(g(t−h)⁻¹ g(t+h)) / 2h, against the commanded body twist."""
    from sms_cli.hil.poses import hil_commands

    h = 1e-4
    ts = np.array([0.0, 13.7, 57.0, 120.5])

    def cmd_at(times):
        t, g1, g2, V1, V2 = DRIFT.arrays(times)
        return hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(MOUNT2), moving)

    cmd = cmd_at(ts)
    lo, hi = cmd_at(ts - h), cmd_at(ts + h)
    for k in range(len(ts)):
        fd = pin.log6(_se3(lo.poses[k]).inverse() * _se3(hi.poses[k])).vector / (2 * h)
        assert np.abs(cmd.twist[k] - fd).max() < 1e-8, (k, cmd.twist[k], fd)
        assert np.linalg.norm(cmd.twist[k]) > 1e-3  # a real motion, not a trivial zero


def test_rigid_following_commands_no_motion():
    from sms_cli.hil.poses import hil_commands

    ts = np.linspace(0.0, 300.0, 61)
    t, g1, g2, V1, V2 = RIGID.arrays(ts)
    cmd = hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(MOUNT2), "master")
    assert np.abs(cmd.twist).max() < 1e-15
    assert np.abs(cmd.poses[:, :3] - cmd.poses[0, :3]).max() < 1e-12


# ----------------------------------------------------------------- reachability (Pinocchio IK)

@pytest.fixture(scope="module")
def client_robot():
    from sms_cli.hil.schema import load_facility
    from sms_cli.hil.stage import _robot

    loaded = load_facility(FACILITY)
    return _robot(loaded, "master", "master", loaded.facility.spacecraft["master"])


def test_ik_recovers_a_forward_kinematics_pose(client_robot):
    from sms_cli.hil.reach import solve_ik

    r = client_robot
    assert r.model.nq == 6 and r.joint_names[0] == "joint_a1"
    for q_known in (np.radians([20, -70, 80, 30, 40, -50]), np.radians([-35, -100, 60, -20, -70, 90])):
        target = r.tool_pose(q_known)  # Pinocchio FK, the oracle
        sol = solve_ik(r, target, r.home)
        got = r.tool_pose(sol.q)
        assert np.abs(got.homogeneous - target.homogeneous).max() < 1e-9
        assert sol.reachable and sol.position_error < 1e-9 and sol.rotation_error < 1e-9
        assert np.all(sol.q >= r.lower) and np.all(sol.q <= r.upper)


def test_trajectory_reachable_until_a_pose_10_m_away(client_robot):
    from sms_cli.hil.reach import reach_trajectory

    r = client_robot
    n, k_far = 300, 217
    qs = np.linspace(r.home + np.radians([0, 20, -10, 0, 30, 0]), np.radians([25, -60, 70, 40, 35, -30]), n)
    poses = np.array([r.mockup_pose(q) for q in qs])  # mock-up poses the robot reaches by construction
    poses[k_far:, 0] += 10.0
    rc = reach_trajectory(r, poses)
    t = np.linspace(0.0, 29.9, n)
    assert rc.first_unreachable == k_far and rc.summary(t)["first_unreachable_s"] == t[k_far]
    assert rc.reachable[:k_far].all() and not rc.reachable[k_far:].any()
    assert rc.position_error[:k_far].max() < 1e-9 and rc.rotation_error[:k_far].max() < 1e-9
    assert "out of reach" in rc.reason or "joint limit" in rc.reason
    assert np.all(rc.q >= r.lower - 1e-12) and np.all(rc.q <= r.upper + 1e-12)
    # the joint path the warm start follows is continuous: no branch jumps between reachable samples
    assert np.abs(np.diff(rc.q[:k_far], axis=0)).max() < np.radians(5)


def test_a_pose_beyond_a_joint_limit_is_named(client_robot):
    """A6 limited to ±350 deg: the mock-up rolled about the flange axis past it, reachable otherwise."""
    from sms_cli.hil.reach import reach_trajectory

    r = client_robot
    q = np.radians([10, -80, 85, 0, 30, 0])
    roll = np.radians(np.linspace(0, 359, 360))
    poses = []
    for a in roll:
        qa = q.copy()
        qa[5] = -a  # axis −x: positive roll about the flange axis is −a6
        poses.append(r.mockup_pose(qa))
    rc = reach_trajectory(r, np.array(poses))
    k = rc.first_unreachable
    assert k is not None and "joint limit (joint_a6)" in rc.reason
    assert abs(np.degrees(roll[k]) - 351) <= 1.0  # the first sample past 350 deg


# ----------------------------------------------------------------- workspace (the COMRADE "12 s" metric)

def test_rigid_spin_needs_no_relative_motion_and_leaves_30_deg_on_time():
    from sms_cli.hil.poses import hil_commands
    from sms_cli.hil.workspace import Envelope, absolute_replay, compare

    dt = 0.1
    ts = np.arange(0.0, 60.0 + dt / 2, dt)
    t, g1, g2, V1, V2 = RIGID.arrays(ts)
    cmd = hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(MOUNT2), "master")
    env = Envelope((0.5, 0.5, 0.5), None, math.radians(30.0))
    w, ea, er = compare(t, absolute_replay(g1, _row(MOUNT1)), cmd.poses, env)
    rel, ab = w["relative"], w["absolute"]
    assert max(rel["translation_range_m"].values()) < 1e-12 and rel["max_rotation_deg"] < 1e-9
    assert rel["leaves_envelope_s"] is None and rel["inside_fraction"] == 1.0
    t_star = math.radians(30.0) / SPIN  # 26.18 s
    assert t_star <= ab["leaves_envelope_s"] < t_star + dt and ab["leaves_by"] == "rotation"
    assert ab["max_rotation_deg"] == pytest.approx(math.degrees(SPIN * 60.0), rel=1e-12)
    # the absolute replay spins the mock-up about its own origin: no translation
    assert max(ab["translation_range_m"].values()) < 1e-12
    # an envelope with a radius: the relative drift of DRIFT leaves 0.1 m when |d| first exceeds it
    t, g1, g2, V1, V2 = DRIFT.arrays(ts)
    cmd = hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(MOUNT2), "master")
    w, _, er = compare(t, absolute_replay(g1, _row(MOUNT1)), cmd.poses, Envelope(None, 0.1, math.radians(90)))
    dist = np.linalg.norm(er.displacement, axis=1)
    k = int(np.argmax(dist > 0.1))
    assert dist[k - 1] <= 0.1 < dist[k] and w["relative"]["leaves_envelope_s"] == t[k] and w["relative"]["leaves_by"] == "radius"


# ----------------------------------------------------------------- the command, its files and its errors

MILD = Analytic(V1=[0.0, 0.0, 0.0, 0.0, SPIN, 0.0], xi=[0.001, 0.0005, -0.0005, 0.0, 0.001, 0.0],
                g10=pin.SE3.Identity(), h0=pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, math.pi), np.array([3.0, 0.0, 0.0])))


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """The shipped facility on a 120 s run whose mounts hold its initial geometry (3 m apart, facing: S6)."""
    folder = write_run(tmp_path_factory.mktemp("hil") / "run", MILD, np.linspace(0.0, 120.0, 601))
    r = run_cli("export", "hil", folder, "--facility", FACILITY, "--json")
    assert r.exit_code == 0, r.output
    return folder, json.loads(r.stdout)


def test_export_summary_and_files(exported):
    folder, s = exported
    hil = folder / "hil"
    assert sorted(p.name for p in hil.iterdir()) == ["commands.csv", "commands.mcap", "workspace.json", "workspace.png"]
    assert s["moving"] == "client" and s["held"] == "servicer" and s["samples"] == 601
    assert s["start_offset"]["distance_m"] < 1e-12
    assert s["reachability"]["client"]["all_reachable"] and s["reachability"]["servicer"]["samples"] == 1
    assert json.loads((hil / "workspace.json").read_text()) == s["workspace"]
    # 45 deg at 0.02 rad/s: the absolute replay leaves the shipped envelope at 39.27 s (samples every 0.2 s)
    assert 45 / math.degrees(SPIN) <= s["workspace"]["absolute"]["leaves_envelope_s"] < 45 / math.degrees(SPIN) + 0.2
    assert s["workspace"]["relative"]["leaves_envelope_s"] is None


def test_csv_rows_are_the_commanded_poses(exported):
    from sms_cli.hil.motion import read_relative_motion
    from sms_cli.hil.poses import hil_commands
    from sms_cli.hil.schema import load_facility

    folder, s = exported
    with open(folder / "hil" / "commands.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    moving = [r for r in rows if r["role"] == "moving"]
    held = [r for r in rows if r["role"] == "held"]
    assert len(moving) == 601 and len(held) == 1 and {r["mockup"] for r in moving} == {"client"}
    fac = load_facility(FACILITY).facility
    m = read_relative_motion(folder / "relative_motion.csv")
    cmd = hil_commands(m.t, m.g1, m.g2, m.V1, m.V2, _row(fac.spacecraft["master"].mount.se3()),
                       _row(fac.spacecraft["other"].mount.se3()))
    pose_cols = ["x", "y", "z", "qx", "qy", "qz", "qw"]
    twist_cols = ["vx", "vy", "vz", "wx", "wy", "wz"]
    got = np.array([[float(r[c]) for c in pose_cols] for r in moving])
    assert np.array_equal(got, cmd.poses)  # repr precision: exact round trip
    assert np.array_equal(np.array([[float(r[c]) for c in twist_cols] for r in moving]), cmd.twist)
    assert np.array_equal(np.array([float(held[0][c]) for c in pose_cols]), cmd.held)
    assert all(r["reachable"] == "1" for r in rows)
    # joint columns reproduce the pose through Pinocchio FK of the shipped URDF
    model = pin.buildModelFromUrdf(str(ROOT / "robots" / "facility" / "industrial_6dof.urdf"))
    data = model.createData()
    fid = model.getFrameId("flange")
    for r in moving[::100]:
        q = np.array([float(r[f"q{j}_rad"]) for j in range(1, 7)])
        pin.framesForwardKinematics(model, data, q)
        mock = data.oMf[fid] * pin.SE3(np.eye(3), np.array([0.5, 0.0, 0.0]))  # base at the origin, flange_to_mockup
        want = _se3([float(r[c]) for c in pose_cols])
        assert np.abs(mock.homogeneous - want.homogeneous).max() < 1e-9


def test_mcap_decodes_with_an_independent_reader(exported):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    folder, s = exported
    with open(folder / "hil" / "commands.csv", newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["role"] == "moving"]
    with open(folder / "hil" / "commands.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary.statistics.message_count == 4 * 601  # /tf, /hil/twist and the two robots' joints
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        assert meta["formation"]["moving"] == "client" and meta["facility"]["name"] == "oos_sim"
        tf, twist = [], []
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            if channel.topic == "/tf":
                tf.append((message.log_time, decoded))
            elif channel.topic == "/hil/twist":
                twist.append(list(decoded.v) + list(decoded.w))
    assert len(tf) == 601 and len(twist) == 601
    log_time, first = tf[0]
    frames = {(f.parent_frame_id, f.child_frame_id) for f in first.transforms}
    assert frames == {("oos_sim", "client_mockup"), ("oos_sim", "servicer_mockup"), ("oos_sim", "client_robot_base"),
                      ("oos_sim", "servicer_robot_base"), ("client_robot_base", "client_tool"),
                      ("servicer_robot_base", "servicer_tool")}
    for k in (0, 300, 600):
        log_time, msg = tf[k]
        assert log_time == round(float(rows[k]["t"]) * 1e9)
        (mock,) = [f for f in msg.transforms if f.child_frame_id == "client_mockup"]
        got = [mock.translation.x, mock.translation.y, mock.translation.z,
               mock.rotation.x, mock.rotation.y, mock.rotation.z, mock.rotation.w]
        assert got == [float(rows[k][c]) for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
        assert msg.transforms[0].timestamp.seconds * 10**9 + msg.transforms[0].timestamp.nanos == log_time
        assert twist[k] == [float(rows[k][c]) for c in ("vx", "vy", "vz", "wx", "wy", "wz")]


def test_workspace_png_is_legible(exported):
    from sms_cli.report.figstyle import DPI, FULL_PX, MIN_FONT_PT, png_info

    folder, _ = exported
    info = png_info((folder / "hil" / "workspace.png").read_bytes())
    assert info["width"] == FULL_PX
    meta = info["text"]
    assert float(meta["sms:font-px-min"]) >= MIN_FONT_PT * DPI / 72 - 1e-6
    assert float(meta["sms:text-overlaps"]) == 0 and float(meta["sms:text-clipped"]) == 0


def test_require_reachable_turns_a_finding_into_exit_1(tmp_path):
    far = Analytic(V1=[0.0, 0.0, 0.0, 0.0, SPIN, 0.0], xi=[0.05, 0.0, 0.0, 0.0, 0.0, 0.0], g10=pin.SE3.Identity(),
                   h0=MILD.h0)  # body 2 drifts 5 cm/s away: the client robot runs out of reach
    folder = write_run(tmp_path / "run", far, np.linspace(0.0, 100.0, 201))
    r = run_cli("export", "hil", folder, "--facility", FACILITY, "--json", "--no-plots")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)["reachability"]["client"]
    assert not s["all_reachable"] and 0 < s["first_unreachable_s"] < 100
    r = run_cli("export", "hil", folder, "--facility", FACILITY, "--require-reachable", "-o", tmp_path / "o")
    assert r.exit_code == 1, r.output
    assert "first unreachable at" in r.stdout and (tmp_path / "o" / "hil" / "commands.csv").exists()


def _facility(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "fac.yaml"
    p.write_text(text.replace("URDF", str(ROOT / "robots" / "facility" / "industrial_6dof.urdf")))
    return p


GOOD = """name: lab
spacecraft:
  client:
    mount: {xyz: [2.0, 0.0, 1.6]}
  servicer:
    mount:
      xyz: [3.0, 0.0, 1.6]
      quaternion: [0.0, 0.0, 1.0, 0.0]
envelope: {radius: 1 m, rotation: 30 deg}
"""


@pytest.mark.parametrize("case, text, line, words", [
    ("quaternion", GOOD.replace("[0.0, 0.0, 1.0, 0.0]", "[0.0, 0.0, 1.0, 0.01]"), 8, "norm 1.00005"),
    ("matrix", GOOD.replace("quaternion: [0.0, 0.0, 1.0, 0.0]", "matrix: [[1, 0, 0], [0, 1, 0], [0, 0.1, 1]]"), 8,
     "not a rotation"),
    ("reflection", GOOD.replace("quaternion: [0.0, 0.0, 1.0, 0.0]", "matrix: [[1, 0, 0], [0, 1, 0], [0, 0, -1]]"), 8,
     "determinant is -1"),
    ("unknown spacecraft", GOOD.replace("  servicer:", "  servicr:"), 5, "neither master/other"),
    ("tool frame", GOOD.replace("    mount: {xyz: [2.0, 0.0, 1.6]}",
                                "    mount: {xyz: [2.0, 0.0, 1.6]}\n    robot: {urdf: URDF, tool_frame: flang}"), 5,
     "did you mean 'flange'"),
])
def test_bad_facility_file_is_exit_2_with_its_line(tmp_path, case, text, line, words):
    folder = write_run(tmp_path / "run", MILD, np.linspace(0.0, 1.0, 3))
    fac = _facility(tmp_path, text)
    r = run_cli("export", "hil", folder, "--facility", fac)
    assert r.exit_code == 2, r.output
    assert f"{fac}:{line}" in r.stderr and words in r.stderr, r.stderr
    assert not EXCEPTION_TEXT.search(r.output), r.output
    assert not (folder / "hil").exists() or not any((folder / "hil").iterdir())


@pytest.mark.parametrize("damage, where, words", [
    ("no table", "relative_motion.csv", "no relative-motion table"),
    ("no formation", "results.json:2", "not the results of a two-spacecraft simulation"),
    ("no folder", "nowhere", "no such results folder"),
    ("short row", "relative_motion.csv:4:1", "values, the header has 27 columns"),
    ("not a number", "relative_motion.csv:3:", "is not a number"),
    ("quaternion", "relative_motion.csv:3:1", "quaternion q2 has norm"),
    ("time", "relative_motion.csv:4:1", "does not increase"),
])
def test_bad_results_folder_is_exit_2(tmp_path, damage, where, words):
    folder = write_run(tmp_path / "run", MILD, np.linspace(0.0, 1.0, 5), formation=damage != "no formation")
    table = folder / "relative_motion.csv"
    lines = table.read_text().splitlines()
    if damage == "no table":
        table.unlink()
    elif damage == "no folder":
        folder = tmp_path / "nowhere"
    elif damage == "short row":
        lines[3] = lines[3].rsplit(",", 1)[0]
    elif damage == "not a number":
        lines[2] = lines[2].replace(",", ",x", 1)
    elif damage == "quaternion":
        f = lines[2].split(",")
        f[13] = repr(float(f[13]) * 1.001)  # q2_z
        lines[2] = ",".join(f)
    elif damage == "time":
        f = lines[3].split(",")
        f[0] = lines[2].split(",")[0]  # a repeated time
        lines[3] = ",".join(f)
    if table.exists():
        table.write_text("\n".join(lines) + "\n")
    r = run_cli("export", "hil", folder, "--facility", FACILITY)
    assert r.exit_code == 2, r.output
    assert where in r.stderr and words in r.stderr, r.stderr
    assert not EXCEPTION_TEXT.search(r.output), r.output


def test_interrupted_export_leaves_no_half_file(tmp_path, monkeypatch):
    from sms_cli.recording import writer

    folder = write_run(tmp_path / "run", MILD, np.linspace(0.0, 10.0, 51))

    def killed(self):
        raise KeyboardInterrupt

    monkeypatch.setattr(writer.ChunkedMcapWriter, "finish", killed)
    r = run_cli("export", "hil", folder, "--facility", FACILITY)
    assert r.exit_code == 130, r.output
    assert sorted(p.name for p in (folder / "hil").iterdir()) == ["commands.csv"]  # written before; no .part, no mcap


def test_help_documents_the_command_and_its_example():
    r = run_cli("export", "hil", "--help")
    assert r.exit_code == 0
    for words in ("--facility", "--require-reachable", "--json", "--out", "simulate.formation", "exit 2",
                  "sms export hil results/formation --facility missions/facilities/oos_sim.yaml"):
        assert words in " ".join(r.stdout.split()), words
    assert FACILITY.exists()


def test_absolute_replay_is_the_motion_from_the_mount():
    """A(t) = mount · g1(0)⁻¹ g1(t), by Pinocchio, for a body that translates and rotates."""
    from sms_cli.hil.workspace import absolute_replay

    moving = Analytic(V1=[0.05, -0.02, 0.01, 0.0, SPIN, 0.01], xi=np.zeros(6))
    ts = np.linspace(0.0, 50.0, 26)
    _, g1, *_ = moving.arrays(ts)
    A = absolute_replay(g1, _row(MOUNT1))
    for k, tk in enumerate(ts):
        want = MOUNT1 * moving.g1(0.0).inverse() * moving.g1(tk)
        assert np.abs(_se3(A[k]).homogeneous - want.homogeneous).max() < 1e-12


def test_reachability_thresholds_are_1_mm_and_0_1_deg():
    from sms_cli.hil.reach import IkSolution

    q = np.zeros(6)
    assert IkSolution(q, 1e-3, math.radians(0.1), []).reachable
    assert not IkSolution(q, 1.001e-3, 0.0, []).reachable
    assert not IkSolution(q, 0.0, math.radians(0.1001), []).reachable


def test_mirror_replay_without_robots_and_mounts_off_the_initial_geometry(tmp_path):
    folder = write_run(tmp_path / "run", DRIFT, np.linspace(0.0, 20.0, 41))
    fac = _facility(tmp_path, GOOD.replace("quaternion: [0.0, 0.0, 1.0, 0.0]", "rpy: [0 deg, 0 deg, 90 deg]")
                    + "moving: servicer\n")
    r = run_cli("export", "hil", folder, "--facility", fac, "--json", "--no-plots")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["moving"] == "servicer" and s["held"] == "client" and s["reachability"] is None
    assert s["workspace"]["role"] == "other" and "png" not in " ".join(s["files"])
    # DRIFT starts 2 m apart, the mounts 1 m: the servicer mock-up starts off its mount, and stderr says where
    assert s["start_offset"]["distance_m"] > 0.9
    # the absolute replay is the servicer's (body 2's) own motion from its mount, by Pinocchio
    mount2 = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, math.pi / 2), np.array([3.0, 0.0, 1.6]))
    p = np.array([(mount2 * DRIFT.g2(0.0).inverse() * DRIFT.g2(tk)).translation for tk in np.linspace(0.0, 20.0, 41)])
    got = s["workspace"]["absolute"]["translation_range_m"]
    assert [got[a] for a in "xyz"] == pytest.approx(list(p.max(axis=0) - p.min(axis=0)), abs=1e-12)
    assert "the mounts do not hold the run's initial relative pose" in r.stderr and f"{fac}:7" in r.stderr
    r = run_cli("export", "hil", folder, "--facility", fac, "--require-reachable", "--no-plots")
    assert r.exit_code == 2 and "gives no robot URDF" in r.stderr
