"""``sms compile``: the human (and JSON) summary of a compiled mission."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from sms_cli.dynamics.locked import format_locked, locked_summary
from sms_cli.mission.load import load_mission
from sms_cli.model.compiler import compile_system
from sms_cli.model.modal import coupled_frequencies
from sms_cli.model.system import SystemModel


def wheel_momentum_capacity(sm: SystemModel) -> dict[str, Any]:
    """Per-wheel momentum I_s·ω_max (N m s) and the array's capacity along each base axis:
    max over admissible wheel speeds of |Σ h_i a_i · e| = Σ I_s,i ω_max,i |a_i · e|."""
    per = {w.name: w.spin_inertia * w.max_speed for w in sm.wheels}
    axes = {}
    for k, label in enumerate("xyz"):
        axes[label] = float(sum(w.spin_inertia * w.max_speed * abs(w.axis[k]) for w in sm.wheels))
    return {"per_wheel_Nms": per, "along_base_axes_Nms": axes}


def model_summary(sm: SystemModel) -> dict[str, Any]:
    """Figures of the compiled model at its initial configuration (SI units, world frame)."""
    q = sm.q0
    pin.ccrba(sm.model, sm.data, q, np.zeros(sm.nv))
    inertia_com = sm.data.Ig.inertia.copy()
    coupled = coupled_frequencies(sm, q)
    return {
        "name": sm.name,
        "dof": {"base": 6, "wheels": len(sm.wheels), "arm": len(sm.arm), "passive": len(sm.springs),
                "modes": sm.n_modes, "total": sm.nx},
        "nq": sm.nq, "nv": sm.nv,
        "total_mass_kg": sm.total_mass,
        "com_world_m": sm.com(q),
        "inertia_about_com_world_kgm2": inertia_com,
        "end_effector": sm.model.frames[sm.ee_frame_id].name,
        "end_effector_position_world_m": sm.ee_pose(q).translation,
        "arm_joints": [{"name": a.name, "kind": a.kind, "lower": a.lower, "upper": a.upper,
                        "max_velocity": a.max_velocity, "max_effort": a.max_effort} for a in sm.arm],
        "wheels": [{"name": w.name, "axis_base": w.axis, "spin_inertia_kgm2": w.spin_inertia,
                    "max_torque_Nm": w.max_torque, "max_speed_rad_s": w.max_speed,
                    "initial_speed_rad_s": w.initial_speed} for w in sm.wheels],
        "wheel_momentum_capacity": wheel_momentum_capacity(sm),
        "locked": locked_summary(sm),  # locked inertia and Λ at q0 (sms_cli.dynamics.locked)
        "appendages": [{"name": a.name, "frame": sm.model.frames[a.frame_id].name,
                        "clamped_frequencies_hz": a.omega / (2 * math.pi), "damping": a.zeta} for a in sm.appendages],
        "springs": [{"joint": s.joint, "stiffness": s.stiffness, "damping": s.damping} for s in sm.springs],
        "coupled_frequencies_hz": coupled / (2 * math.pi),
        "payloads": [{"name": p.name, "frame": sm.model.frames[p.frame_id].name, "mass_kg": p.inertia_in_joint.mass,
                      "attached": p.attached} for p in sm.payloads.values()],
        "kinematics_only": sm.kinematics_only,
        "warnings": [w.render() for w in sm.warnings],
    }


def compile_summary(mission_path: Path, strict: bool = False) -> dict[str, Any]:
    """Load, compile and summarise a mission (plain JSON-ready data); ``strict`` refuses lint findings."""
    from sms_cli.results import _jsonable

    loaded = load_mission(mission_path)
    sm = compile_system(loaded, strict=strict)
    moves = None
    if loaded.mission.simulation is not None:
        from sms_cli.sim.stage import planned_simulation
        from sms_cli.sim.validate import validate_simulation

        validate_simulation(sm, loaded)
        moves = [p.as_dict() for p in planned_simulation(sm, loaded)[1]]
    out = model_summary(sm)
    out["mission_file"] = str(mission_path)
    if sm.thrusters is not None:
        from sms_cli.thrusters.capability import capability_report

        out["thrusters"] = capability_report(sm.thrusters)
    if loaded.mission.client is not None:
        from sms_cli.formation.stage import prepared
        from sms_cli.formation.summary import pair_summary

        _, client = prepared(loaded)
        out["client"] = model_summary(client)
        if client.thrusters is not None:
            from sms_cli.thrusters.capability import capability_report

            out["client"]["thrusters"] = capability_report(client.thrusters)
        out["pair"] = pair_summary(loaded, sm, client)
    if moves:
        out["moves"] = moves
        out["auto_duration"] = loaded.mission.simulation.auto_duration.model_dump()
    return _jsonable(out)


def _fmt_limit(x: float | None, unit: str = "") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return f"{x:.4g}{unit}"


def format_summary(s: dict[str, Any]) -> str:
    """Human-readable multi-line summary."""
    d = s["dof"]
    lines = [
        f"mission   {s['name']}  ({s['mission_file']})",
        f"DoF       base {d['base']} · wheels {d['wheels']} · arm {d['arm']} · passive {d['passive']} · modes {d['modes']}"
        f"  (total {d['total']}; nq={s['nq']}, nv={s['nv']})",
        f"mass      {s['total_mass_kg']:.4f} kg",
        "CoM       [" + ", ".join(f"{c:.4f}" for c in s["com_world_m"]) + "] m (world)",
        "inertia   about CoM, world axes (kg m^2):",
    ]
    for row in s["inertia_about_com_world_kgm2"]:
        lines.append("            [" + ", ".join(f"{x:12.4f}" for x in row) + "]")
    lines.append(f"end eff.  {s['end_effector']} at [" + ", ".join(f"{c:.4f}" for c in s["end_effector_position_world_m"]) + "] m")
    if s["arm_joints"]:
        lines.append("arm       name                 kind        lower      upper    v max    effort")
        for a in s["arm_joints"]:
            lines.append(f"          {a['name']:<20} {a['kind']:<10} {_fmt_limit(a['lower']):>9} {_fmt_limit(a['upper']):>9}"
                         f" {_fmt_limit(a['max_velocity']):>8} {_fmt_limit(a['max_effort']):>9}")
    if s["wheels"]:
        cap = s["wheel_momentum_capacity"]
        lines.append("wheels    name        axis (base frame)            I_spin     τ max     ω max (rpm)  h max (N m s)")
        for w in s["wheels"]:
            ax = "[" + ", ".join(f"{c:+.3f}" for c in w["axis_base"]) + "]"
            lines.append(f"          {w['name']:<10} {ax:<28} {w['spin_inertia_kgm2']:<10.4g} {w['max_torque_Nm']:<9.4g}"
                         f" {w['max_speed_rad_s'] * 60 / (2 * math.pi):<12.5g} {cap['per_wheel_Nms'][w['name']]:.4g}")
        ax = cap["along_base_axes_Nms"]
        lines.append(f"          momentum capacity along base x/y/z: {ax['x']:.4g} / {ax['y']:.4g} / {ax['z']:.4g} N m s")
        lines.extend(format_locked(s.get("locked")))
    for a in s["appendages"]:
        f = ", ".join(f"{x:.4g}" for x in a["clamped_frequencies_hz"])
        lines.append(f"modes     {a['name']} at {a['frame']}: clamped {f} Hz (ζ " + ", ".join(f"{z:.3g}" for z in a["damping"]) + ")")
    for sp in s["springs"]:
        lines.append(f"spring    {sp['joint']}: k = {sp['stiffness']:.4g}, c = {sp['damping']:.4g}")
    if s["coupled_frequencies_hz"]:
        lines.append("coupled   free-free elastic frequencies: " + ", ".join(f"{x:.4g}" for x in s["coupled_frequencies_hz"]) + " Hz")
    generated = re.compile(r"^tile_\d+(@.+)?$")  # the assembly's tile bodies (sms_cli.sim.assembly.tile_name)
    tiles = [p for p in s["payloads"] if generated.match(p["name"]) and p["name"].endswith("@store")]
    for p in s["payloads"]:
        if len(tiles) > 3 and generated.match(p["name"]) and p is not tiles[0]:
            continue  # the assembly's tile bodies (sms_cli.sim.assembly): one line for all of them
        if len(tiles) > 3 and p is tiles[0]:
            lines.append(f"payload   {len(tiles)} tiles of {p['mass_kg']:.4g} kg in the store ({tiles[0]['frame']} .. "
                         f"{tiles[-1]['frame']}), carried on the end effector and placed by the assembly tasks")
            continue
        lines.append(f"payload   {p['name']}: {p['mass_kg']:.4g} kg at {p['frame']} ({'attached' if p['attached'] else 'detached'} at t=0)")
    if s.get("moves"):
        from types import SimpleNamespace

        from sms_cli.sim.authority import format_moves

        lines.extend(format_moves(s["moves"], SimpleNamespace(**s["auto_duration"])))
    if s.get("thrusters"):
        from sms_cli.thrusters.capability import format_report

        lines.extend(format_report(s["thrusters"]))
    if s.get("kinematics_only"):
        lines.append("model     KINEMATICS ONLY: placeholder inertias on " + ", ".join(s["kinematics_only"])
                     + " (dynamics stages refuse it)")
    if s.get("pair"):
        from sms_cli.formation.summary import format_pair

        c = s["client"]
        lines.append(f"client    {c['name']}: mass {c['total_mass_kg']:.4f} kg, DoF base {c['dof']['base']} · wheels "
                     f"{c['dof']['wheels']} · arm {c['dof']['arm']}")
        lines.extend(format_pair(s["pair"]))
        if c.get("thrusters"):
            from sms_cli.thrusters.capability import format_report

            lines.extend("client " + line if i == 0 else line for i, line in enumerate(format_report(c["thrusters"])))
    if s["warnings"]:
        lines.append(f"warnings  {len(s['warnings'])}:")
        lines.extend("  - " + w.replace("\n", "\n    ") for w in s["warnings"])
    else:
        lines.append("warnings  none")
    return "\n".join(lines)
