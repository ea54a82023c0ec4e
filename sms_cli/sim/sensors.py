"""Sensor models with seeded noise and bias: gyro, attitude, joint encoders."""

from __future__ import annotations

import numpy as np

from sms_cli.model.system import SystemModel
from sms_cli.sim.attitude_math import quat_exp, quat_mul
from sms_cli.sim.interfaces import Sensed
from sms_cli.sim.schema import SensorsSpec


class Sensors:
    """Turns the true state into ``Sensed`` measurements (deterministic for a given seed)."""

    def __init__(self, sm: SystemModel, spec: SensorsSpec):
        self.sm = sm
        self.spec = spec
        self.rng = np.random.default_rng(spec.seed)
        self.noisy = any(s.noise > 0 or np.any(np.asarray(s.bias) != 0) for s in (spec.gyro, spec.attitude, spec.joints))
        self.q_arm_idx = np.array([a.q_index for a in sm.arm], dtype=int)

    def _perturb(self, x: np.ndarray, s) -> np.ndarray:
        out = x + np.asarray(s.bias, float) if np.any(np.asarray(s.bias) != 0) else x.copy()
        if s.noise > 0:
            out = out + s.noise * self.rng.standard_normal(x.shape)
        return out

    def measure(self, t: float, q: np.ndarray, v: np.ndarray, eta: np.ndarray, etadot: np.ndarray) -> Sensed:
        sm = self.sm
        quat = q[3:7].copy()
        omega = v[3:6].copy()
        q_arm = q[self.q_arm_idx].copy() if self.q_arm_idx.size else np.zeros(0)
        qd_arm = v[sm.idx.arm].copy()
        if self.noisy:
            sp = self.spec
            omega = self._perturb(omega, sp.gyro)
            if sp.attitude.noise > 0 or np.any(np.asarray(sp.attitude.bias) != 0):
                quat = quat_mul(quat, quat_exp(self._perturb(np.zeros(3), sp.attitude)))
            q_arm = self._perturb(q_arm, sp.joints)
            qd_arm = self._perturb(qd_arm, sp.joints)
            q = q.copy()
            q[3:7] = quat
            if self.q_arm_idx.size:
                q[self.q_arm_idx] = q_arm
            v = v.copy()
            v[3:6] = omega
            v[sm.idx.arm] = qd_arm
        R = _rot(q[3:7])
        return Sensed(t=t, quat=quat, omega=omega, position=q[0:3].copy(), velocity=R @ v[0:3],
                      q_arm=q_arm, qd_arm=qd_arm, wheel_speed=v[sm.idx.wheels].copy(), q=q, v=v, eta=eta, etadot=etadot)


def _rot(quat: np.ndarray) -> np.ndarray:
    x, y, z, w = quat
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
