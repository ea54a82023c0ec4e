"""Simulation metrics, per phase and overall (SI units; angles in rad, with deg copies)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Trace:
    """Samples at the controller rate (appended by the engine)."""

    t: list[float] = field(default_factory=list)
    phase: list[int] = field(default_factory=list)
    att_err: list[float] = field(default_factory=list)  # rad
    joint_err: list[np.ndarray] = field(default_factory=list)  # rad or m
    ee_err: list[float] = field(default_factory=list)  # m (nan when no EE target)
    wheel_speed: list[np.ndarray] = field(default_factory=list)
    wheel_torque: list[np.ndarray] = field(default_factory=list)
    joint_torque: list[np.ndarray] = field(default_factory=list)
    saturated: list[bool] = field(default_factory=list)
    modal_peak: list[float] = field(default_factory=list)
    momentum: list[np.ndarray] = field(default_factory=list)  # [p (3), k about origin (3)]
    energy: list[float] = field(default_factory=list)
    base_reaction: list[np.ndarray] = field(default_factory=list)  # [f; n] base frame, nan when the base is not held
    base_torque: list[np.ndarray] = field(default_factory=list)  # attitude-law torque on the base (N m, base frame)
    segment: list[int] = field(default_factory=list)  # bumps when a payload is attached/released or the base is held
    base_motion: list[np.ndarray] = field(default_factory=list)  # [base position; base-body momentum], world (base_motion.py)
    # Kraiem 2022 (3.67) rate tracking (when the model has an arm): desired and actual joint rates; the
    # desired wheel rates of the NDI law (its attitude hold: the rates that bring the base to ω_des)
    joint_rate_ref: list[np.ndarray] = field(default_factory=list)
    joint_rate: list[np.ndarray] = field(default_factory=list)
    wheel_rate_ref: list[np.ndarray] = field(default_factory=list)
    # the NDI law's command split (Kraiem 2022 Fig. 3.15, 4.28): [feedback; linearising; disturbance] × actuators
    # (wheels then arm), flattened row by row (ndi_law.torque_split)
    ndi_torque_split: list[np.ndarray] = field(default_factory=list)
    # joint stops, per arm joint: s spent on a stop during the tick [t, t + 1/control_rate), and the largest
    # penetration beyond the URDF range in that tick (rad or m; also without the stops: how far past)
    joint_stop_time: list[np.ndarray] = field(default_factory=list)
    joint_stop_penetration: list[np.ndarray] = field(default_factory=list)
    # real thrusters (sms_cli.thrusters): the tick's ideal wrench, its firing pattern's cycle average ([f; n],
    # base joint frame, N and N m), the pattern's total thrust (N) and the propellant used so far (kg)
    thruster_commanded: list[np.ndarray] = field(default_factory=list)
    thruster_delivered: list[np.ndarray] = field(default_factory=list)
    thrust_total: list[float] = field(default_factory=list)
    propellant_used: list[float] = field(default_factory=list)
    # momentum laws (sms_cli.sim.laws.momentum): locked velocity mu (rad/s, base frame) and the law's W (J)
    locked: list[np.ndarray] = field(default_factory=list)
    lyapunov: list[float] = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        def stack(x, width):
            return np.array(x) if x and np.size(x[0]) else np.zeros((len(self.t), width))
        return {
            "t": np.array(self.t), "phase": np.array(self.phase, dtype=int), "att_err": np.array(self.att_err),
            "joint_err": stack(self.joint_err, 0), "ee_err": np.array(self.ee_err),
            "wheel_speed": stack(self.wheel_speed, 0), "wheel_torque": stack(self.wheel_torque, 0),
            "joint_torque": stack(self.joint_torque, 0), "saturated": np.array(self.saturated, dtype=bool),
            "modal_peak": np.array(self.modal_peak), "momentum": np.array(self.momentum), "energy": np.array(self.energy),
            "base_reaction": np.array(self.base_reaction) if self.base_reaction else np.zeros((len(self.t), 6)),
            "segment": np.array(self.segment, dtype=int),
            "base_torque": np.array(self.base_torque) if self.base_torque else np.zeros((len(self.t), 3)),
            **({"base_motion": np.array(self.base_motion)} if self.t and len(self.base_motion) == len(self.t) else {}),
            **{k: np.array(getattr(self, k)) for k in ("joint_rate_ref", "joint_rate", "wheel_rate_ref", "ndi_torque_split", "thruster_commanded",
                                                        "thruster_delivered", "thrust_total", "propellant_used",
                                                        "locked", "lyapunov")
               if len(getattr(self, k)) == len(self.t) and self.t},
            "joint_stop_time": stack(self.joint_stop_time, 0), "joint_stop_penetration": stack(self.joint_stop_penetration, 0),
        }


def relative_rate_error(ref: np.ndarray, actual: np.ndarray) -> float | None:
    """Kraiem 2022 (3.67): max over actuators and samples of |q̇_d,i − q̇_i| / max_t |q̇_d,i| (samples × actuators),
    actuators whose reference never moves (max |q̇_d,i| ≤ 1e-9) left out; None when none moves."""
    if ref.size == 0:
        return None
    scale = np.max(np.abs(ref), axis=0)
    moving = scale > 1e-9
    if not np.any(moving):
        return None
    return float(np.max(np.abs(ref[:, moving] - actual[:, moving]) / scale[moving]))


def settling_time(t: np.ndarray, err: np.ndarray, band: float) -> float | None:
    """First time after which |err| stays within band until the end (None if it never settles)."""
    outside = np.nonzero(np.abs(err) > band)[0]
    if outside.size == 0:
        return float(t[0]) if t.size else None
    last = outside[-1]
    if last == err.size - 1:
        return None
    return float(t[last + 1])


def _stats(x: np.ndarray) -> dict[str, float]:
    if x.size == 0 or np.all(np.isnan(x)):
        return {"max": None, "rms": None, "final": None}
    return {"max": float(np.nanmax(np.abs(x))), "rms": float(math.sqrt(np.nanmean(x**2))), "final": float(x[~np.isnan(x)][-1])}


def summarize(a: dict[str, np.ndarray], mask: np.ndarray, band: float, dt_control: float,
              arm_names: list[str] | None = None) -> dict:
    """Metrics of the samples selected by mask (``arm_names``: the arm joints, to name per-joint metrics)."""
    t = a["t"][mask]
    out: dict = {"start_s": float(t[0]) if t.size else None, "end_s": float(t[-1]) if t.size else None}
    att = _stats(a["att_err"][mask])
    out["attitude_error_rad"] = att
    out["attitude_error_deg"] = {k: (None if v is None else math.degrees(v)) for k, v in att.items()}
    st = settling_time(t, a["att_err"][mask], band) if t.size else None
    out["settling_time_s"] = None if st is None else st - float(t[0])
    je = a["joint_err"][mask]
    out["joint_error_max"] = float(np.max(np.abs(je))) if je.size else None
    out["joint_error_rms"] = float(np.sqrt(np.mean(je**2))) if je.size else None
    out["end_effector_error_m"] = _stats(a["ee_err"][mask])
    for key, label in (("wheel_torque", "wheel_torque_peak_Nm"), ("wheel_speed", "wheel_speed_peak_rad_s"),
                       ("joint_torque", "joint_torque_peak")):
        x = a[key][mask]
        out[label] = float(np.max(np.abs(x))) if x.size else None
    bt = a["base_torque"][mask]
    out["attitude_torque_peak_Nm"] = float(np.max(np.abs(bt))) if bt.size else None
    out["saturation_time_s"] = float(np.count_nonzero(a["saturated"][mask]) * dt_control)
    sat = a["saturated"][mask]  # the saturated run from the first tick (Caldera 2019: "maximum torque at the beginning")
    out["saturated_from_start_s"] = float((np.argmin(sat) if not sat.all() else sat.size) * dt_control)
    br = a["base_reaction"][mask]
    if br.size and np.any(np.isfinite(br)):
        out["base_reaction_force_peak_N"] = float(np.nanmax(np.linalg.norm(br[:, :3], axis=1)))
        out["base_reaction_torque_peak_Nm"] = float(np.nanmax(np.linalg.norm(br[:, 3:], axis=1)))
    if "joint_rate_ref" in a:
        out["joint_rate_error_rel_max"] = relative_rate_error(a["joint_rate_ref"][mask], a["joint_rate"][mask])
    if "wheel_rate_ref" in a:  # a tracking measure of the arm's motion: none where the arm does not move
        out["wheel_rate_error_rel_max"] = (relative_rate_error(a["wheel_rate_ref"][mask], a["wheel_speed"][mask])
                                           if out.get("joint_rate_error_rel_max") is not None else None)
    if "base_motion" in a:  # free-floating runs of an arm: base displacement and the arm's reaction force
        from sms_cli.sim.base_motion import base_motion_metrics

        out.update(base_motion_metrics(a["t"], a["base_motion"], mask))
    mp = a["modal_peak"][mask]
    out["modal_amplitude_peak"] = float(np.max(mp)) if mp.size else None
    out.update(joint_stop_metrics(a, mask, arm_names))
    if "ndi_torque_split" in a:
        out["torque_split"] = torque_split_metrics(a["ndi_torque_split"][mask], a["wheel_speed"].shape[1])
    return out


def torque_split_metrics(split: np.ndarray, n_wheels: int) -> dict | None:
    """Kraiem 2022's torque decomposition (Fig. 3.15, 4.28) of the NDI command over samples × [feedback; linearising;
    disturbance] × actuators (wheels then arm; ``ndi_law.torque_split``): per group (wheels, arm), each actuator's peak
    |part| (N m, or N for a prismatic joint) and the median over the group's actuators of the peak ratios
    linearising/feedback and disturbance/linearising. An actuator whose denominator peak is below 1e-6 of the group's
    largest feedback peak is left out: there the denominator is round-off (a wheel on the base has no linearising
    torque about its axis, computed ~1e-12 N m; the flagship's arm at rest after the release, 4e-14 to 5e-13 N m against
    feedback peaks up to 1.2e-5), and the ratio, 1e6 or more, differs between the two loops at 1e-9 (5298287.3397 against
    5298287.3453 in CI); None when all are.
    None where the law never ran."""
    if split.size == 0 or not np.any(split):
        return None
    na = split.shape[1] // 3
    peaks = np.max(np.abs(split.reshape(split.shape[0], 3, na)), axis=0)  # (3, na)

    def ratio(num, den, scale):
        ok = den > 1e-6 * scale
        return float(np.median(num[ok] / den[ok])) if np.any(ok) else None

    out = {}
    for group, cols in (("wheels", slice(0, n_wheels)), ("arm", slice(n_wheels, na))):
        fb, lin, dist = peaks[0, cols], peaks[1, cols], peaks[2, cols]
        if fb.size == 0:
            continue
        out[group] = {"feedback_peak": fb.tolist(), "linearising_peak": lin.tolist(), "disturbance_peak": dist.tolist(),
                      "linearising_to_feedback": ratio(lin, fb, fb.max()),
                      "disturbance_to_linearising": ratio(dist, lin, fb.max())}
    return out


def joint_stop_metrics(a: dict[str, np.ndarray], mask: np.ndarray, arm_names: list[str] | None = None) -> dict:
    """Time on the joint stops (s, summed over the joints; per arm joint, by name) and the largest
    penetration beyond a URDF limit (rad or m) of the samples selected by mask."""
    st, pen = a["joint_stop_time"][mask], a["joint_stop_penetration"][mask]
    per_joint = np.sum(st, axis=0)
    names = arm_names if arm_names is not None else [str(i) for i in range(per_joint.size)]
    return {"joint_stop_time_s": float(np.sum(st)),
            "joint_stop_time_per_joint_s": {n: float(x) for n, x in zip(names, per_joint)},
            "joint_stop_penetration_max": float(np.max(pen)) if pen.size else 0.0}


def conservation(a: dict[str, np.ndarray], wheel_spin_inertia: np.ndarray | None = None) -> dict:
    """Drift of world momentum (linear; angular about the world origin) and energy change over the run.

    Relative drifts divide by the momentum at t = 0, or, when the system starts at rest, by the
    largest momentum the wheels exchanged with the base (Σ I_s |ω_w|): the internal momentum scale."""
    h = a["momentum"]
    if h.size == 0:
        return {}
    # momentum is only conserved between events that exchange it with the outside (payload
    # attached/released, base held by a support): drift is measured within each such segment
    seg = a["segment"] if a["segment"].size == len(h) else np.zeros(len(h), dtype=int)
    held = np.all(np.isfinite(a["base_reaction"]), axis=1) if a["base_reaction"].size else np.zeros(len(h), dtype=bool)
    dh = np.zeros(6)
    for k in np.unique(seg):
        in_seg = (seg == k) & ~held  # a held base exchanges momentum with its support
        if not np.any(in_seg):
            continue
        hk = h[in_seg]
        dh = np.maximum(dh, np.max(np.abs(hk - hk[0]), axis=0))
    p0, k0 = float(np.linalg.norm(h[0, :3])), float(np.linalg.norm(h[0, 3:]))
    k_int = float(np.max(np.abs(a["wheel_speed"]) @ wheel_spin_inertia)) if (
        wheel_spin_inertia is not None and wheel_spin_inertia.size and a["wheel_speed"].size) else 0.0
    scale_k = max(k0, k_int)
    e = a["energy"]
    return {
        "linear_momentum_drift_abs": float(np.max(dh[:3])), "angular_momentum_drift_abs": float(np.max(dh[3:])),
        "linear_momentum_drift_rel": float(np.max(dh[:3]) / p0) if p0 > 1e-12 else None,
        "angular_momentum_drift_rel": float(np.max(dh[3:]) / scale_k) if scale_k > 1e-12 else None,
        "energy_change_J": float(e[-1] - e[0]) if e.size else None,
    }
