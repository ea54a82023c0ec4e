"""The one adapter between Pinocchio's state convention and the seeds' (SPART's).

Pinocchio (internal): free-flyer ``q = [x y z, qx qy qz qw, ...]`` with the base-link origin
position in the world frame; base velocity ``v_b = [v (base frame), ω (base frame)]``
(linear first, both in the base frame, v = velocity of the base-link origin).

Seeds (theses, SPART): base velocity ``q̇0 = [ω0 (base frame); ṙ0 (inertial frame)]``
(angular first, mixed frames) with ``ṙ0`` the velocity of the base frame origin (the seeds
put it at the base CoM: place the base-link origin at the base CoM to match them exactly);
twists ``[ω; v]`` angular first; attitude as Z-Y-X Euler angles ``R = Rz(ψ) Ry(θ) Rx(φ)``
or a quaternion.

``v_b = T(q) q̇0`` with ``T = [[0, Rᵀ], [I, 0]]``; ``seed_map(q)`` returns T.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def base_rotation(q: np.ndarray) -> np.ndarray:
    """World-from-base rotation matrix R of a free-flyer configuration."""
    x, y, z, w = q[3:7]
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


def seed_map(q: np.ndarray) -> np.ndarray:
    """6×6 T with Pinocchio base velocity = T @ seed base velocity."""
    R = base_rotation(q)
    T = np.zeros((6, 6))
    T[0:3, 3:6] = R.T
    T[3:6, 0:3] = np.eye(3)
    return T


def base_velocity_to_seed(q: np.ndarray, v_base: np.ndarray) -> np.ndarray:
    """Pinocchio ``[v_body; ω_body]`` → seed ``[ω_body; ṙ_inertial]``."""
    R = base_rotation(q)
    return np.concatenate([v_base[3:6], R @ v_base[0:3]])


def base_velocity_from_seed(q: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Seed ``[ω_body; ṙ_inertial]`` → Pinocchio ``[v_body; ω_body]``."""
    R = base_rotation(q)
    return np.concatenate([R.T @ seed[3:6], seed[0:3]])


def twist_linear_first_to_angular_first(twist: np.ndarray) -> np.ndarray:
    """``[v; ω]`` (Pinocchio) → ``[ω; v]`` (seeds); works on 6-vectors and 6×n matrices."""
    return np.concatenate([twist[3:6], twist[0:3]], axis=0)


def euler_zyx_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` (Kraiem 2022 (2.7), URDF rpy)."""
    return pin.rpy.rpyToMatrix(roll, pitch, yaw)


def matrix_to_euler_zyx(R: np.ndarray) -> np.ndarray:
    """Inverse of ``euler_zyx_to_matrix``: [roll, pitch, yaw]."""
    return pin.rpy.matrixToRpy(R)


def quaternion_xyzw_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion [x, y, z, w] (Pinocchio/ROS order) of a rotation matrix, w ≥ 0."""
    quat = pin.Quaternion(R).normalized()
    c = np.array([quat.x, quat.y, quat.z, quat.w])
    return -c if c[3] < 0 else c


def euler_zyx_from_quaternions(quat: np.ndarray) -> np.ndarray:
    """[roll, pitch, yaw] (rad) of unit quaternions [x, y, z, w] (…, 4) → (…, 3), vectorised.
    Equals ``matrix_to_euler_zyx`` away from gimbal lock (|pitch| = π/2), where any split of
    roll and yaw is valid and this one follows atan2 continuously."""
    x, y, z, w = (quat[..., i] for i in range(4))
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r10 = 2.0 * (x * y + z * w)
    r20 = 2.0 * (x * z - y * w)
    r21 = 2.0 * (y * z + x * w)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    return np.stack([np.arctan2(r21, r22), np.arctan2(-r20, np.hypot(r00, r10)), np.arctan2(r10, r00)], axis=-1)
