"""Actuators: wheel allocation, torque and speed saturation, friction; joint torque limits.

Sign convention: a wheel motor torque τ_w (on the rotor, about its axis a) puts −τ_w a on
the base, so a desired base torque T (base frame) needs A τ_w = −T with A = [a_1 … a_n].
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from sms_cli.model.system import SystemModel
from sms_cli.sim.schema import AllocationSpec, WheelFriction


class WheelArray:
    """Allocation and limits of the reaction wheels."""

    def __init__(self, sm: SystemModel, alloc: AllocationSpec, friction: WheelFriction):
        self.sm = sm
        self.n = len(sm.wheels)
        self.A = np.array([w.axis for w in sm.wheels]).T if self.n else np.zeros((3, 0))
        self.A_pinv = np.linalg.pinv(self.A) if self.n else np.zeros((0, 3))
        self.null = np.eye(self.n) - self.A_pinv @ self.A
        self.spin = np.array([w.spin_inertia for w in sm.wheels])
        self.max_torque = np.array([w.max_torque for w in sm.wheels])
        self.max_speed = np.array([w.max_speed for w in sm.wheels])
        self.alloc = alloc
        self.friction = friction
        self.v_idx = sm.idx.wheels
        self.effective_inertia = self.spin.copy()  # refreshed by update_effective_inertia

    def allocate(self, base_torque: np.ndarray, wheel_speed: np.ndarray) -> np.ndarray:
        """Wheel motor torques (unsaturated) for a desired base torque (N m, base frame)."""
        tau = -self.A_pinv @ base_torque
        if self.alloc.null_space_gain > 0 and self.n > 3:
            tau -= self.alloc.null_space_gain * self.null @ (self.spin * (wheel_speed - self.alloc.target_speed))
        return tau

    def update_effective_inertia(self, q: np.ndarray) -> None:
        """Inertia seen by each wheel's relative speed, 1/(M⁻¹)_ii at configuration q."""
        if self.n:
            Minv = pin.computeMinverse(self.sm.model, self.sm.data, q)
            d = np.diag(Minv)[self.v_idx]
            self.effective_inertia = 1.0 / d

    def clip_torque(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Motor torque limit; returns (clipped, saturated flags)."""
        clipped = np.clip(tau, -self.max_torque, self.max_torque)
        return clipped, np.abs(tau) > self.max_torque * (1 + 1e-12)

    def speed_limited(self, tau: np.ndarray, speed: np.ndarray, dt: float) -> np.ndarray:
        """Torque that cannot push a wheel past its speed limit within one plant step of dt:
        toward the limit, |τ| ≤ I_eff (ω_max − |ω|)/dt, and 0 at the limit."""
        out = tau.copy()
        toward = np.sign(tau) == np.sign(speed)
        room = np.maximum(self.max_speed - np.abs(speed), 0.0)
        cap = self.effective_inertia * room / dt
        mask = toward & (np.abs(tau) > cap)
        out[mask] = np.sign(tau[mask]) * cap[mask]
        return out

    @property
    def has_friction(self) -> bool:
        return self.friction.coulomb != 0 or self.friction.viscous != 0

    def may_reach_limit(self, speed: np.ndarray, tau: np.ndarray, horizon: float) -> bool:
        """Whether a wheel could reach its speed limit within ``horizon`` seconds under ``tau``
        (with a factor 2 of margin); if not, the speed limiter can be skipped for that period."""
        reach = np.abs(speed) + 2.0 * np.abs(tau) / self.effective_inertia * horizon
        return bool(np.any(reach >= self.max_speed))

    def friction_torque(self, speed: np.ndarray) -> np.ndarray:
        f = self.friction
        if f.coulomb == 0 and f.viscous == 0:
            return np.zeros(self.n)
        return -f.coulomb * np.sign(speed) - f.viscous * speed


def clip_joint_torque(sm: SystemModel, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint effort limits (inf where the URDF gives none)."""
    lim = np.array([a.max_effort for a in sm.arm])
    return np.clip(tau, -lim, lim), np.abs(tau) > lim * (1 + 1e-12)
