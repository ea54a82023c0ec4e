"""Phase references: attitude (step or quintic eigen-axis slew) and joint waypoints (quintic)."""

from __future__ import annotations

import numpy as np

from sms_cli.model.conventions import euler_zyx_to_matrix, quaternion_xyzw_from_matrix
from sms_cli.sim.attitude_math import quat_log, quat_mul, quat_conj
from sms_cli.sim.interfaces import ArmRef, AttitudeRef


def quintic(s: float) -> tuple[float, float, float]:
    """Rest-to-rest quintic blend on s ∈ [0, 1]: (p, dp/ds, d²p/ds²)."""
    s = min(max(s, 0.0), 1.0)
    return (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4, 60 * s - 180 * s**2 + 120 * s**3)


class AttitudeProfile:
    """Attitude reference of a phase, starting from the previous reference ``q_start``; evaluated by the
    compiled loop's kernel (``sms_cli.sim.compiled.profiles.attitude_reference``) from ``params``."""

    def __init__(self, q_start: np.ndarray, rpy_target, profile: str, slew_time: float | None):
        self.q_start = q_start
        if rpy_target is None:
            self.q_target, self.rotvec, self.T = q_start, np.zeros(3), None
        else:
            self.q_target = quaternion_xyzw_from_matrix(euler_zyx_to_matrix(*rpy_target))
            self.rotvec = quat_log(quat_mul(quat_conj(q_start), self.q_target))  # body-frame eigen-axis rotation
            self.T = slew_time if profile == "smooth" else None
        self.params = np.ascontiguousarray(np.concatenate([np.asarray(q_start, float), self.rotvec,
                                                           [0.0 if self.T is None else float(self.T)],
                                                           np.asarray(self.q_target, float)]), dtype=float)

    def at(self, tau: float) -> AttitudeRef:
        """Reference at time tau from the phase start."""
        from sms_cli.sim.compiled.profiles import attitude_reference

        if self.T is None:
            return AttitudeRef(self.q_target)
        q, w, wd = np.empty(4), np.empty(3), np.empty(3)
        attitude_reference(self.params, float(tau), q, w, wd)
        return AttitudeRef(q, w, wd)


class JointProfile:
    """Joint reference through waypoints (quintic rest-to-rest segments), from ``q_start``."""

    def __init__(self, q_start: np.ndarray, names: list[str], waypoints, profile: str = "quintic"):
        self.step = profile == "step"
        self.times = [0.0]
        self.points = [np.array(q_start, float)]
        for w in waypoints:
            nxt = self.points[-1].copy()
            for name, value in w.joints.items():
                nxt[names.index(name)] = value
            self.times.append(w.at)
            self.points.append(nxt)

    @property
    def final(self) -> np.ndarray:
        return self.points[-1]

    @property
    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(times (m+1,), points (m+1, n)) as ``sms_cli.sim.compiled.arm_laws.joint_reference`` takes them."""
        if getattr(self, "_arrays", None) is None:
            n = self.points[0].size
            self._arrays = (np.array(self.times, float),
                            np.ascontiguousarray(np.reshape(self.points, (len(self.points), n)), dtype=float))
        return self._arrays

    def at(self, tau: float) -> ArmRef:
        """The reference at time tau from the phase start (the compiled loop's kernel, ``joint_reference``)."""
        from sms_cli.sim.compiled.arm_laws import joint_reference

        times, points = self.arrays
        n = points.shape[1]
        q, qd, qdd = np.empty(n), np.empty(n), np.empty(n)
        joint_reference(times, points, self.step, float(tau), q, qd, qdd)
        return ArmRef(q, qd, qdd)
