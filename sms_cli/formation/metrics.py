"""Metrics of a two-spacecraft run (the ``simulate`` section of results.json): shape convergence, locked
motion, momentum between pushes, energy split, wheels, timing. Units SI, angles in degrees where named."""

from __future__ import annotations

import math

import numpy as np

RPM = 60 / (2 * math.pi)


def _settle_time(t: np.ndarray, inside: np.ndarray) -> float | None:
    """First time after which ``inside`` holds to the end of the run (None: it does not hold at the end)."""
    if inside.size == 0 or not inside[-1]:
        return None
    outside = np.flatnonzero(~inside)
    return float(t[0]) if outside.size == 0 else float(t[outside[-1] + 1])


def _quiet_windows(t: np.ndarray, pushes) -> list[tuple[int, int]]:
    """Index ranges [i0, i1] of the samples between pushes (no push acting anywhere inside)."""
    busy = np.zeros(t.size, bool)
    for p in pushes:
        busy |= (t > p.at - 1e-9) & (t < p.at + p.duration + 1e-9)
    windows, start = [], None
    for i, b in enumerate(busy):
        if not b and start is None:
            start = i
        if b and start is not None:
            windows.append((start, i - 1))
            start = None
    if start is not None:
        windows.append((start, t.size - 1))
    return [(a, b) for a, b in windows if b > a]


def _push_metrics(i: int, push, t: np.ndarray, H: np.ndarray) -> dict:
    """A push's momentum change (world frame, between the samples just before and just after it): the linear
    part's norm is the impulse |∫R f dt| (N s), |f| Δt when the base does not turn during the push."""
    before = int(np.searchsorted(t, push.at - 1e-9)) - 1
    after = int(np.searchsorted(t, push.at + push.duration - 1e-9))
    out = {"name": push.name or f"push{i + 1}", "body": push.body, "at_s": push.at, "duration_s": push.duration,
           "force_N": list(push.force), "momentum_change": None, "linear_impulse_Ns": None}
    if before >= 0 and after < t.size:
        dH = H[after] - H[before]
        out.update(momentum_change=dH.tolist(), linear_impulse_Ns=float(np.linalg.norm(dH[:3])))
    return out


def formation_metrics(trace: dict, spec, names: tuple[str, str], wall_s: float, steps: int, engine: str = "python") -> dict:
    """The run's metrics (see the module docstring); ``engine``: the plant step that ran (``timing.engine``)."""
    t = trace["t"]
    out: dict = {"master": names[0], "other": names[1], "law": spec.relative_law, "actuation": spec.actuation}
    pos = np.linalg.norm(trace["shape_position"], axis=1)
    ang = np.degrees(trace["shape_angle"])
    inside = (pos <= spec.settle_position) & (ang <= math.degrees(spec.settle_angle))
    out["shape"] = {
        "controlled": spec.shape.controlled,
        "position_error_initial_m": float(pos[0]), "position_error_final_m": float(pos[-1]),
        "position_error_final_xyz_m": trace["shape_position"][-1].tolist(),
        "angle_error_initial_deg": float(ang[0]), "angle_error_final_deg": float(ang[-1]),
        "settling_time_s": _settle_time(t, inside),
        "twist_final": trace["V_E"][-1].tolist(),
        "kinetic_energy_initial_J": float(trace["T_E"][0]), "kinetic_energy_final_J": float(trace["T_E"][-1]),
    }
    V_L = trace["V_L"]
    out["locked"] = {
        "controlled": spec.locked.controlled,
        "twist_initial": V_L[0].tolist(), "twist_final": V_L[-1].tolist(),
        "angular_rate_initial_rad_s": float(np.linalg.norm(V_L[0, 3:])),
        "angular_rate_final_rad_s": float(np.linalg.norm(V_L[-1, 3:])),
        "kinetic_energy_initial_J": float(trace["T_L"][0]), "kinetic_energy_final_J": float(trace["T_L"][-1]),
    }
    if spec.locked.controlled:
        lp = np.linalg.norm(trace["locked_position"], axis=1)
        out["locked"].update({"position_error_final_m": float(lp[-1]),
                              "angle_error_final_deg": float(np.degrees(trace["locked_angle"][-1]))})
    H = trace["H_world"]
    drift_p = drift_k = 0.0
    quiet = _quiet_windows(t, spec.pushes)
    for a, b in quiet:
        drift_p = max(drift_p, float(np.max(np.linalg.norm(H[a:b + 1, :3] - H[a, :3], axis=1))))
        drift_k = max(drift_k, float(np.max(np.linalg.norm(H[a:b + 1, 3:] - H[a, 3:], axis=1))))
    scale_p = max(float(np.max(np.linalg.norm(H[:, :3], axis=1))), 1e-300)
    scale_k = max(float(np.max(np.linalg.norm(H[:, 3:], axis=1))), 1e-300)
    out["conservation"] = {
        "linear_momentum_drift_between_pushes_Ns": drift_p, "angular_momentum_drift_between_pushes_Nms": drift_k,
        "linear_momentum_drift_between_pushes_rel": drift_p / scale_p,
        "angular_momentum_drift_between_pushes_rel": drift_k / scale_k,
        "momentum_initial": H[0].tolist(), "momentum_final": H[-1].tolist(),
    }
    out["pushes"] = [_push_metrics(i, p, t, H) for i, p in enumerate(spec.pushes)]
    W = trace["W"]
    rise = max((float(np.max(np.diff(W[a:b + 1]))) for a, b in quiet), default=0.0)
    out["energy"] = {"lyapunov_initial_J": float(W[0]), "lyapunov_final_J": float(W[-1]),
                     "lyapunov_final_over_initial": float(W[-1] / W[0]) if W[0] > 0 else None,
                     "lyapunov_max_rise_between_samples_J": max(rise, 0.0),
                     "kinetic_total_final_J": float(trace["T"][-1])}
    for i, name in enumerate(names):
        w = trace[f"wheels{i + 1}"]
        if w.shape[1]:
            out[f"wheels_{name}"] = {"speed_peak_rad_s": float(np.max(np.abs(w))), "speed_peak_rpm": float(np.max(np.abs(w)) * RPM)}
        if trace[f"propellant{i + 1}"][-1] > 0:
            F, D = trace[f"F{i + 1}"], trace[f"D{i + 1}"]
            out[f"thrusters_{name}"] = {"propellant_used_kg": float(trace[f"propellant{i + 1}"][-1]),
                                        "force_residual_peak_N": float(np.max(np.linalg.norm(F[:, :3] - D[:, :3], axis=1))),
                                        "torque_residual_peak_Nm": float(np.max(np.linalg.norm(F[:, 3:] - D[:, 3:], axis=1)))}
    dt_sample = float(t[1] - t[0]) if t.size > 1 else 0.0
    out["saturation_time_s"] = float(np.count_nonzero(trace["saturated"]) * dt_sample)
    out["timing"] = {"engine": engine, "steps": steps, "wall_s": wall_s, "us_per_step": 1e6 * wall_s / max(steps, 1),
                     "real_time_factor": float(t[-1]) / wall_s if wall_s > 0 else None}
    return out
