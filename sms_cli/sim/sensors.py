"""Sensor models with seeded noise and bias: gyro, attitude, joint encoders."""

from __future__ import annotations

import numpy as np

from sms_cli.model.system import SystemModel
from sms_cli.sim.interfaces import Sensed
from sms_cli.sim.schema import SensorsSpec


class Sensors:
    """Turns the true state into ``Sensed`` measurements (deterministic for a given seed): the perturbation is
    ``sms_cli.sim.compiled.sensors.measure_state``'s, on normals from ``np.random.default_rng(seed)`` drawn K
    per control tick (``draw``; the compiled loops draw a slice of ticks at once, the same numbers)."""

    def __init__(self, sm: SystemModel, spec: SensorsSpec):
        from sms_cli.sim.compiled.sensors import SENS_JOINT_BIAS, noise_width, sensor_parameters

        self.sm = sm
        self.spec = spec
        self.rng = np.random.default_rng(spec.seed)
        self.noisy = any(s.noise > 0 or np.any(np.asarray(s.bias) != 0) for s in (spec.gyro, spec.attitude, spec.joints))
        self.q_arm_idx = np.array([a.q_index for a in sm.arm], dtype=np.int64)
        self.v_arm_idx = np.array([a.v_index for a in sm.arm], dtype=np.int64)
        self.width = noise_width(spec, len(sm.arm))
        self.par = sensor_parameters(spec, len(sm.arm)) if self.noisy else np.zeros(SENS_JOINT_BIAS + len(sm.arm))
        self._saved = None

    def draw(self, ticks: int) -> np.ndarray:
        """The normals of the next ``ticks`` control ticks (ticks × K), from the stream; ``rewind`` takes back
        those of the ticks that did not run."""
        self._saved = self.rng.bit_generator.state
        if not self.width:
            return np.zeros((ticks, 0))
        return self.rng.standard_normal((ticks, self.width))

    def rewind(self, used: int, drawn: int) -> None:
        """The stream as if only ``used`` of the last ``drawn`` ticks had been drawn (a phase that settled early)."""
        if used < drawn and self.width:
            self.rng.bit_generator.state = self._saved
            self.rng.standard_normal((used, self.width))

    def measure(self, t: float, q: np.ndarray, v: np.ndarray, eta: np.ndarray, etadot: np.ndarray) -> Sensed:
        sm = self.sm
        if self.noisy:
            from sms_cli.sim.compiled.sensors import measure_state

            q_s, v_s = np.empty(q.shape[0]), np.empty(v.shape[0])
            measure_state(self.par, self.draw(1)[0], self.q_arm_idx, self.v_arm_idx, np.ascontiguousarray(q, dtype=float),
                          np.ascontiguousarray(v, dtype=float), q_s, v_s)
            q, v = q_s, v_s
        quat = q[3:7].copy()
        omega = v[3:6].copy()
        q_arm = q[self.q_arm_idx].copy() if self.q_arm_idx.size else np.zeros(0)
        qd_arm = v[sm.idx.arm].copy()
        R = _rot(q[3:7])
        return Sensed(t=t, quat=quat, omega=omega, position=q[0:3].copy(), velocity=R @ v[0:3],
                      q_arm=q_arm, qd_arm=qd_arm, wheel_speed=v[sm.idx.wheels].copy(), q=q, v=v, eta=eta, etadot=etadot)

    def warm_call(self):
        """``measure_state``'s call in ``measure`` on throw-away data (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        q, v = self.sm.q0.astype(float).copy(), np.zeros(self.sm.nv)
        return KernelCall("sms_cli.sim.compiled.sensors:measure_state", (
            self.par, np.zeros(self.width), self.q_arm_idx, self.v_arm_idx, q, v, q.copy(), v.copy()), cost=0.4)


def _rot(quat: np.ndarray) -> np.ndarray:
    x, y, z, w = quat
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
