"""The ``budget`` stage: evaluate every scenario, write results.json, CSV and plots, format a table.

Artifacts (all written atomically into the results folder):
``results.json`` section ``budget``; ``budget.csv`` (one row per step and scenario);
``budget_mass.png`` (mass along the mission); ``budget_dv.png`` (ΔV per phase).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

from sms_cli.errors import InputError, Location, Problem
from sms_cli.orbit.budget import ScenarioResult, evaluate_scenario
from sms_cli.results import ResultsDir, atomic_path, write_text_atomic

#: the files ``write_budget`` writes next to results.json
ARTIFACTS = ("budget.csv", "budget_mass.png", "budget_dv.png")

CSV_COLUMNS = [
    "scenario", "index", "phase", "name", "type", "propulsion", "dv_impulsive_m_s", "dv_factor", "dv_m_s",
    "mass_before_kg", "propellant_kg", "mass_after_kg", "attached_mass_after_kg", "burn_duration_s",
    "coast_duration_s", "orbit_after",
]


def _step_rows(r: ScenarioResult) -> list[dict[str, Any]]:
    R = r.constants.radius
    rows = []
    for p, sm in zip(r.planned, r.chain.steps):
        burns = [{"dv_m_s": b.dv * p.dv_factor, "label": b.label,
                  "altitude_km": None if math.isnan(b.radius) else (b.radius - R) / 1e3} for b in p.result.burns]
        event = None
        if p.event is not None:
            event = {"kind": p.event[0], "target" if p.event[0] != "refuel" else "mass_kg": p.event[1]}
            if p.event[0] == "capture":
                event["mass_kg"] = p.event[2]
        rows.append({
            "index": p.index + 1, "name": p.name, "type": p.type, "phase": p.phase,
            "propulsion": p.propulsion.name if p.propulsion else None,
            "dv_impulsive_m_s": p.dv_impulsive, "dv_factor": p.dv_factor, "dv_m_s": p.dv, "burns": burns,
            "mass_before_kg": sm.mass_before, "propellant_kg": sm.propellant, "mass_after_kg": sm.mass_after,
            "attached_mass_after_kg": sm.attached_after, "burn_duration_s": sm.burn_duration,
            "coast_duration_s": p.result.coast, "duration_tbd": p.result.coast is None,
            "orbit_after": p.result.orbit.as_dict(r.constants), "orbit_after_text": p.result.orbit.describe(r.constants),
            "event": event, "info": p.result.info, "notes": list(p.result.notes),
        })
    return rows


def _sum(rows: list[dict], key: str) -> float:
    return float(sum(row[key] or 0.0 for row in rows))


def scenario_dict(r: ScenarioResult) -> dict[str, Any]:
    """results.json data of one scenario (SI, with units in the key names)."""
    rows = _step_rows(r)
    by_prop: dict[str, dict[str, float]] = {}
    by_phase: dict[str, dict[str, float]] = {}
    for row in rows:
        if row["propulsion"]:
            d = by_prop.setdefault(row["propulsion"], {"dv_m_s": 0.0, "propellant_kg": 0.0, "burn_duration_s": 0.0})
            d["dv_m_s"] += row["dv_m_s"]
            d["propellant_kg"] += row["propellant_kg"]
            d["burn_duration_s"] += row["burn_duration_s"]
        d = by_phase.setdefault(row["phase"], {"dv_m_s": 0.0, "propellant_kg": 0.0, "burn_duration_s": 0.0})
        d["dv_m_s"] += row["dv_m_s"]
        d["propellant_kg"] += row["propellant_kg"]
        d["burn_duration_s"] += row["burn_duration_s"]
    propellant = _sum(rows, "propellant_kg")
    chain = r.chain
    reserve = r.margin * propellant
    residual = chain.final_mass - r.dry_mass - chain.final_attached
    closes = chain.closure(r.margin) >= -1e-9
    totals = {
        "dv_impulsive_m_s": _sum(rows, "dv_impulsive_m_s"), "dv_m_s": _sum(rows, "dv_m_s"),
        "propellant_kg": propellant, "burn_duration_s": _sum(rows, "burn_duration_s"),
        "coast_duration_s": _sum(rows, "coast_duration_s"),
        "duration_tbd_steps": sum(1 for row in rows if row["duration_tbd"]),
    }
    totals["mission_duration_s"] = totals["burn_duration_s"] + totals["coast_duration_s"]
    mass = {
        "dry_mass_kg": r.dry_mass, "wet_mass_kg": r.wet_mass, "wet_mass_source": r.wet_mass_source,
        "required_wet_mass_kg": r.required_wet_mass, "required_wet_mass_grid_kg": r.required_wet_mass_grid,
        "final_mass_kg": chain.final_mass, "final_attached_mass_kg": chain.final_attached,
        "residual_propellant_kg": residual, "propellant_margin": r.margin, "reserve_required_kg": reserve,
        "closes": bool(closes),
        "legs": [{"consumed_kg": leg.consumed, "residual_kg": leg.residual} for leg in chain.legs],
    }
    return {
        "name": r.name, "description": r.description,
        "initial_orbit": r.orbit0.as_dict(r.constants), "initial_orbit_text": r.orbit0.describe(r.constants),
        "final_orbit_text": (r.planned[-1].result.orbit if r.planned else r.orbit0).describe(r.constants),
        "steps": rows, "totals": totals, "mass": mass,
        "by_propulsion": by_prop, "by_phase": [{"phase": k, **v} for k, v in by_phase.items()],
        "warnings": list(r.warnings),
    }


def budget_dict(results: list[ScenarioResult], spec) -> dict[str, Any]:
    c = results[0].constants
    out: dict[str, Any] = {
        "constants": {"mu_m3_s2": c.mu, "earth_radius_m": c.radius, "g0_m_s2": c.g0, "j2": c.j2},
        "propulsion": {n: {"kind": p.kind, "isp_s": p.isp, "thrust_n": p.thrust, "propellant_model": p.propellant_model,
                           "duration_model": p.duration_model, "dv_margins": dict(p.dv_margins)}
                       for n, p in spec.propulsion.items()},
        "scenarios": [scenario_dict(r) for r in results],
        "artifacts": [],  # the files write_budget writes
    }
    if len(results) == 1:
        out["totals"] = out["scenarios"][0]["totals"]
        out["mass"] = out["scenarios"][0]["mass"]
    return out


# ------------------------------------------------------------------ artifacts


def budget_csv(data: dict[str, Any]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for sc in data["scenarios"]:
        for row in sc["steps"]:
            vals = []
            for col in CSV_COLUMNS:
                v = sc["name"] if col == "scenario" else row["orbit_after_text"] if col == "orbit_after" else row[col]
                if col == "coast_duration_s" and v is None:
                    v = "TBD"
                vals.append(f"{v:.10g}" if isinstance(v, float) else ("" if v is None else v))
            w.writerow(vals)
    return buf.getvalue()


def _save(fig, target: Path) -> None:
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")


def plot_mass(data: dict[str, Any], target: Path) -> None:
    """Total and chaser mass after each step, one line pair per scenario."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.8))
    for k, sc in enumerate(data["scenarios"]):
        color = f"C{k % 10}"
        steps = sc["steps"]
        x = list(range(len(steps) + 1))
        total = [sc["mass"]["wet_mass_kg"]] + [s["mass_after_kg"] for s in steps]
        chaser = [sc["mass"]["wet_mass_kg"]] + [s["mass_after_kg"] - s["attached_mass_after_kg"] for s in steps]
        ax.step(x, total, where="post", color=color, label=f"{sc['name']}: total (with targets)")
        ax.step(x, chaser, where="post", color=color, linestyle="--", label=f"{sc['name']}: chaser")
        ax.axhline(sc["mass"]["dry_mass_kg"], color=color, linestyle=":", linewidth=0.8)
        if len(data["scenarios"]) == 1:
            ax.set_xticks(x)
            ax.set_xticklabels(["start"] + [s["name"] for s in steps], rotation=60, ha="right", fontsize=7)
    ax.set_xlabel("step" if len(data["scenarios"]) > 1 else "")
    ax.set_ylabel("mass [kg]")
    ax.set_title("Mass along the mission (dotted: dry mass)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    _save(fig, target)
    plt.close(fig)


def plot_dv(data: dict[str, Any], target: Path) -> None:
    """ΔV (with margins) per phase, one panel per scenario."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scs = data["scenarios"]
    fig, axes = plt.subplots(len(scs), 1, figsize=(8, 1.2 + 0.5 * sum(max(len(s["by_phase"]), 1) for s in scs) + len(scs)),
                             squeeze=False)
    for ax, sc in zip(axes[:, 0], scs):
        phases = [p["phase"] for p in sc["by_phase"]]
        dvs = [p["dv_m_s"] for p in sc["by_phase"]]
        ax.barh(range(len(phases)), dvs, color="C0")
        ax.set_yticks(range(len(phases)))
        ax.set_yticklabels(phases, fontsize=8)
        ax.invert_yaxis()
        for y, v in enumerate(dvs):
            ax.text(v, y, f" {v:.1f}", va="center", fontsize=7)
        ax.set_title(f"{sc['name']}: ΔV per phase, total {sc['totals']['dv_m_s']:.1f} m/s", fontsize=9)
        ax.set_xlabel("ΔV [m/s]")
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    _save(fig, target)
    plt.close(fig)


# ------------------------------------------------------------------ printed table


def _fmt(v: float | None, nd: int) -> str:
    return "TBD" if v is None else f"{v:.{nd}f}"


def format_budget(data: dict[str, Any]) -> str:
    """Plain-text tables, one per scenario, units in the headers."""
    out = []
    for sc in data["scenarios"]:
        head = ["#", "phase", "step", "prop", "ΔV imp [m/s]", "factor", "ΔV [m/s]", "m_prop [kg]",
                "mass after [kg]", "burn [s]", "wait [d]", "orbit after [km @ deg]"]
        body = []
        for s in sc["steps"]:
            coast = None if s["coast_duration_s"] is None else s["coast_duration_s"] / 86400.0
            body.append([str(s["index"]), s["phase"], s["name"], s["propulsion"] or "-",
                         _fmt(s["dv_impulsive_m_s"], 3), f"{s['dv_factor']:.2f}", _fmt(s["dv_m_s"], 3),
                         _fmt(s["propellant_kg"], 3), _fmt(s["mass_after_kg"], 2), _fmt(s["burn_duration_s"], 1),
                         _fmt(coast, 3), s["orbit_after_text"]])
        t = sc["totals"]
        body.append(["", "TOTAL", "", "", _fmt(t["dv_impulsive_m_s"], 3), "", _fmt(t["dv_m_s"], 3),
                     _fmt(t["propellant_kg"], 3), "", _fmt(t["burn_duration_s"], 1),
                     _fmt(t["coast_duration_s"] / 86400.0, 3) + ("+TBD" if t["duration_tbd_steps"] else ""), ""])
        widths = [max(len(r[i]) for r in [head] + body) for i in range(len(head))]
        numeric = {0, 4, 5, 6, 7, 8, 9, 10}

        def line(r: list[str]) -> str:
            return "  ".join(c.rjust(w) if i in numeric else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))).rstrip()

        m = sc["mass"]
        out.append(f"== budget: {sc['name']} ==  start {sc['initial_orbit_text']}")
        out.append(line(head))
        out.append("  ".join("-" * w for w in widths))
        out.extend(line(r) for r in body[:-1])
        out.append("  ".join("-" * w for w in widths))
        out.append(line(body[-1]))
        req = m["required_wet_mass_kg"]
        req_txt = "diverges" if req is None else f"{req:.2f} kg" + (
            f" ({m['required_wet_mass_grid_kg']:.0f} kg on the grid)" if m["required_wet_mass_grid_kg"] != req else "")
        out.append(f"wet mass {m['wet_mass_kg']:.2f} kg ({m['wet_mass_source']}), dry {m['dry_mass_kg']:.2f} kg, "
                   f"final {m['final_mass_kg']:.2f} kg, residual propellant {m['residual_propellant_kg']:.2f} kg "
                   f"(reserve {m['propellant_margin']:.0%} = {m['reserve_required_kg']:.2f} kg)")
        out.append(f"smallest closing wet mass {req_txt}; budget {'CLOSES' if m['closes'] else 'DOES NOT CLOSE'}")
        for name, d in sc["by_propulsion"].items():
            out.append(f"  {name}: ΔV {d['dv_m_s']:.3f} m/s, propellant {d['propellant_kg']:.3f} kg, "
                       f"burn time {d['burn_duration_s']:.1f} s ({d['burn_duration_s'] / 86400.0:.2f} d)")
        for w in sc["warnings"]:
            out.append(f"  warning: {w}")
        out.append("")
    return "\n".join(out).rstrip() + "\n"


# ------------------------------------------------------------------ entry point


def compute_budget(loaded_mission) -> dict[str, Any]:
    """Evaluate the mission's ``budget:`` section; the ``budget`` section of results.json (SI units,
    units in the key names), with ``artifacts`` empty: nothing is written."""
    spec = loaded_mission.mission.budget
    if spec is None:
        raise InputError(problems=[Problem(
            "this mission has no 'budget:' section", Location(loaded_mission.path), "budget",
            "add a budget section (initial_orbit, propulsion, spacecraft, sequence); see missions/hipparcos_geo.yaml")])
    src = getattr(loaded_mission, "source", None)

    def locate(path: tuple):
        return src.locate(path) if src is not None else Location(loaded_mission.path)

    ks = [None] if spec.scenarios is None else list(range(len(spec.scenarios)))
    results = [evaluate_scenario(spec, k, locate) for k in ks]
    if spec.scenarios is None:
        results[0].name = loaded_mission.mission.name
    return budget_dict(results, spec)


def write_budget(data: dict[str, Any], results_dir: Path | str | ResultsDir) -> dict[str, Any]:
    """Write budget.csv, the plots and the ``budget`` section of results.json; returns ``data`` with its artifacts."""
    rd = results_dir if isinstance(results_dir, ResultsDir) else ResultsDir(results_dir)
    write_text_atomic(rd.file("budget.csv"), budget_csv(data))
    plot_mass(data, rd.file("budget_mass.png"))
    plot_dv(data, rd.file("budget_dv.png"))
    data["artifacts"] = list(ARTIFACTS)
    rd.update("budget", data)
    return data


def run_budget(loaded_mission, results_dir: Path | str | ResultsDir) -> dict[str, Any]:
    """Evaluate the mission's ``budget:`` section; write results.json, budget.csv and the plots,
    holding the results folder for the whole command (``ResultsDir.writing``)."""
    rd = results_dir if isinstance(results_dir, ResultsDir) else ResultsDir(results_dir)
    with rd.writing(loaded_mission.mission.name, loaded_mission.path):
        return write_budget(compute_budget(loaded_mission), rd)
