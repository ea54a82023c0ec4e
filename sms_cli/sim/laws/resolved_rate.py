"""End-effector tracking by generalized-Jacobian resolved rate (Chevallard 2019, §5.4,
(5.53)–(5.57), Fig. 5.5): an outer P loop on the end-effector error gives a twist, the
generalized Jacobian maps it to joint rates, an inner D loop gives the torques:

    q̇_d = J*⁺ (ẋ_d + K e − J*_r Ω),   τ = K_D (q̇_d − q̇)

J* = J_mEE (free-floating base, zero momentum: ``SystemModel.generalized_jacobians``) or the
fixed-base Jacobian; J*_r Ω removes the end-effector motion the spinning wheels cause through
the base (J_rEE). Position rows only unless the reference carries an orientation (optional
``quat`` [x y z w] and ``omega`` (rad/s) attributes, inertial frame). e in m (and rad), ẋ in m/s,
K (1/s), K_D (N m s/rad). J*⁺ is a damped least-squares inverse: damping λ² = λ_max² (1 − (σ_min/ε)²)
when the smallest singular value σ_min drops below ε, 0 otherwise (Nakamura–Hanafusa,
Maciejewski–Klein). Joint rates are scaled down together to respect each joint's max velocity.
"""

from __future__ import annotations

import math

import numpy as np

from sms_cli.sim.interfaces import EndEffectorRef, Sensed
from sms_cli.sim.laws.plant_models import base_rotation


def damped_pinv_solve(J: np.ndarray, x: np.ndarray, damping: float, threshold: float) -> tuple[np.ndarray, float]:
    """Σ σ_i/(σ_i² + λ²) v_i u_iᵀ x with the adaptive λ above (J with at most 6 rows); returns (solution, λ²).
    Computed by the law's kernel (``sms_cli.sim.compiled.resolved_rate.joint_rates``), without rate limits."""
    from sms_cli.sim.compiled.resolved_rate import joint_rates

    J = np.asarray(J, dtype=float)
    m, n = J.shape
    A, b = np.zeros((6, n)), np.zeros(6)
    A[6 - m:], b[6 - m:] = J, x
    out = np.empty(n)
    lam2 = joint_rates(A, np.zeros((6, 0)), b, 6 - m, np.zeros(0), float(damping), float(threshold), np.full(n, np.inf), out)
    return out, float(lam2)


def _f64(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


def _rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix."""
    c = max(-1.0, min(1.0, 0.5 * (np.trace(R) - 1.0)))
    angle = math.acos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if angle < 1e-9:
        return 0.5 * w
    if math.pi - angle < 1e-6:
        d = np.sqrt(np.maximum((np.diag(R) + 1.0) / 2.0, 0.0))
        k = int(np.argmax(d))
        axis = R[:, k] + np.eye(3)[:, k]
        return angle * axis / np.linalg.norm(axis)
    return angle / (2.0 * math.sin(angle)) * w


class ResolvedRate:
    """Generalized-Jacobian resolved-rate end-effector tracking (see module docstring)."""

    def __init__(self, sm, gain, kd, damping: float = 0.05, threshold: float = 0.05,
                 jacobian: str = "generalized", max_rate=None, orientation_gain=None):
        if jacobian not in ("generalized", "fixed_base"):
            raise ValueError("jacobian is 'generalized' or 'fixed_base'")
        self.sm = sm
        self.K = np.asarray(gain, dtype=float)
        self.K_rot = self.K if orientation_gain is None else np.asarray(orientation_gain, dtype=float)
        self.kd = np.asarray(kd, dtype=float)
        self.damping, self.threshold = float(damping), float(threshold)
        self.jacobian = jacobian
        n = len(sm.arm)
        if max_rate is None:
            max_rate = [a.max_velocity for a in sm.arm]
        self.max_rate = np.broadcast_to(np.asarray(max_rate, dtype=float), (n,)).copy()
        self.last_damping = 0.0
        self.last_error = np.zeros(3)

    def reset(self) -> None:
        pass

    def _jacobians(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(J_m, J_r): end-effector twist [ω; v] (inertial) per arm rate and per wheel rate."""
        sm = self.sm
        if self.jacobian == "generalized":
            G = sm.generalized_jacobians(q)
            return G["J_mEE"], G["J_rEE"]
        import pinocchio as pin

        pin.computeJointJacobians(sm.model, sm.data, q)
        pin.updateFramePlacements(sm.model, sm.data)
        J = pin.getFrameJacobian(sm.model, sm.data, sm.ee_frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        J = np.vstack([J[3:6], J[0:3]])
        return J[:, sm.idx.arm], J[:, sm.idx.wheels]

    def joint_rates(self, s: Sensed, ref: EndEffectorRef) -> np.ndarray:
        """Desired joint rates q̇_d (arm order) for the reference at this instant (the kernel
        ``sms_cli.sim.compiled.resolved_rate.joint_rates`` on Pinocchio's Jacobians)."""
        from sms_cli.sim.compiled.resolved_rate import joint_rates

        sm = self.sm
        pose = sm.ee_pose(s.q)
        e = np.asarray(ref.position, dtype=float) - pose.translation
        self.last_error = e
        Jm, Jr = self._jacobians(s.q)
        twist = np.concatenate([np.zeros(3), np.asarray(ref.velocity, dtype=float) + self.K * e])
        quat = getattr(ref, "quat", None)
        if quat is not None:
            e_rot = _rotvec(base_rotation(np.asarray(quat, dtype=float)) @ pose.rotation.T)
            twist[:3] = np.asarray(getattr(ref, "omega", np.zeros(3)), dtype=float) + self.K_rot * e_rot
        qd = np.empty(Jm.shape[1])
        self.last_damping = float(joint_rates(_f64(Jm), _f64(Jr), twist, 0 if quat is not None else 3,
                                              _f64(s.wheel_speed), self.damping, self.threshold, self.max_rate, qd))
        return qd

    def torque(self, s: Sensed, ref: EndEffectorRef) -> np.ndarray:
        """Inner rate loop of the seed: τ = K_D (q̇_d − q̇)."""
        return self.kd * (self.joint_rates(s, ref) - np.asarray(s.qd_arm, dtype=float))
