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
    # mounts off the initial geometry by 5 cm: the start offset says so
    shifted = pin.SE3(m2.rotation, m2.translation + np.array([0.0, 0.05, 0.0]))
    cmd = hil_commands(t, g1, g2, V1, V2, _row(MOUNT1), _row(shifted), moving)
    assert cmd.start_offset[0] == pytest.approx(0.05, abs=1e-12)


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
