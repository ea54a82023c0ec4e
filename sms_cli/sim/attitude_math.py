"""Quaternion helpers for the simulator (xyzw, scalar last; world ← base)."""

from __future__ import annotations

import numpy as np


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of xyzw quaternions; (4,) or stacks (…, 4) that broadcast."""
    ax, ay, az, aw = (a[..., i] for i in range(4))
    bx, by, bz, bw = (b[..., i] for i in range(4))
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def quat_conj(q: np.ndarray) -> np.ndarray:
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def quat_log(q: np.ndarray) -> np.ndarray:
    """Rotation vector (rad, angle ≤ π) of unit quaternions, (4,) → (3,) or (…, 4) → (…, 3)."""
    q = np.where(q[..., 3:4] < 0, -q, q)
    n = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    scale = np.where(n < 1e-12, 2.0, 2.0 * np.arctan2(n, q[..., 3:4]) / np.maximum(n, 1e-300))
    return scale * q[..., :3]


def attitude_error(q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation vector of q_ref⁻¹ ⊗ q (base-frame error; zero when aligned), rad; stacks (…, 4) broadcast."""
    return quat_log(quat_mul(quat_conj(q_ref), q))
