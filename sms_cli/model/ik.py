"""Inverse kinematics of one frame by damped least squares (closed-loop IK), with Pinocchio.

Used by the HIL facility robots (``sms_cli.hil.reach``) and by the assembly tasks
(``sms_cli.sim.assembly``), each on a fixed-base model: frames are those of ``model``'s world.

Method: a Levenberg–Marquardt step on the body pose error ``e = log6(T*⁻¹ T(q))`` with
``∂e/∂q = Jlog6(T*⁻¹ T(q)) J_LOCAL``, joint limits enforced by projection after every step,
at most :data:`MAX_STEP` rad (or m) per joint and iteration. The pose is reached when the result is
within :data:`POSITION_TOL` (1 mm) and :data:`ROTATION_TOL` (0.1 deg) of the target.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

POSITION_TOL = 1e-3  # m
ROTATION_TOL = np.radians(0.1)  # rad
CONVERGED = 1e-12  # |e| (m, rad) at which the iteration stops
MAX_ITER = 100
MAX_STEP = 0.3  # rad (or m) per iteration, per joint
LIMIT_EPS = 1e-9  # rad: a joint this close to a bound is at its limit


@dataclass
class IkSolution:
    """Joint positions (rad, m), residual position (m) and rotation (rad) of the frame, and the
    indices of the joints left against a limit."""

    q: np.ndarray
    position_error: float
    rotation_error: float
    at_limit: list[int]

    @property
    def reachable(self) -> bool:
        return self.position_error <= POSITION_TOL and self.rotation_error <= ROTATION_TOL


def solve_frame_ik(model, data, frame: int, target, q0: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                   max_iter: int = MAX_ITER) -> IkSolution:
    """Damped least squares CLIK of frame ``frame`` from ``q0`` to ``target`` (``pinocchio.SE3`` in the
    model's world frame), joint positions kept in [lower, upper]; returns the best iterate."""
    import pinocchio as pin

    q = np.clip(np.array(q0, dtype=float), lower, upper)
    best_q, best = q.copy(), np.inf
    stall = 0
    for _ in range(max_iter):
        pin.framesForwardKinematics(model, data, q)
        dMi = target.actInv(data.oMf[frame])  # T*⁻¹ T(q)
        f = pin.log6(dMi).vector  # = −log6(T(q)⁻¹ T*): the body pose error, zero at the target
        err = float(np.linalg.norm(f))
        if err < best - 1e-15:
            best, best_q, stall = err, q.copy(), 0
        else:
            stall += 1
        if err < CONVERGED or stall >= 8:
            break
        J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL)
        Je = pin.Jlog6(dMi) @ J  # ∂ log6(T*⁻¹ T(q)) / ∂q
        lam2 = 1e-10 + 1e-3 * min(err * err, 1.0)
        dq = -Je.T @ np.linalg.solve(Je @ Je.T + lam2 * np.eye(6), f)
        dq *= min(1.0, MAX_STEP / max(float(np.abs(dq).max()), 1e-300))
        q = np.clip(q + dq, lower, upper)
    pin.framesForwardKinematics(model, data, best_q)
    T = data.oMf[frame]
    dp = float(np.linalg.norm(T.translation - target.translation))
    dR = float(np.linalg.norm(pin.log3(T.rotation.T @ target.rotation)))
    at = [j for j in range(best_q.size) if best_q[j] - lower[j] < LIMIT_EPS or upper[j] - best_q[j] < LIMIT_EPS]
    return IkSolution(best_q, dp, dR, at)
