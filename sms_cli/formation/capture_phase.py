"""A mission's ``formation.capture`` inside the two-spacecraft loop: the interface frames added to the plant, the
plant step checked against the interface frequency before the run, the capture engaged at its time (the offset
checked, the gains frozen from the relative operational inertia), the interface wrenches at every plant stage,
and the capture metrics. The mechanics are in ``sms_cli.formation.capture``."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from sms_cli.formation import capture as C
from sms_cli.formation.plant import prefixed


class CaptureMissed(Exception):
    """At the capture time the two frames are further apart than the tolerance (the run stops; exit 3)."""


class CapturePhase:
    """The capture of ``spec`` (a ``CaptureSpec``) on ``plant``; ``locate(path)`` gives a mission Location."""

    def __init__(self, spec, plant, servicer: str, client: str, dt: float, locate):
        from sms_cli.model.build import frame_id

        self.spec = spec
        self.plant = plant
        bodies = {b.name: b for b in plant.bodies}
        s, c = bodies[servicer], bodies[client]
        here = ("formation", "capture")
        C.check_resolution(dt, float(spec.natural_frequency), locate(here + ("natural_frequency",)),
                           "formation.capture.natural_frequency")
        own_a = (s.ee_frame_id if spec.servicer_frame is None else
                 s.frames[s.system.model.frames[frame_id(s.system.model, spec.servicer_frame, "formation.capture.servicer_frame",
                                                         locate(here + ("servicer_frame",)))].name])
        own_b = c.frames[c.system.model.frames[frame_id(c.system.model, spec.client_frame, "formation.capture.client_frame",
                                                        locate(here + ("client_frame",)))].name]
        self.frame_a = plant.add_frame(prefixed("capture_interface", servicer), own_a, spec.servicer_offset.se3())
        self.frame_b = plant.add_frame(prefixed("capture_interface", client), own_b, spec.client_offset.se3())
        self.target = pin.SE3.Identity()  # joined: frame b on frame a
        self.gains = None
        self.monitor = C.CaptureMonitor(plant.model)
        self.data = plant.model.createData()
        self.t_capture = None

    def due(self, t: float) -> bool:
        return self.gains is None and t >= float(self.spec.at) - 1e-9

    def engage(self, t: float, q: np.ndarray, v: np.ndarray) -> None:
        """Check the offset (CaptureMissed) and freeze the gains K = ω²Λ_rel, D = 2ζωΛ_rel at the state (q, v)."""
        model, data = self.plant.model, self.data
        pin.framesForwardKinematics(model, data, q)
        g_a, g_b = data.oMf[self.frame_a].copy(), data.oMf[self.frame_b].copy()
        try:
            C.check_capture_offset(g_a, g_b, self.target, t, float(self.spec.tolerance_position),
                                   math.degrees(float(self.spec.tolerance_angle)))
        except Exception as exc:  # the NumericalError that says how far: the loop stops and keeps what ran
            raise CaptureMissed(str(exc)) from None
        lam = C.relative_operational_inertia(model, data, q, self.frame_a, self.frame_b)
        self.gains = C.InterfaceGains.from_frequency(lam, float(self.spec.natural_frequency), float(self.spec.damping_ratio))
        self.monitor.at_capture(data, t, q, v, self.frame_a, self.frame_b, self.target)
        self.t_capture = t

    def wrenches(self, q: np.ndarray, v: np.ndarray) -> list:
        """The interface wrench pair at (q, v) (none before the capture)."""
        if self.gains is None:
            return []
        return C.interface_wrenches(self.plant.model, self.data, q, v, self.frame_a, self.frame_b, self.target, self.gains)

    def sample(self, q: np.ndarray, v: np.ndarray, pair=None) -> None:
        """Update the monitor's peaks with the interface wrenches at (q, v), by the compiled ``pair``
        (``sms_cli.sim.compiled.pair.PairPlant``) when given, else with Pinocchio."""
        if self.gains is None:
            return
        if pair is None:
            self.monitor.sample(self.wrenches(q, v))
        else:
            self.monitor.sample(pair.capture_wrenches(q, v, (self.frame_a, self.frame_b, self.target, self.gains.K,
                                                             self.gains.D)))

    def metrics(self, q: np.ndarray, v: np.ndarray, t: np.ndarray, H2: np.ndarray) -> dict:
        """Peak interface force and torque, stack rate, momentum before and after (world frame), offset at t_c.
        ``t``, ``H2``: the sampled times and the other body's world momentum, whose largest change after t_c is the
        impulse the interface exchanged: the scale of the momentum changes (the pair's may start at zero)."""
        if self.gains is None:
            return {"engaged": False, "at_s": float(self.spec.at)}
        m = self.monitor.finish(self.data, q, v)
        before, after = m.momentum_before, m.momentum_after
        k = int(np.searchsorted(t, m.t_capture - 1e-9))
        dH2 = H2[k:] - H2[k]
        exchanged = float(np.max(np.linalg.norm(dH2[:, :3], axis=1))), float(np.max(np.linalg.norm(dH2[:, 3:], axis=1)))
        scale = (max(exchanged[0], float(np.linalg.norm(before[:3])), 1e-300),
                 max(exchanged[1], float(np.linalg.norm(before[3:])), 1e-300))
        return {
            "engaged": True, "at_s": m.t_capture, "offset_m": m.offset_m, "offset_deg": m.offset_deg,
            "natural_frequency_hz": float(self.spec.natural_frequency), "damping_ratio": float(self.spec.damping_ratio),
            "peak_force_N": m.peak_force_N, "peak_torque_Nm": m.peak_torque_Nm,
            "stack_rate_rad_s": m.stack_rate_base.tolist(), "stack_rate_deg_s": float(np.degrees(np.linalg.norm(m.stack_rate_base))),
            "momentum_before": before.tolist(), "momentum_after": after.tolist(),
            "linear_impulse_exchanged_Ns": exchanged[0], "angular_impulse_exchanged_Nms": exchanged[1],
            "linear_momentum_change_rel": float(np.linalg.norm(after[:3] - before[:3])) / scale[0],
            "angular_momentum_change_rel": float(np.linalg.norm(after[3:] - before[3:])) / scale[1],
        }
