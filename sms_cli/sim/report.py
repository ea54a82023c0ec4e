"""Plain-text summary of a simulation (what ``sms simulate`` prints)."""

from __future__ import annotations


def _f(x, fmt: str = ".4g", unit: str = "") -> str:
    return "—" if x is None else f"{x:{fmt}}{unit}"


def _stop_line(p: dict) -> str:
    """Time on the joint stops and penetration beyond the URDF limits of a phase ('' when neither)."""
    t, pen = p.get("joint_stop_time_s") or 0.0, p.get("joint_stop_penetration_max") or 0.0
    if t <= 0 and pen <= 0:
        return ""
    per = ", ".join(f"{n} {x:.3g} s" for n, x in (p.get("joint_stop_time_per_joint_s") or {}).items() if x > 0)
    return (f"joints on a stop {t:.3g} s" + (f" ({per})" if per else "")
            + f"; max penetration beyond a limit {pen:.3g} rad or m")


def format_simulation(sec: dict) -> str:
    """Per-phase table and overall metrics (a two-spacecraft run: ``format_formation``)."""
    if "formation" in sec:
        return format_formation(sec)
    lines = [f"status {sec['status']}" + (f" ({sec['divergence']})" if sec.get("divergence") else "")
             + f"  t_end {sec['t_end_s']:.3f} s, {sec['steps']} plant steps"]
    tm = sec.get("timing", {})
    if tm:
        lines.append(f"timing {tm['wall_s']:.2f} s wall, {tm['us_per_step']:.1f} µs/step, "
                     f"{_f(tm.get('real_time_factor'), '.1f')}× real time")
    lines.append(f"{'phase':<22}{'kind':<13}{'dur [s]':>9}{'att err max':>13}{'final':>10}{'settle [s]':>11}"
                 f"{'joint err':>11}{'att τ pk':>10}{'wheel τ pk':>11}{'joint τ pk':>11}{'sat [s]':>9}")
    for p in sec["phases"]:
        a = p.get("attitude_error_deg", {})
        lines.append(f"{p['name'][:21]:<22}{p['kind']:<13}{p['duration_s']:>9.2f}{_f(a.get('max'), '.4g', '°'):>13}"
                     f"{_f(a.get('final'), '.3g', '°'):>10}{_f(p.get('settling_time_s'), '.1f'):>11}"
                     f"{_f(p.get('joint_error_max'), '.3g'):>11}{_f(p.get('attitude_torque_peak_Nm'), '.3g'):>10}"
                     f"{_f(p.get('wheel_torque_peak_Nm'), '.3g'):>11}"
                     f"{_f(p.get('joint_torque_peak'), '.3g'):>11}{_f(p.get('saturation_time_s'), '.1f'):>9}")
    for p in sec["phases"]:
        if p.get("base_reaction_torque_peak_Nm") is not None:
            lines.append(f"  {p['name']}: base held; reaction peaks {p['base_reaction_force_peak_N']:.4g} N, "
                         f"{p['base_reaction_torque_peak_Nm']:.4g} N m")
    for p in sec["phases"]:
        line = _stop_line(p)
        if line:
            lines.append(f"  {p['name']}: {line}")
    for p in sec["phases"]:
        j, w = p.get("joint_rate_error_rel_max"), p.get("wheel_rate_error_rel_max")
        if j is not None or w is not None:
            lines.append(f"  {p['name']}: rate tracking (Kraiem 2022 (3.67)) joints {_f(j, '.2e')}, wheels {_f(w, '.2e')}")
    for p in sec["phases"]:
        arm = (p.get("torque_split") or {}).get("arm")
        if arm:
            lines.append(f"  {p['name']}: arm command split (peak ratios) linearising/feedback "
                         f"{_f(arm['linearising_to_feedback'], '.2g')}, disturbance/linearising "
                         f"{_f(arm['disturbance_to_linearising'], '.2g')}")
    auto = [m for m in sec.get("moves") or [] if m.get("given_s") is None]
    if auto:
        lines.append("moves sized from the actuator authority: " + ", ".join(
            f"{m['phase']} #{m['segment']} {m['duration_s']:.0f} s (set by {m['limited_by']})" for m in auto))
    c = sec.get("conservation", {})
    if c:
        lines.append(f"momentum drift linear {_f(c.get('linear_momentum_drift_abs'), '.2e')} N s"
                     f" (rel {_f(c.get('linear_momentum_drift_rel'), '.2e')}), angular {_f(c.get('angular_momentum_drift_abs'), '.2e')} N m s"
                     f" (rel {_f(c.get('angular_momentum_drift_rel'), '.2e')}); energy change {_f(c.get('energy_change_J'), '.4g')} J")
    lines.append(f"recording {sec['files']['mcap']}")
    return "\n".join(lines)


def format_formation(sec: dict) -> str:
    """A two-spacecraft run: shape and locked motion, momentum, timing."""
    f, sh, lk, c, tm = sec["formation"], sec["shape"], sec["locked"], sec["conservation"], sec.get("timing", {})
    lines = [f"status {sec['status']}" + (f" ({sec['divergence']})" if sec.get("divergence") else "")
             + f"  t_end {sec['t_end_s']:.3f} s, {sec['steps']} plant steps; master {f['master']}, other {f['other']}",
             f"shape error   {sh['position_error_initial_m']:.4g} m, {sh['angle_error_initial_deg']:.3g}° -> "
             f"{sh['position_error_final_m']:.3g} m, {sh['angle_error_final_deg']:.3g}°"
             f"  (settled at {_f(sh.get('settling_time_s'), '.1f')} s)",
             f"locked rate   {lk['angular_rate_initial_rad_s']:.4g} -> {lk['angular_rate_final_rad_s']:.4g} rad/s",
             f"momentum drift between pushes: {c['linear_momentum_drift_between_pushes_Ns']:.3g} N s, "
             f"{c['angular_momentum_drift_between_pushes_Nms']:.3g} N m s"]
    cap = sec.get("capture")
    if cap and cap.get("engaged"):
        lines.append(f"capture at {cap['at_s']:.4g} s (offset {cap['offset_m']:.3g} m, {cap['offset_deg']:.3g}°): peak "
                     f"{cap['peak_force_N']:.3g} N, {cap['peak_torque_Nm']:.3g} N m; stack rate {cap['stack_rate_deg_s']:.3g}°/s; "
                     f"momentum change {cap['linear_momentum_change_rel']:.2g} / {cap['angular_momentum_change_rel']:.2g} "
                     "of the exchanged impulse")
    if tm:
        lines.append(f"timing {tm['wall_s']:.2f} s wall, {tm['us_per_step']:.1f} µs/step, "
                     f"{_f(tm.get('real_time_factor'), '.1f')}× real time")
    lines.append(f"files: {', '.join(str(v) for k, v in sec.get('files', {}).items() if k != 'plots')}")
    return "\n".join(lines)
