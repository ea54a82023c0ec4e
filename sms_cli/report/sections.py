"""One builder per results.json section → a report :class:`Section` (only when its data exist).

Every numeric column says its unit: in its header (``ΔV [m/s]``), in a ``unit`` column, or in each
cell when the unit changes from row to row (``qty``); ``–`` marks a dimensionless quantity. Each
figure's caption says what the figure shows and what to read from it.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from sms_cli.report.model import Figure, Section, Table, figure_from_file, fmt, qty

RPM = 60 / (2 * math.pi)
TASK = "task units"  # manipulabilities: units of the task rows (m/s per joint unit for linear rows)
INDEX_LABELS = {
    "K_m": ("K^m_ω0: joint share of the base attitude disturbance", "–"),
    "K_r": ("K^r_ω0: wheel share", "–"),
    "mu_fixed": ("manipulability, fixed base", TASK),
    "fixed_cond": ("σmin/σmax of the fixed-base Jacobian", "–"),
    "mu_gjm": ("manipulability of the generalized Jacobian (free floating)", TASK),
    "gjm_cond": ("σmin/σmax of the generalized Jacobian", "–"),
    "singular": ("singular configuration (fraction = mean)", "–"),
    "mu_ratio": ("μ free floating / μ fixed base", "–"),
    "mu_dyn": ("dynamic manipulability μ*", TASK),
    "mu_scal_lin": ("μ(ṙ_EE), base free", TASK),
    "mu_null_lin": ("null-motion μ^N(ṙ_EE), fixed attitude", TASK),
    "mu_null_ang": ("null-motion μ^N(ω_EE)", TASK),
    "mu_scal_lin_norm": ("μ(ṙ_EE) normalised", "–"),
    "mu_null_lin_norm": ("μ^N(ṙ_EE) normalised", "–"),
    "joint_limit_margin": ("joint-limit margin", "–"),
    "h_arm_max": ("arm momentum at max joint speed", "N m s"),
    "h_ratio": ("arm momentum / wheel capacity", "–"),
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


def _vector(xs: Any, unit: str) -> str:
    return "[" + ", ".join(fmt(x) for x in xs or []) + "]" + (f"\u00a0{unit}" if unit and unit != "–" else "")


# ----------------------------------------------------------------- model

_JOINT_UNITS = {"prismatic": ("m", "m/s", "N")}


def _joint_units(kind: str) -> tuple[str, str, str]:
    return _JOINT_UNITS.get(kind, ("rad", "rad/s", "N m"))


def model_section(c: dict[str, Any], folder: Path, robot_png: bytes | None) -> Section:
    s = Section("model", "Mission and model")
    d = c.get("dof", {})
    com = c.get("com_world_m") or [None] * 3
    inertia = c.get("inertia_about_com_world_kgm2") or [[None] * 3] * 3
    rows = [
        ["degrees of freedom", f"{d.get('total')} = base {d.get('base')} + wheels {d.get('wheels')} + arm {d.get('arm')}"
                               f" + passive {d.get('passive')} + modes {d.get('modes')}"],
        ["total mass", qty(c.get("total_mass_kg"), "kg")],
        ["centre of mass (world)", _vector(com, "m")],
        ["inertia about CoM (diag, world)", _vector([inertia[i][i] for i in range(3)], "kg m²")],
        ["end effector", f"{c.get('end_effector')} at " + _vector(c.get("end_effector_position_world_m"), "m")],
    ]
    cap = c.get("wheel_momentum_capacity", {}).get("along_base_axes_Nms")
    if cap:
        rows.append(["wheel momentum capacity (x, y, z)", _vector([cap[k] for k in ("x", "y", "z")], "N m s")])
    if c.get("coupled_frequencies_hz"):
        rows.append(["coupled modal frequencies", _vector(c["coupled_frequencies_hz"][:12], "Hz")])
    s.add(Table("Model at the initial configuration (world frame, SI)", ["quantity", "value"], rows))
    if robot_png:
        s.add(Figure.of_png(f"{c.get('name', '')}: the robot in its initial configuration, to check the model is the "
                            "one meant (URDF primitives, link frames, end effector ★, base triad, wheel spin axes).",
                            robot_png, "robot drawing"))
    if c.get("arm_joints"):
        h = ["joint", "kind", "lower", "upper", "max velocity", "max effort"]
        rows = []
        for a in c["arm_joints"]:
            pos, vel, eff = _joint_units(a["kind"])
            rows.append([a["name"], a["kind"], qty(a["lower"], pos), qty(a["upper"], pos), qty(a["max_velocity"], vel),
                         qty(a["max_effort"], eff)])
        s.add(Table("Arm joints (limits in the joint's unit: rad or m)", h, rows, _num_cols(h, 2)))
    if c.get("wheels"):
        h = ["wheel", "spin axis (base frame, unit vector)", "spin inertia [kg m²]", "max torque [N m]", "max speed [rpm]",
             "initial [rpm]"]
        s.add(Table("Reaction wheels", h, [[w["name"], "[" + ", ".join(f"{a:.3f}" for a in w["axis_base"]) + "]",
                                              fmt(w["spin_inertia_kgm2"]), fmt(w["max_torque_Nm"]),
                                              fmt(w["max_speed_rad_s"] * RPM if w["max_speed_rad_s"] is not None else None),
                                              fmt((w.get("initial_speed_rad_s") or 0.0) * RPM)] for w in c["wheels"]],
                    _num_cols(h, 2)))
    if c.get("appendages"):
        h = ["appendage", "junction frame", "clamped frequencies [Hz]", "damping ratios [–]"]
        s.add(Table("Flexible appendages (hybrid coordinates)", h,
                    [[a["name"], a["frame"], ", ".join(fmt(f) for f in a["clamped_frequencies_hz"]),
                      ", ".join(fmt(z) for z in a["damping"])] for a in c["appendages"]]))
    if c.get("payloads"):
        h = ["payload", "frame", "mass [kg]", "attached at start"]
        s.add(Table("Payloads", h, [[p["name"], p["frame"], fmt(p["mass_kg"]), fmt(p["attached"])] for p in c["payloads"]],
                    [False, False, True, False]))
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
        closes = "pass" if m["closes"] else "fail"
        s.add(Table(f"{sc['name']}: mass closure", ["quantity", "value"], [
            ["wet mass", f"{qty(m['wet_mass_kg'], 'kg', 6)} ({m['wet_mass_source']})"],
            ["dry mass", qty(m["dry_mass_kg"], "kg", 6)],
            ["final mass", qty(m["final_mass_kg"], "kg", 6)],
            ["residual propellant", f"{qty(m['residual_propellant_kg'], 'kg', 6)} "
                                    f"(reserve required {qty(m['reserve_required_kg'], 'kg')} = {m['propellant_margin']:.0%})"],
            ["smallest closing wet mass", "diverges" if req is None else qty(req, "kg", 6)],
            ["budget closes", "YES" if m["closes"] else "NO"],
        ], row_classes=[""] * 5 + [closes], status_col=1))
        if sc.get("by_propulsion"):
            h2 = ["propulsion", "ΔV [m/s]", "propellant [kg]", "burn time [s]", "burn time [d]"]
            s.add(Table(f"{sc['name']}: per propulsion system", h2,
                        [[n, fmt(d["dv_m_s"]), fmt(d["propellant_kg"]), fmt(d["burn_duration_s"]),
                          fmt(d["burn_duration_s"] / 86400.0)] for n, d in sc["by_propulsion"].items()], _num_cols(h2)))
        s.notes.extend(f"{sc['name']}: {w}" for w in sc.get("warnings", []))
    captions = {"budget_mass.png": "Mass along the mission: whether the propellant lasts to the last step "
                                   "(total with captured targets, chaser; dotted: dry mass).",
                "budget_dv.png": "ΔV per phase (with margins): which phases dominate the budget."}
    for name in _pngs(b.get("artifacts", [])):
        s.add(figure_from_file(folder, name, captions.get(name, _caption_from_name(name))))
    return s


# ----------------------------------------------------------------- analysis


def _index_caption(stem: str) -> str | None:
    """The caption of an analysis plot named after an index (``analysis_<variant>_<index>``)."""
    from sms_cli.analysis.plots import LOWER_IS_BETTER

    for key, (label, _) in sorted(INDEX_LABELS.items(), key=lambda kv: -len(kv[0])):
        if stem.endswith("_" + key):
            variant = stem[len("analysis_"):-len(key) - 1]
            direction = "lower" if key in LOWER_IS_BETTER else "higher"
            if variant == "compare":
                return (f"{label} for each design variant on one colour scale ({direction} is better): where in the "
                        "workspace a variant improves on the nominal design. Each cell of the XY, XZ and YZ projections "
                        "(satellite frame, m) shows the best value of the configurations that reach it.")
            return (f"Variant '{variant}': {label} over the reachable workspace ({direction} is better). Each cell of the "
                    "XY, XZ and YZ projections of the end-effector positions (satellite frame, m) shows the best value "
                    "of the sampled configurations that reach it; grey cells: only undefined values.")
    return None


def analysis_section(a: dict[str, Any], folder: Path) -> Section:
    s = Section("analysis", "Workspace and kinematic indices")
    s.intro = (f"{fmt(a.get('samples', 0))} configurations ({a.get('method')}, n = {a.get('n')}) of the arm joints "
               + ", ".join(f"{j['name']} ∈ [{fmt(j['lower'])}, {fmt(j['upper'])}]" for j in a.get("joints", []))
               + f"; task rows: {a.get('task')}.")
    stats = ["min", "p05", "p50", "p95", "max", "mean"]
    for vname, v in a.get("variants", {}).items():
        idx = v.get("indices", {})
        h = ["index", "unit"] + stats + ["undefined [samples]"]
        rows = []
        for key, d in idx.items():
            if key.startswith("ee_"):
                continue
            label, unit = INDEX_LABELS.get(key, (key, "–"))
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
                label, unit = INDEX_LABELS.get(key, (key, "–"))
                rows.append([f"{label} ({key})", unit] + [fmt(c.get(k)) for k in ("fraction_lower", "min_change", "max_change")])
        if rows:
            h = ["index", "unit", "fraction of samples lower [–]", "min change", "max change"]
            s.add(Table(f"Variant '{vname}' against the nominal design (changes in the index's unit)", h, rows,
                        _num_cols(h, 2)))
    for m in a.get("modal", []) or []:
        conf = ", ".join(f"{k} = {fmt(v)}" for k, v in m.get("configuration", {}).items()) or "initial configuration"
        h = ["mode", "frequency [Hz]", "frequency [rad/s]", "damping ratio [–]", "dominant coordinate"]
        s.add(Table(f"Coupled modes at {conf} ({m.get('joints')} joints, {m.get('states')} states)", h,
                    [[str(k + 1), fmt(x["frequency_hz"]), fmt(x["frequency_rad_s"]), fmt(x["damping"]), x.get("dominant", "")]
                     for k, x in enumerate(m.get("modes", []))], [True, True, True, True, False]))
    for name in _pngs(a.get("artifacts", [])):
        stem = Path(name).stem
        cap = _index_caption(stem) or _caption_from_name(name)
        if stem.endswith("_hist"):
            cap = (f"Variant '{stem[len('analysis_'):-5]}': how each index is distributed over the sampled workspace "
                   "(0.5 to 99.5 percentiles; dashed: median). A long tail marks the configurations to avoid.")
        elif stem.endswith("_slices"):
            cap = (f"Variant '{stem[len('analysis_'):-7]}': which joint drives each index. Each line is the mean of the "
                   "index along one joint, from its lower to its upper limit, over the samples of the other joints.")
        s.add(figure_from_file(folder, name, cap))
    return s


# ----------------------------------------------------------------- synthesis

GAMMA = "√s × ε_c unit"  # γ bounds √∫ε_cᵀε_c: ε_c in its own unit (rad or m), integrated over time
COST = "s × ε_c unit²"
# Labels and units of the synthesis figures of results.json (dotted paths).
SYNTHESIS_FIGURES = {
    "gamma": ("γ: guaranteed bound on √∫ε_cᵀε_c (solver)", GAMMA),
    "gamma_certified": ("γ certified by the returned Lyapunov matrix", GAMMA),
    "worst_cost.gramian": ("worst ∫ε_cᵀε_c over the initial errors (Gramian)", COST),
    "worst_cost.simulated": ("worst ∫ε_cᵀε_c over the initial errors (simulated)", COST),
    "worst_cost.gamma_squared": ("γ²: the bound it must stay below", COST),
    "robustness.relaxation": ("robustness relaxation", ""),
    "robustness.linearisations": ("linearisations", "count"),
    "robustness.samples": ("sampled configurations", "count"),
    "robustness.spread": ("half-width of the sampled box", "rad or m"),
    "initial_errors.modal_displacement": ("initial-error bound: modal displacement |η|", "√kg m"),
    "initial_errors.modal_rate": ("initial-error bound: modal rate |η̇|", "√kg m/s"),
    "initial_errors.base_rate": ("initial-error bound: base-rate estimate", "rad/s"),
    "initial_errors.tracking": ("initial-error bound: tracking |q_d − q|", "rad or m"),
    "initial_errors.tracking_rate": ("initial-error bound: tracking rate", "rad/s or m/s"),
    "initial_errors.disturbance_torque": ("initial-error bound: disturbance torque", "N m"),
    "tracking_box": ("tracking-error box (position, rate)", "rad or m, rad/s or m/s"),
    "lmi.size": ("LMI size (rows)", "count"),
    "lmi.n_q": ("controlled coordinates n_q", "count"),
    "lmi.n_e": ("observer states n_e", "count"),
    "lmi.n_variables": ("decision variables", "count"),
    "lmi.solver": ("solver", ""),
    "lmi.solver_status": ("solver status", ""),
    "lmi.solve_time_s": ("solve time", "s"),
    "lmi.build_time_s": ("build time", "s"),
    "lmi.verify_time_s": ("verification time", "s"),
    "observer.L_norm": ("‖L‖₂ of the observer gain", "mixed (see the L table)"),
    "inertia.worst_kg_m2": ("largest locked inertia per axis (x, y, z)", "kg m²"),
    "inertia.min_kg_m2": ("smallest locked inertia per axis (x, y, z)", "kg m²"),
    "inertia.configurations": ("configurations sampled for the inertia", "count"),
    "wheel_torque_capacity_n_m": ("wheel torque capacity per axis (x, y, z)", "N m"),
    "disturbance_bound_n_m": ("arm disturbance bound per axis (x, y, z)", "N m"),
    "arm_motion.max_joint_acceleration": ("arm motion assumed: max joint acceleration", "rad/s²"),
    "arm_motion.max_joint_rate": ("arm motion assumed: max joint rate", "rad/s"),
    "saturation_angle_rad": ("step that saturates the wheels, per axis (x, y, z)", "rad"),
    "gains.k1_n_m": ("twisting gain k1 = r1", "N m"),
    "gains.k2_n_m": ("twisting gain k2 = r2", "N m"),
    "gains.lambda_1_s": ("surface slope λ", "1/s"),
    "gains.C": ("bound C on the uncontrolled σ̈", "rad/s²"),
    "gains.K_m": ("K_m: least ∂σ̈/∂u", "1/(kg m²)"),
    "gains.K_M": ("K_M: largest ∂σ̈/∂u", "1/(kg m²)"),
    "total_time_s": ("synthesis time", "s"),
}
_SKIP = ("law", "variant", "status", "axes", "frame", "poles", "verification", "regions", "files", "timing", "plots",
         "artifacts", "observer.states", "observer.outputs", "robustness.rho")
# Per-actuator gains of results.json: key → (header, unit).
GAIN_COLUMNS = {
    "actuator": ("actuator", None), "axis": ("axis", None),
    "kp_1_s2": ("kp", "1/s²"), "kv_1_s": ("kv", "1/s"), "kp_n_m_rad": ("kp", "N m/rad"), "kd_n_m_s_rad": ("kd", "N m s/rad"),
    "torque_limit": ("effort limit", "N m or N"), "accel_limit": ("acceleration limit", "rad/s² or m/s²"),
    "bandwidth_rad_s": ("bandwidth ω_n", "rad/s"), "damping": ("damping ratio ζ", "–"),
    "slope_1_s": ("surface slope λ", "1/s"), "c_rad_s2": ("switching gain c", "rad/s²"), "mu_s_rad": ("tanh slope μ", "s/rad"),
}
# Verification checks: name → (what it checks, unit of its value and limit).
CHECKS = {
    "controller_poles": ("controller poles inside the requested region (worst relative margin)", "–"),
    "observer_poles": ("observer poles inside their region (worst relative margin)", "–"),
    "certificate": ("the Lyapunov matrix proves γ (certified γ ≤ solver γ)", GAMMA),
    "gamma_bound": ("worst ∫ε_cᵀε_c below γ²", COST),
    "actuator_authority": ("peak feedback acceleration / limit", "–"),
    "flexible_damping": ("least observer damping ≥ open-loop modal damping", "–"),
    "switching_gain": ("c·J_min − disturbance bound (least over the axes)", "N m"),
    "wheel_authority": ("peak SMC torque / wheel capacity", "–"),
    "twisting_conditions": ("twisting conditions (Ruggiero 2020, (4.6))", ""),
    "riccati_residual": ("relative Riccati residual", "–"),
    "bandwidth": ("least natural frequency over the configurations", "rad/s"),
    "damping": ("least damping ratio over the configurations", "–"),
    "stable_over_workspace": ("largest Re s over the configurations", "1/s"),
}


def _leaves(tree: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """Dotted paths of the scalars and short numeric lists of a section (skipping the tabled parts)."""
    out: list[tuple[str, Any]] = []
    if prefix in _SKIP:
        return out
    if isinstance(tree, dict):
        for k, v in tree.items():
            out += _leaves(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(tree, list):
        if tree and len(tree) <= 6 and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in tree):
            out.append((prefix, tree))
    elif isinstance(tree, (bool, int, float, str)) and not (isinstance(tree, str) and tree.endswith((".png", ".yaml"))):
        out.append((prefix, tree))
    return out


def _observer_unit(state: str, outputs: list[str]) -> str:
    """Unit of a row of L (state rate per output): η → √kg m, η̇ → √kg m/s, ω0 → rad/s; outputs rad/s."""
    if all(o.startswith("w0") for o in outputs):
        if state.endswith("_rate"):
            return "√kg m/(rad s)"
        if state.startswith("w0"):
            return "1/s"
        if "mode" in state:
            return "√kg m/rad"
    return "state unit/(s × output unit)"


def _gain_tables(s: Section, sy: dict[str, Any], g: dict[str, Any]) -> None:
    gains = sy.get("gains")
    if isinstance(gains, list) and gains and all(isinstance(x, dict) for x in gains):
        keys = [k for k in gains[0] if k in GAIN_COLUMNS]
        h = [GAIN_COLUMNS[k][0] + (f" [{GAIN_COLUMNS[k][1]}]" if GAIN_COLUMNS[k][1] else "") for k in keys]
        s.add(Table("Gains per actuator", h, [[fmt(x.get(k)) for k in keys] for x in gains],
                    [GAIN_COLUMNS[k][1] is not None for k in keys]))
        return
    ctl, acts = g.get("controller"), g.get("actuators", [])
    if ctl and acts:
        unit = ("1/s²", "1/s") if ctl.get("units") == "acceleration" else ("N m/rad", "N m s/rad")
        h = ["actuator", f"kp [{unit[0]}]", f"kv [{unit[1]}]"]
        s.add(Table(f"Controller gains ({ctl.get('units')} form)", h,
                    [[n, fmt(p), fmt(v)] for n, p, v in zip(acts, ctl.get("kp", []), ctl.get("kv", []))], _num_cols(h)))
    smc = g.get("smc")
    if smc:
        h = ["axis", "slope λ [1/s]", "c [rad/s²]", "μ [s/rad]", "disturbance bound [N m]"]
        s.add(Table("Sliding-mode gains", h, [[ax, fmt(a), fmt(b), fmt(c), fmt(d)] for ax, a, b, c, d in zip(
            smc.get("axes", []), smc.get("slope", []), smc.get("c", []), smc.get("mu", []), smc.get("disturbance_bound", []))],
            _num_cols(h)))


def synthesis_section(sy: dict[str, Any], folder: Path) -> Section:
    s = Section("synthesis", "Gains and closed-loop poles")
    g: dict[str, Any] = {}
    gains_file = folder / "gains.yaml"
    if gains_file.is_file():
        import yaml

        try:
            g = yaml.safe_load(gains_file.read_text(encoding="utf-8")) or {}
        except (yaml.YAMLError, UnicodeDecodeError):
            g = None
        if not isinstance(g, dict):
            g = {}
            s.notes.append(f"{gains_file} could not be read (damaged), so the gain tables from it are left out")
    law, variant = g.get("law", sy.get("law", "?")), g.get("variant") or sy.get("variant")
    s.intro = f"law: {law}" + (f", variant {variant}" if variant else "") + (f"; status: {sy['status']}" if sy.get("status") else "")
    _gain_tables(s, sy, g)
    obs = g.get("observer")
    if obs and obs.get("L"):
        outs = [str(o) for o in obs.get("outputs", [])]
        h = ["state", "unit"] + outs
        s.add(Table("Observer gain L (states × outputs; each row in the unit of the state's rate per output unit)", h,
                    [[st, _observer_unit(str(st), outs)] + [fmt(x) for x in row] for st, row in zip(obs.get("states", []), obs["L"])],
                    _num_cols(h, 2)))
    regions = sy.get("regions")
    if isinstance(regions, dict) and regions:
        h = ["loop", "decay rate α [1/s]", "min damping ζ [–]", "max frequency r [rad/s]"]
        s.add(Table("Requested pole regions (Re s ≤ −α, ζ ≥ ζ_min, |s| ≤ r)", h,
                    [[k, fmt(r.get("decay_rate")), fmt(r.get("min_damping")), fmt(r.get("max_frequency"))]
                     for k, r in regions.items() if isinstance(r, dict)], _num_cols(h)))
    ver = g.get("verification") or sy.get("verification") or {}
    checks = ver.get("checks") if isinstance(ver, dict) else None
    if checks and isinstance(checks, list) and all(isinstance(c, dict) for c in checks):
        h = ["check", "status", "value", "limit", "unit", "detail"]
        rows, cls = [], []
        for c in checks:
            what, unit = CHECKS.get(str(c.get("name")), (str(c.get("name")), ""))
            ok = bool(c.get("passed", True))
            rows.append([f"{c.get('name')}: {what}", "PASS" if ok else "FAIL", fmt(c.get("value")), fmt(c.get("limit")),
                         unit or "—", str(c.get("detail") or "")])
            cls.append("pass" if ok else "fail")
        s.add(Table("Verification of the gains", h, rows, [False, False, True, True, False, False], cls, status_col=1))
    figures = [(SYNTHESIS_FIGURES.get(k, (k, "")), v) for k, v in _leaves(sy)]
    if figures:
        s.add(Table("Synthesis figures (results.json)", ["quantity", "value", "unit"],
                    [[label, _vector(v, "") if isinstance(v, list) else fmt(v), unit or "—"] for (label, unit), v in figures],
                    [False, True, False]))
    for name in _pngs(sy):
        cap = (_caption_from_name(name) + ": the closed-loop poles against the requested region (shaded); every "
               "pole inside it is what the verification checks. Right: zoom on the controller region."
               if "pole" in name else _caption_from_name(name))
        s.add(figure_from_file(folder, name, cap))
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
    ("joint_stop_time_s", "time on the joint stops (summed over the joints)", "s"),
    ("joint_stop_penetration_max", "joint past a URDF limit, max", "rad or m"),
]
CONSERVATION = {
    "linear_momentum_drift_abs": ("linear momentum drift, absolute", "N s"),
    "angular_momentum_drift_abs": ("angular momentum drift, absolute", "N m s"),
    "linear_momentum_drift_rel": ("linear momentum drift, relative", "–"),
    "angular_momentum_drift_rel": ("angular momentum drift, relative", "–"),
    "energy_change_J": ("mechanical energy change (work of the actuators)", "J"),
}
SIM_CAPTIONS = {
    "sim_attitude_error.png": "Base attitude error against time: whether the base settles, and when (log scale above "
                              "0.001 deg; phase starts dashed).",
    "sim_wheels.png": "Reaction-wheel speeds (rpm) and motor torques (N m) against their limits (dotted): how close the "
                      "wheels come to saturating.",
    "sim_joints.png": "Manipulator joint tracking errors and torques: how well the arm follows its reference.",
    "sim_modes.png": "Largest modal amplitude of the flexible appendages: how much the manoeuvre excites them.",
    "sim_end_effector.png": "End-effector position error against time: how well the end effector reaches its target.",
    "sim_thrusters.png": "Thrusters: the ideal torque and force the law asked for (solid) against the cycle average of "
                         "the firings that delivered it (dashed; the difference is the MIB dead band and the "
                         "quantisation), the total thrust and the propellant used (as Vicariotto 2023 Figs. 4.4d, 4.5d).",
    "sim_momentum.png": "Locked velocity μ = ω + Λθ̇ (Vicariotto 2023 (4.8)) and the attitude law's Lyapunov function "
                        "W: whether the law dissipates what it should.",
    "sim_torque_split.png": "The NDI command split as Kraiem 2022 plots it (Figs. 3.15, 4.28): the feedback torque M◇v, "
                            "the linearising torque (the actuators' own motion) and the disturbance torque (the "
                            "estimated flexible and base states, minus the disturbance observer's estimate).",
}


def _validation_table(phases: list[dict]) -> Table | None:
    """Kraiem 2022's validation measures per phase where the NDI law ran: rate tracking (3.67) and the command
    split's peak ratios (median over each group's actuators; ``sim.metrics.torque_split_metrics``)."""
    rows = []
    for i, p in enumerate(phases):
        ts = p.get("torque_split") or {}
        if not ts and p.get("joint_rate_error_rel_max") is None:
            continue
        rows.append([p.get("name", str(i)), fmt(p.get("joint_rate_error_rel_max")), fmt(p.get("wheel_rate_error_rel_max")),
                     fmt(_get(ts, "arm.linearising_to_feedback")), fmt(_get(ts, "arm.disturbance_to_linearising")),
                     fmt(_get(ts, "wheels.linearising_to_feedback")), fmt(_get(ts, "wheels.disturbance_to_linearising"))])
    if not rows:
        return None
    h = ["phase", "(3.67) joints [–]", "(3.67) wheels [–]", "arm lin./feedback [–]", "arm dist./lin. [–]",
         "wheels lin./feedback [–]", "wheels dist./lin. [–]"]
    return Table("Rate tracking (Kraiem 2022 (3.67)) and the NDI command split (peak ratios)", h, rows, _num_cols(h))


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
            v = v * RPM
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
                                      fmt(p["wheel_speed_peak_rad_s"] * RPM) if p.get("wheel_speed_peak_rad_s") is not None else "—",
                                      fmt(p.get("saturation_time_s"))] for i, p in enumerate(phases)], _num_cols(h, 2)))
        validation = _validation_table(phases)
        if validation is not None:
            s.add(validation)
    cons = sim.get("conservation", {})
    if cons:
        s.add(Table("Conservation checks (momentum without external forces; energy change)", ["quantity", "value", "unit"],
                    [[label, fmt(v), unit] for k, v in cons.items() for label, unit in [CONSERVATION.get(k, (k, "—"))]],
                    [False, True, False]))
    for name in _pngs(sim.get("files", {}).get("plots", [])):
        s.add(figure_from_file(folder, name, SIM_CAPTIONS.get(name, _caption_from_name(name))))
    for f in extra:
        s.add(f)
    return s


FORMATION_CAPTIONS = {
    "formation_shape_error.png": "Relative (shape) error: the other spacecraft's base position (cm) and rotation angle "
                                 "(deg) in the master's frame against the setpoint; dashed lines mark the pushes.",
    "formation_twists.png": "Locked (total) twist V_L and shape (relative) twist V_E of the passive decomposition "
                            "(Vicariotto 2023 (5.5)): the locked system keeps its motion while the shape is controlled.",
    "formation_momentum.png": "Total momentum of the pair in the world frame: constant between pushes when only "
                              "internal wrenches act; each push changes it by its impulse.",
    "formation_energy.png": "Kinetic energy split T = ½V_LᵀM_LV_L + ½V_EᵀM_EV_E + wheels, and the law's Lyapunov "
                            "function W, which must not increase between pushes.",
}


def formation_section(sim: dict[str, Any], folder: Path) -> Section:
    """The two-spacecraft simulation: relative and locked motion, momentum, pushes, energy, timing."""
    f = sim["formation"]
    s = Section("simulation", "Two-spacecraft simulation (locked/shape decomposition)")
    s.intro = (f"status: {sim.get('status')}; {fmt(sim.get('t_end_s'))} s simulated in {fmt(sim.get('steps'))} steps; "
               f"master (body 1): {f.get('master')}, other: {f.get('other')}; law {sim.get('law')}, "
               f"shape effort applied by: {sim.get('actuation')}")
    sh, lk, cons = sim.get("shape", {}), sim.get("locked", {}), sim.get("conservation", {})
    s.add(Table("Relative (shape) and locked motion", ["quantity", "value", "unit"], [
        ["shape position error, initial", fmt(sh.get("position_error_initial_m")), "m"],
        ["shape position error, final", fmt(sh.get("position_error_final_m")), "m"],
        ["shape angle error, initial", fmt(sh.get("angle_error_initial_deg")), "deg"],
        ["shape angle error, final", fmt(sh.get("angle_error_final_deg")), "deg"],
        ["shape settling time", fmt(sh.get("settling_time_s")), "s"],
        ["locked angular rate, initial", fmt(lk.get("angular_rate_initial_rad_s")), "rad/s"],
        ["locked angular rate, final", fmt(lk.get("angular_rate_final_rad_s")), "rad/s"],
        ["locked kinetic energy, initial / final", f"{fmt(lk.get('kinetic_energy_initial_J'))} / "
                                                   f"{fmt(lk.get('kinetic_energy_final_J'))}", "J"],
        ["shape kinetic energy, initial / final", f"{fmt(sh.get('kinetic_energy_initial_J'))} / "
                                                  f"{fmt(sh.get('kinetic_energy_final_J'))}", "J"],
    ], [False, True, False]))
    s.add(Table("Momentum of the pair (world frame)", ["quantity", "value", "unit"], [
        ["linear momentum drift between pushes", fmt(cons.get("linear_momentum_drift_between_pushes_Ns")), "N s"],
        ["angular momentum drift between pushes", fmt(cons.get("angular_momentum_drift_between_pushes_Nms")), "N m s"],
        ["relative drifts (linear, angular)", f"{fmt(cons.get('linear_momentum_drift_between_pushes_rel'))}, "
                                              f"{fmt(cons.get('angular_momentum_drift_between_pushes_rel'))}", "–"],
    ], [False, True, False]))
    pushes = sim.get("pushes") or []
    if pushes:
        s.add(Table("Pushes", ["body", "at [s]", "duration [s]", "force [N]", "momentum change [N s, N m s]"],
                    [[p["body"], fmt(p["at_s"]), fmt(p["duration_s"]), ", ".join(fmt(x) for x in p["force_N"]),
                      ", ".join(fmt(x, 3) for x in p["momentum_change"]) if p.get("momentum_change") else "—"]
                     for p in pushes], [False, True, True, False, False]))
    cap = sim.get("capture")
    if isinstance(cap, dict) and cap.get("engaged"):
        s.add(Table(f"Capture at {fmt(cap.get('at_s'))} s through a compliant interface "
                    f"({fmt(cap.get('natural_frequency_hz'))} Hz, damping ratio {fmt(cap.get('damping_ratio'))})",
                    ["quantity", "value", "unit"], [
                        ["offset of the frames at the capture", f"{fmt(cap.get('offset_m'))} / {fmt(cap.get('offset_deg'))}",
                         "m / deg"],
                        ["peak interface force", fmt(cap.get("peak_force_N")), "N"],
                        ["peak interface torque", fmt(cap.get("peak_torque_Nm")), "N m"],
                        ["stack rate after the capture", fmt(cap.get("stack_rate_deg_s")), "deg/s"],
                        ["impulse exchanged (linear, angular)", f"{fmt(cap.get('linear_impulse_exchanged_Ns'))}, "
                                                                f"{fmt(cap.get('angular_impulse_exchanged_Nms'))}", "N s, N m s"],
                        ["momentum change through the capture (linear, angular), of the exchanged impulse",
                         f"{fmt(cap.get('linear_momentum_change_rel'))}, {fmt(cap.get('angular_momentum_change_rel'))}", "–"],
                    ], [False, True, False]))
    tm = sim.get("timing", {})
    if tm:
        s.notes.append(f"{fmt(tm.get('us_per_step'))} µs per plant step with recording, "
                       f"{fmt(tm.get('real_time_factor'))}× real time ({fmt(tm.get('steps'))} steps)")
    for name in _pngs(sim.get("files", {}).get("plots", [])):
        s.add(figure_from_file(folder, name, FORMATION_CAPTIONS.get(name, _caption_from_name(name))))
    hil = sim.get("hil")
    if isinstance(hil, dict):
        ws = hil.get("workspace", {})
        rows = []
        for kind in ("absolute", "relative"):
            w = ws.get(kind, {})
            r = w.get("translation_range_m", {})
            rows.append([kind, ", ".join(fmt(r.get(a)) for a in "xyz"), fmt(w.get("max_rotation_deg")),
                         fmt(w.get("leaves_envelope_s")) if w.get("leaves_envelope_s") is not None else "never",
                         fmt(w.get("inside_fraction"))])
        s.add(Table(f"Hardware-in-the-loop replay on {hil.get('facility')}: {hil.get('moving')}'s robot moves, "
                    f"{hil.get('held')}'s holds (Vicariotto 2023 (6.2))",
                    ["replay", "translation range x, y, z [m]", "max rotation [deg]", "leaves the envelope at [s]",
                     "fraction inside [–]"], rows, [False, False, True, True, True]))
        for name, rc in (hil.get("reachability") or {}).items():
            s.notes.append(f"{name}'s facility robot: " + ("every commanded pose reachable" if rc.get("all_reachable") else
                           f"first unreachable at {fmt(rc.get('first_unreachable_s'))} s ({rc.get('reason')})"))
        s.add(figure_from_file(folder, "hil/workspace.png",
                               "The facility workspace an absolute replay would need against the relative one "
                               "(Vicariotto 2023 L203-L207: the COMRADE absolute spin fitted only 12 s)."))
    return s


# ----------------------------------------------------------------- requirements and provenance


def requirements_section(verdicts: list[dict[str, Any]]) -> Section:
    s = Section("requirements", "Requirement verdicts")
    h = ["requirement", "metric", "value", "bound", "margin", "unit", "status"]
    rows, cls = [], []
    for v in verdicts:
        rows.append([v["name"], v["metric"], "missing" if v["value"] is None else fmt(v["value"], 6), v["bound"] or "",
                     fmt(v.get("margin")), v.get("unit") or "–", v["status"].upper()])
        cls.append("pass" if v["status"] == "pass" else "fail")
    s.add(Table(f"{sum(c == 'pass' for c in cls)}/{len(cls)} requirements met", h, rows,
                [False, False, True, False, True, False, False], cls, status_col=6))
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
