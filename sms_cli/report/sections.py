"""One builder per results.json section → a report :class:`Section` (only when its data exist)."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from sms_cli.report.model import Figure, Section, Table, figure_from_file, fmt, png_uri

INDEX_LABELS = {
    "K_m": ("K^m_ω0: joint share of the base attitude disturbance", "—"),
    "K_r": ("K^r_ω0: wheel share", "—"),
    "mu_fixed": ("manipulability, fixed base", "—"),
    "fixed_cond": ("σmin/σmax of the fixed-base Jacobian", "—"),
    "mu_gjm": ("manipulability of the generalized Jacobian (free floating)", "—"),
    "gjm_cond": ("σmin/σmax of the generalized Jacobian", "—"),
    "singular": ("singular configuration (fraction = mean)", "—"),
    "mu_ratio": ("μ free floating / μ fixed base", "—"),
    "mu_dyn": ("dynamic manipulability μ*", "—"),
    "mu_scal_lin": ("μ(ṙ_EE), base free", "—"),
    "mu_null_lin": ("null-motion μ^N(ṙ_EE), fixed attitude", "—"),
    "mu_null_ang": ("null-motion μ^N(ω_EE)", "—"),
    "mu_scal_lin_norm": ("μ(ṙ_EE) normalised", "—"),
    "mu_null_lin_norm": ("μ^N(ṙ_EE) normalised", "—"),
    "joint_limit_margin": ("joint-limit margin", "—"),
    "h_arm_max": ("arm momentum at max joint speed", "N m s"),
    "h_ratio": ("arm momentum / wheel capacity", "—"),
}
_WORKSPACE = ("ee_x", "ee_y", "ee_z")


def _num_cols(headers: list[str], first_text: int = 1) -> list[bool]:
    return [i >= first_text for i in range(len(headers))]


def _pngs(tree: Any) -> list[str]:
    """Every '*.png' file name mentioned in a section, in order, without repeats."""
    found: list[str] = []

    def walk(x: Any) -> None:
        if isinstance(x, dict):
            for v in x.values():
                walk(v)
        elif isinstance(x, list):
            for v in x:
                walk(v)
        elif isinstance(x, str) and x.lower().endswith(".png") and x not in found:
            found.append(x)

    walk(tree)
    return found


def _caption_from_name(name: str) -> str:
    return re.sub(r"[_-]+", " ", Path(name).stem).strip().capitalize()


# ----------------------------------------------------------------- model


def model_section(c: dict[str, Any], folder: Path, robot_png: bytes | None) -> Section:
    s = Section("model", "Mission and model")
    d = c.get("dof", {})
    com = c.get("com_world_m") or [None] * 3
    inertia = c.get("inertia_about_com_world_kgm2") or [[None] * 3] * 3
    rows = [
        ["degrees of freedom", f"{d.get('total')} = base {d.get('base')} + wheels {d.get('wheels')} + arm {d.get('arm')}"
                               f" + passive {d.get('passive')} + modes {d.get('modes')}"],
        ["total mass", f"{fmt(c.get('total_mass_kg'))} kg"],
        ["centre of mass (world)", "[" + ", ".join(fmt(x) for x in com) + "] m"],
        ["inertia about CoM (diag, world)", "[" + ", ".join(fmt(inertia[i][i]) for i in range(3)) + "] kg m²"],
        ["end effector", f"{c.get('end_effector')} at [" + ", ".join(fmt(x) for x in c.get("end_effector_position_world_m") or []) + "] m"],
    ]
    cap = c.get("wheel_momentum_capacity", {}).get("along_base_axes_Nms")
    if cap:
        rows.append(["wheel momentum capacity (x, y, z)", ", ".join(fmt(cap[k]) for k in ("x", "y", "z")) + " N m s"])
    if c.get("coupled_frequencies_hz"):
        rows.append(["coupled modal frequencies", ", ".join(fmt(f) for f in c["coupled_frequencies_hz"][:12]) + " Hz"])
    s.add(Table("Model at the initial configuration (world frame, SI)", ["quantity", "value"], rows))
    if robot_png:
        s.add(Figure(f"{c.get('name', '')}: the robot in its initial configuration (URDF primitives, link frames, "
                     "end effector ★, base triad, wheel spin axes).", png_uri(robot_png), "robot drawing"))
    if c.get("arm_joints"):
        h = ["joint", "kind", "lower", "upper", "max velocity", "max effort"]
        s.add(Table("Arm joints (rad or m; rad/s or m/s; N m or N)", h,
                    [[a["name"], a["kind"], fmt(a["lower"]), fmt(a["upper"]), fmt(a["max_velocity"]), fmt(a["max_effort"])]
                     for a in c["arm_joints"]], _num_cols(h, 2)))
    if c.get("wheels"):
        h = ["wheel", "axis (base frame)", "spin inertia [kg m²]", "max torque [N m]", "max speed [rpm]", "initial [rpm]"]
        rpm = 60 / (2 * math.pi)
        s.add(Table("Reaction wheels", h, [[w["name"], "[" + ", ".join(f"{a:.3f}" for a in w["axis_base"]) + "]",
                                              fmt(w["spin_inertia_kgm2"]), fmt(w["max_torque_Nm"]),
                                              fmt(w["max_speed_rad_s"] * rpm if w["max_speed_rad_s"] is not None else None),
                                              fmt((w.get("initial_speed_rad_s") or 0.0) * rpm)] for w in c["wheels"]],
                    _num_cols(h, 2)))
    if c.get("appendages"):
        h = ["appendage", "junction frame", "clamped frequencies [Hz]", "damping ratios"]
        s.add(Table("Flexible appendages (hybrid coordinates)", h,
                    [[a["name"], a["frame"], ", ".join(fmt(f) for f in a["clamped_frequencies_hz"]),
                      ", ".join(fmt(z) for z in a["damping"])] for a in c["appendages"]]))
    if c.get("payloads"):
        h = ["payload", "frame", "mass [kg]", "attached at start"]
        s.add(Table("Payloads", h, [[p["name"], p["frame"], fmt(p["mass_kg"]), fmt(p["attached"])] for p in c["payloads"]]))
    s.notes.extend(f"warning: {w}" for w in c.get("warnings", []))
    return s


# ----------------------------------------------------------------- budget


def budget_section(b: dict[str, Any], folder: Path) -> Section:
    s = Section("budget", "ΔV and propellant budget")
    for sc in b.get("scenarios", []):
        h = ["#", "phase", "step", "propulsion", "ΔV [m/s]", "propellant [kg]", "mass after [kg]", "burn [s]",
             "wait [d]", "orbit after"]
        rows = [[str(st["index"]), st["phase"], st["name"], st["propulsion"] or "—", fmt(st["dv_m_s"]),
                 fmt(st["propellant_kg"]), fmt(st["mass_after_kg"], 6), fmt(st["burn_duration_s"]),
                 "TBD" if st["coast_duration_s"] is None else fmt(st["coast_duration_s"] / 86400.0),
                 st["orbit_after_text"]] for st in sc["steps"]]
        t = sc["totals"]
        rows.append(["", "total", "", "", fmt(t["dv_m_s"], 6), fmt(t["propellant_kg"], 6), "", fmt(t["burn_duration_s"]),
                     fmt(t["coast_duration_s"] / 86400.0) + (" + TBD" if t.get("duration_tbd_steps") else ""), ""])
        num = [True, False, False, False, True, True, True, True, True, False]
        s.add(Table(f"{sc['name']}: manoeuvre sequence from {sc['initial_orbit_text']} (ΔV with margins)", h, rows, num,
                    [""] * (len(rows) - 1) + ["total"]))
        m = sc["mass"]
        req = m.get("required_wet_mass_kg")
        s.add(Table(f"{sc['name']}: mass closure", ["quantity", "value"], [
            ["wet mass", f"{fmt(m['wet_mass_kg'], 6)} kg ({m['wet_mass_source']})"],
            ["dry mass", f"{fmt(m['dry_mass_kg'], 6)} kg"],
            ["final mass", f"{fmt(m['final_mass_kg'], 6)} kg"],
            ["residual propellant", f"{fmt(m['residual_propellant_kg'], 6)} kg "
                                    f"(reserve required {fmt(m['reserve_required_kg'])} kg = {m['propellant_margin']:.0%})"],
            ["smallest closing wet mass", "diverges" if req is None else f"{fmt(req, 6)} kg"],
            ["budget closes", "YES" if m["closes"] else "NO"],
        ], row_classes=[""] * 5 + ["pass" if m["closes"] else "fail"]))
        if sc.get("by_propulsion"):
            h2 = ["propulsion", "ΔV [m/s]", "propellant [kg]", "burn time [s]", "burn time [d]"]
            s.add(Table(f"{sc['name']}: per propulsion system", h2,
                        [[n, fmt(d["dv_m_s"]), fmt(d["propellant_kg"]), fmt(d["burn_duration_s"]),
                          fmt(d["burn_duration_s"] / 86400.0)] for n, d in sc["by_propulsion"].items()], _num_cols(h2)))
        s.notes.extend(f"{sc['name']}: {w}" for w in sc.get("warnings", []))
    captions = {"budget_mass.png": "Mass along the mission (total with captured targets, chaser; dotted: dry mass).",
                "budget_dv.png": "ΔV per phase (with margins)."}
    for name in _pngs(b.get("artifacts", [])):
        s.add(figure_from_file(folder, name, captions.get(name, _caption_from_name(name))))
    return s


# ----------------------------------------------------------------- analysis


def analysis_section(a: dict[str, Any], folder: Path) -> Section:
    s = Section("analysis", "Workspace and kinematic indices")
    s.intro = (f"{a.get('samples', 0):,} configurations ({a.get('method')}, n = {a.get('n')}) of the arm joints "
               + ", ".join(f"{j['name']} ∈ [{fmt(j['lower'])}, {fmt(j['upper'])}]" for j in a.get("joints", []))
               + f"; task rows: {a.get('task')}.")
    stats = ["min", "p05", "p50", "p95", "max", "mean"]
    for vname, v in a.get("variants", {}).items():
        idx = v.get("indices", {})
        h = ["index", "unit"] + stats + ["NaN"]
        rows = []
        for key, d in idx.items():
            if key.startswith("ee_"):
                continue
            label, unit = INDEX_LABELS.get(key, (key, "—"))
            rows.append([f"{label} ({key})", unit] + [fmt(d.get(k)) for k in stats] + [fmt(d.get("nan"))])
        s.add(Table(f"Variant '{vname}': index statistics over the sampled workspace", h, rows, _num_cols(h, 2)))
        ws = [[k[-1], fmt(idx[k]["min"]), fmt(idx[k]["max"])] for k in _WORKSPACE if k in idx]
        if ws:
            s.add(Table(f"Variant '{vname}': end-effector reach (satellite frame)",
                        ["axis", "min [m]", "max [m]"], ws, _num_cols(["a", "b", "c"])))
    for vname, comp in a.get("comparison", {}).items():
        rows = []
        for key, c in comp.items():
            if isinstance(c, dict):
                rows.append([key] + [fmt(c.get(k)) for k in ("fraction_lower", "min_change", "max_change")])
        if rows:
            h = ["index", "fraction of samples lower", "min change", "max change"]
            s.add(Table(f"Variant '{vname}' against the nominal design", h, rows, _num_cols(h)))
    for i, m in enumerate(a.get("modal", []) or []):
        conf = ", ".join(f"{k} = {fmt(v)}" for k, v in m.get("configuration", {}).items()) or "initial configuration"
        h = ["mode", "frequency [Hz]", "frequency [rad/s]", "damping ratio", "dominant coordinate"]
        s.add(Table(f"Coupled modes at {conf} ({m.get('joints')} joints, {m.get('states')} states)", h,
                    [[str(k + 1), fmt(x["frequency_hz"]), fmt(x["frequency_rad_s"]), fmt(x["damping"]), x.get("dominant", "")]
                     for k, x in enumerate(m.get("modes", []))], [True, True, True, True, False]))
    for name in _pngs(a.get("artifacts", [])):
        stem = Path(name).stem
        cap = _caption_from_name(name)
        for key, (label, _) in sorted(INDEX_LABELS.items(), key=lambda kv: -len(kv[0])):
            if stem.endswith("_" + key):
                variant = stem[len("analysis_"):-len(key) - 1]
                cap = (f"{label} per variant (shared colour scale)." if variant == "compare"
                       else f"Variant '{variant}': {label} at each sampled end-effector position (satellite frame, m).")
                break
        else:
            if stem.endswith("_hist"):
                cap = f"Variant '{stem[len('analysis_'):-5]}': histograms of the indices over the workspace."
            elif stem.endswith("_slices"):
                cap = f"Variant '{stem[len('analysis_'):-7]}': index maps on joint-space slices."
        s.add(figure_from_file(folder, name, cap))
    return s


# ----------------------------------------------------------------- synthesis


def _flat_scalars(tree: Any, prefix: str = "", depth: int = 0, limit: int = 60) -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    if isinstance(tree, dict):
        for k, v in tree.items():
            if k in ("timing", "artifacts", "files", "plots"):
                continue
            out += _flat_scalars(v, f"{prefix}.{k}" if prefix else str(k), depth + 1, limit)
    elif isinstance(tree, (bool, int, float, str)) and not (isinstance(tree, str) and tree.endswith((".png", ".yaml"))):
        out.append((prefix, tree))
    return out[:limit]


def synthesis_section(sy: dict[str, Any], folder: Path) -> Section:
    s = Section("synthesis", "Gains and closed-loop poles")
    gains_file = folder / "gains.yaml"
    if gains_file.is_file():
        import yaml

        try:
            g = yaml.safe_load(gains_file.read_text(encoding="utf-8")) or {}
        except (yaml.YAMLError, UnicodeDecodeError):
            g = None
        if not isinstance(g, dict):
            g = {}
            s.notes.append(f"{gains_file} could not be read (damaged), so the gain tables are left out")
        s.intro = f"law: {g.get('law', sy.get('law', '?'))}" + (f", variant {g['variant']}" if g.get("variant") else "")
        ctl = g.get("controller")
        acts = g.get("actuators", [])
        if ctl and acts:
            unit = ("1/s², 1/s" if ctl.get("units") == "acceleration" else "N m/rad, N m s/rad")
            h = ["actuator", "kp", "kv"]
            s.add(Table(f"Controller gains ({ctl.get('units')} form: {unit})", h,
                        [[n, fmt(p), fmt(v)] for n, p, v in zip(acts, ctl.get("kp", []), ctl.get("kv", []))], _num_cols(h)))
        smc = g.get("smc")
        if smc:
            h = ["axis", "slope λ [1/s]", "c [rad/s²]", "μ [s/rad]", "disturbance bound [N m]"]
            s.add(Table("Sliding-mode gains", h, [[ax, fmt(a), fmt(b), fmt(c), fmt(d)] for ax, a, b, c, d in zip(
                smc.get("axes", []), smc.get("slope", []), smc.get("c", []), smc.get("mu", []), smc.get("disturbance_bound", []))],
                _num_cols(h)))
        obs = g.get("observer")
        if obs and obs.get("L"):
            h = ["state"] + [str(o) for o in obs.get("outputs", [])]
            s.add(Table("Observer gain L (states × outputs)", h,
                        [[st] + [fmt(x) for x in row] for st, row in zip(obs.get("states", []), obs["L"])], _num_cols(h)))
        ver = g.get("verification") or sy.get("verification") or {}
        checks = ver.get("checks") if isinstance(ver, dict) else None
        if checks and isinstance(checks, list) and all(isinstance(c, dict) for c in checks):
            keys = [k for k in checks[0] if k not in ("details",)][:5]
            s.add(Table("Verification of the gains", keys, [[fmt(c.get(k)) for k in keys] for c in checks],
                        row_classes=["pass" if c.get("passed", True) else "fail" for c in checks]))
    scalars = _flat_scalars(sy)
    if scalars:
        s.add(Table("Synthesis figures (results.json)", ["quantity", "value"], [[k, fmt(v)] for k, v in scalars]))
    for name in _pngs(sy):
        s.add(figure_from_file(folder, name, _caption_from_name(name) + " (closed-loop poles and the requested region)"
                               if "pole" in name else _caption_from_name(name)))
    return s


# ----------------------------------------------------------------- simulation

_SIM_LABELS = [
    ("attitude_error_deg.max", "attitude error, max", "deg"), ("attitude_error_deg.rms", "attitude error, RMS", "deg"),
    ("attitude_error_deg.final", "attitude error, final", "deg"), ("settling_time_s", "settling time", "s"),
    ("joint_error_max", "joint tracking error, max", "rad or m"), ("joint_error_rms", "joint tracking error, RMS", "rad or m"),
    ("end_effector_error_m.max", "end-effector error, max", "m"), ("end_effector_error_m.final", "end-effector error, final", "m"),
    ("wheel_torque_peak_Nm", "wheel torque, peak", "N m"), ("wheel_speed_peak_rad_s", "wheel speed, peak", "rpm"),
    ("joint_torque_peak", "joint torque, peak", "N m or N"), ("saturation_time_s", "time in saturation", "s"),
    ("modal_amplitude_peak", "modal amplitude, peak", "√kg m"),
]


def _get(d: dict, dotted: str) -> Any:
    for k in dotted.split("."):
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def simulation_section(sim: dict[str, Any], folder: Path, wheels: list[dict], extra: list[Figure]) -> Section:
    s = Section("simulation", "Nonlinear simulation")
    s.intro = (f"status: {sim.get('status')}; {fmt(sim.get('t_end_s'))} s simulated in {fmt(sim.get('steps'))} steps"
               + (f"; diverged: {sim['divergence']}" if sim.get("divergence") else ""))
    overall = sim.get("overall", {})
    rows = []
    for key, label, unit in _SIM_LABELS:
        v = _get(overall, key)
        if v is None:
            continue
        if unit == "rpm":
            v = v * 60 / (2 * math.pi)
        rows.append([label, fmt(v), unit])
    if rows:
        s.add(Table("Whole run", ["metric", "value", "unit"], rows, [False, True, False]))
    phases = sim.get("phases", [])
    if phases:
        h = ["phase", "kind", "duration [s]", "att. error max [deg]", "att. error final [deg]", "settling [s]",
             "EE error max [m]", "wheel speed peak [rpm]", "saturated [s]"]
        s.add(Table("Per phase", h, [[p.get("name", str(i)), p.get("kind", ""), fmt(p.get("duration_s")),
                                      fmt(_get(p, "attitude_error_deg.max")), fmt(_get(p, "attitude_error_deg.final")),
                                      fmt(p.get("settling_time_s")), fmt(_get(p, "end_effector_error_m.max")),
                                      fmt(p["wheel_speed_peak_rad_s"] * 60 / (2 * math.pi)) if p.get("wheel_speed_peak_rad_s") is not None else "—",
                                      fmt(p.get("saturation_time_s"))] for i, p in enumerate(phases)], _num_cols(h, 2)))
    cons = sim.get("conservation", {})
    if cons:
        s.add(Table("Conservation checks (momentum without external forces; energy change)", ["quantity", "value"],
                    [[k, fmt(v)] for k, v in cons.items()], [False, True]))
    captions = {
        "sim_attitude_error.png": "Base attitude error angle against time (phase boundaries dashed).",
        "sim_wheels.png": "Reaction-wheel speeds (rpm) and motor torques (N m).",
        "sim_joints.png": "Manipulator joint tracking errors and torques.",
        "sim_modes.png": "Peak modal amplitude of the flexible appendages.",
        "sim_end_effector.png": "End-effector position error against time.",
    }
    for name in _pngs(sim.get("files", {}).get("plots", [])):
        s.add(figure_from_file(folder, name, captions.get(name, _caption_from_name(name))))
    for f in extra:
        s.add(f)
    return s


# ----------------------------------------------------------------- requirements and provenance


def requirements_section(verdicts: list[dict[str, Any]]) -> Section:
    s = Section("requirements", "Requirement verdicts")
    h = ["requirement", "metric", "value", "bound", "margin", "status"]
    rows, cls = [], []
    for v in verdicts:
        unit = f" {v['unit']}" if v.get("unit") else ""
        value = "missing" if v["value"] is None else fmt(v["value"], 6) + unit
        rows.append([v["name"], v["metric"], value, (v["bound"] + unit) if v["bound"] else "", fmt(v.get("margin")),
                     v["status"].upper()])
        cls.append("pass" if v["status"] == "pass" else "fail")
    s.add(Table(f"{sum(c == 'pass' for c in cls)}/{len(cls)} requirements met", h, rows,
                [False, False, True, False, True, False], cls))
    s.notes.extend(f"{v['name']}: {v['message']}" for v in verdicts if v.get("message") and v["status"] != "pass")
    return s


def provenance_section(run: dict[str, Any], results_sha: str) -> Section:
    s = Section("provenance", "Provenance")
    rows = [["mission", run.get("mission", "—")], ["date of the run", run.get("date", "—")],
            ["command", run.get("command", "—")], ["platform", run.get("platform", "—")],
            ["results.json sha256", results_sha]]
    s.add(Table("Run", ["item", "value"], rows))
    files = run.get("files", {})
    if files:
        s.add(Table("Input files", ["role", "path", "sha256"], [[k, f.get("path", ""), f.get("sha256") or "unreadable"]
                                                              for k, f in files.items()]))
    vers = run.get("versions", {})
    if vers:
        s.add(Table("Software versions", ["package", "version"], [[k, v] for k, v in vers.items()]))
    return s
