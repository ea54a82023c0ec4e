"""The HIL mapping of Vicariotto 2023 §6.2 ((6.2), thesis L1163): the relative motion of two simulated
spacecraft replayed by two facility robots, one held still and one moving.

Poses are rows ``[x y z qx qy qz qw]`` world<-frame (m, unit quaternion, scalar last, Hamilton), stacked
(n, 7); twists are body twists ``[v; ω]`` in the moving frame (m/s, rad/s), as Pinocchio's LOCAL frame.
Everything is vectorised over samples; ``tests/test_hil_export.py`` checks it against ``pinocchio.SE3``.

With g1, g2 the absolute poses (world<-base i) and V1, V2 their body twists:

- relative pose ``g12 = g1⁻¹ g2`` (body 2 seen from body 1, DESIGN.md §4b), and its body twist (in
  frame 2) ``V12 = V2 − Ad(g12⁻¹) V1`` (from ``ġ12 = −V̂1 g12 + g12 V̂2``);
- ``moving = "master"`` (the thesis): ``g2_HW = mount of body 2`` held, ``g1_HW(t) = g2_HW g12(t)⁻¹``;
  its body twist is ``V1_HW = −Ad(g12) V12 = V1 − Ad(g12) V2`` (zero when the two move as one body);
- ``moving = "other"`` (the mirror): ``g1_HW = mount of body 1`` held, ``g2_HW(t) = g1_HW g12(t)``,
  body twist ``V2_HW = V12``.

Either way ``g1_HW⁻¹ g2_HW = g12`` at every sample. The held mount fixes where the replay starts:
when the two mounts already hold the initial relative geometry (``mount1⁻¹ mount2 = g12(0)``) the moving
mock-up starts at its own mount; otherwise it starts where g12(0) puts it and ``start_offset`` says how far.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sms_cli.sim.attitude_math import quat_conj as qconj
from sms_cli.sim.attitude_math import quat_log
from sms_cli.sim.attitude_math import quat_mul as qmul

# ----------------------------------------------------------------- quaternion/pose algebra (vectorised)


def qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R(q) v for unit quaternions q (…, 4) and vectors v (…, 3)."""
    u, w = q[..., :3], q[..., 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose product a b (rows (…, 7))."""
    return np.concatenate([a[..., :3] + qrot(a[..., 3:], b[..., :3]), qmul(a[..., 3:], b[..., 3:])], axis=-1)


def inverse(a: np.ndarray) -> np.ndarray:
    """Pose inverse a⁻¹ (rows (…, 7))."""
    qi = qconj(a[..., 3:])
    return np.concatenate([-qrot(qi, a[..., :3]), qi], axis=-1)


def adjoint(g: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Ad(g) V for body twists V = [v; ω] (…, 6): ω' = R ω, v' = R v + p × (R ω) (Pinocchio's ``g.act(Motion)``)."""
    w = qrot(g[..., 3:], V[..., 3:])
    return np.concatenate([qrot(g[..., 3:], V[..., :3]) + np.cross(g[..., :3], w), w], axis=-1)


def continuous(poses: np.ndarray) -> np.ndarray:
    """The same poses with each quaternion's sign chosen so that consecutive ones have a positive dot
    product (q and −q are one rotation: no jumps for interpolating readers); the first keeps w ≥ 0."""
    out = np.array(poses, dtype=float, copy=True)
    q = out[:, 3:]
    flip = np.ones(len(q))
    flip[0] = -1.0 if q[0, 3] < 0 else 1.0
    if len(q) > 1:
        flip[1:] = np.where(np.einsum("ij,ij->i", q[1:], q[:-1]) < 0, -1.0, 1.0)
    q *= np.cumprod(flip)[:, None]
    return out


def rotation_angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad, in [0, π]) of unit quaternions (…, 4)."""
    return np.linalg.norm(quat_log(q), axis=-1)


def pose_row(se3) -> np.ndarray:
    """``[x y z qx qy qz qw]`` of a ``pinocchio.SE3``."""
    import pinocchio as pin

    return np.asarray(pin.SE3ToXYZQUAT(se3), dtype=float).copy()


# ----------------------------------------------------------------- the mapping


@dataclass
class HilCommands:
    """What the two facility robots are commanded (facility world frame; n samples).

    ``moving`` is "master" or "other"; ``poses`` (n, 7) world<-mock-up of the moving mock-up and
    ``twist`` (n, 6) its body twist [v; ω]; ``held`` (7,) the held mock-up's pose; ``g12`` (n, 7) the
    relative pose; ``start_offset`` (m, rad) of the moving mock-up's first pose from its own mount."""

    t: np.ndarray
    moving: str
    poses: np.ndarray
    twist: np.ndarray
    held: np.ndarray
    g12: np.ndarray
    start_offset: tuple[float, float]

    def pair(self) -> tuple[np.ndarray, np.ndarray]:
        """(g1_HW, g2_HW), each (n, 7)."""
        held = np.broadcast_to(self.held, self.poses.shape)
        return (self.poses, held) if self.moving == "master" else (held, self.poses)


def relative_pose(g1: np.ndarray, g2: np.ndarray) -> np.ndarray:
    """g12 = g1⁻¹ g2 (n, 7)."""
    return compose(inverse(g1), g2)


def relative_twist(g12: np.ndarray, V1: np.ndarray, V2: np.ndarray) -> np.ndarray:
    """Body twist of g12 in frame 2: V12 = V2 − Ad(g12⁻¹) V1 (n, 6)."""
    return V2 - adjoint(inverse(g12), V1)


def hil_commands(t: np.ndarray, g1: np.ndarray, g2: np.ndarray, V1: np.ndarray, V2: np.ndarray,
                 mount1: np.ndarray, mount2: np.ndarray, moving: str = "master") -> HilCommands:
    """The robots' commands of Vicariotto 2023 (6.2) (see the module docstring); ``mount1``, ``mount2``
    are the mock-ups' poses (7,) in the facility world at t = 0."""
    if moving not in ("master", "other"):
        raise ValueError(f"moving must be 'master' or 'other', not {moving!r}")
    g12 = relative_pose(g1, g2)
    V12 = relative_twist(g12, V1, V2)
    if moving == "master":
        held = np.asarray(mount2, dtype=float)
        poses = compose(held, inverse(g12))
        twist = -adjoint(g12, V12)
        own = np.asarray(mount1, dtype=float)
    else:
        held = np.asarray(mount1, dtype=float)
        poses = compose(held, g12)
        twist = V12
        own = np.asarray(mount2, dtype=float)
    d = compose(inverse(own), poses[0])
    offset = (float(np.linalg.norm(d[:3])), float(rotation_angle(d[3:])))
    return HilCommands(np.asarray(t, dtype=float), moving, continuous(poses), twist, held, g12, offset)


__all__ = ["HilCommands", "hil_commands", "relative_pose", "relative_twist", "compose", "inverse", "adjoint",
           "qmul", "qconj", "qrot", "rotation_angle", "continuous", "pose_row"]
