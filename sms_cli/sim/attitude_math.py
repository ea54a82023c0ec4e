"""Quaternion helpers for the simulator (xyzw, scalar last; world ← base)."""

from __future__ import annotations

import math

import numpy as np


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of xyzw quaternions."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def quat_conj(q: np.ndarray) -> np.ndarray:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def quat_exp(rotvec: np.ndarray) -> np.ndarray:
    """Unit quaternion of a rotation vector (rad)."""
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-12:
        return np.array([0.5 * rotvec[0], 0.5 * rotvec[1], 0.5 * rotvec[2], 1.0])
    s = math.sin(0.5 * angle) / angle
    return np.array([s * rotvec[0], s * rotvec[1], s * rotvec[2], math.cos(0.5 * angle)])


def quat_log(q: np.ndarray) -> np.ndarray:
    """Rotation vector (rad, angle ≤ π) of a unit quaternion."""
    if q[3] < 0:
        q = -q
    n = float(np.linalg.norm(q[:3]))
    if n < 1e-12:
        return 2.0 * q[:3]
    return 2.0 * math.atan2(n, q[3]) / n * q[:3]


def attitude_error(q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation vector of q_ref⁻¹ ⊗ q (base-frame error; zero when aligned), rad."""
    return quat_log(quat_mul(quat_conj(q_ref), q))
