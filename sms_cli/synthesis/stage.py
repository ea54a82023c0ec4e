"""The ``synthesize`` stage: gains for the mission's ``synthesis:`` request, verified, written.

Artifacts (atomic): ``results.json`` section ``synthesis`` (law, γ, regions, closed-loop poles
per linearisation, every verification check with pass/fail, solve time, LMI size, gain table);
``gains.yaml`` (``sms_cli/synthesis/gains_io.py``); ``synthesis_poles.png`` (pole map with the
requested region). A failed verification is written as such, then raised as NumericalError
(exit 3) naming the failed checks and what to relax; so is an infeasible LMI.

Laws: ``lmi`` (Kraiem 2022 NDI + observer, acceleration gains per actuator), ``pd``/``lqr``/``smc``
(base attitude axes x, y, z of the base frame, torque gains on the worst-case locked inertia).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sms_cli.errors import InputError, NumericalError, Problem
from sms_cli.results import ResultsDir

if TYPE_CHECKING:
    from sms_cli.synthesis.gains_io import GainsFile
    from sms_cli.synthesis.regions import PoleRegion

AXES = ["x", "y", "z"]

HINTS = {
    "controller_poles": "widen the controller region (lower decay_rate/min_damping, raise max_frequency)",
    "observer_poles": "widen the observer region, or add the failing configuration to sampling.configurations",
    "ndo_poles": "widen the observer region",
    "certificate": "the LMI solution is badly conditioned: lower max_frequency or narrow sampling.spread",
    "gamma_bound": "the γ guarantee does not hold: narrow sampling.spread or lower max_frequency",
    "actuator_authority": "raise the torque limits, lower tracking_error_amplitude or the controller decay_rate",
    "flexible_damping": "set observer_region.min_damping at least to the modal damping ratio",
    "bandwidth": "lower the bandwidth or check the inertia range",
    "damping": "raise the damping ratio",
    "wheel_authority": "lower the bandwidth (pd/lqr) or the margin (smc), or use stronger wheels",
    "riccati_residual": "rescale q_position/q_velocity/r_effort",
    "stable_over_workspace": "raise the damping weights",
    "twisting_conditions": "raise the margin",
}


def _c(z) -> list[list[float]]:
    return [[float(np.real(v)), float(np.imag(v))] for v in np.asarray(z, dtype=complex)]


@dataclass
class Synthesized:
    """What a synthesis computed: the ``synthesis`` section (``files`` empty), the gains file's
    content, the closed-loop poles per linearisation (rad/s, complex) and the requested pole regions."""

    section: dict[str, Any]
    gains: GainsFile
    poles: list[dict[str, Any]]
    regions: dict[str, PoleRegion]


def run_synthesis(loaded, out_dir: Path | str, plots: bool = True) -> dict[str, Any]:
    """Run the mission's synthesis; return the ``synthesis`` section written to results.json,
    holding the results folder for the whole command (``ResultsDir.writing``)."""
    out = Path(out_dir)
    with ResultsDir(out).writing(loaded.mission.name, loaded.path):
        done = synthesize_mission(loaded, on_infeasible=lambda section: ResultsDir(out).update("synthesis", section))
        write_synthesis(done, loaded.mission.name, out, plots)
    check_verified(done.section)
    return done.section


def synthesize_mission(loaded, on_infeasible: Callable[[dict], None] | None = None) -> Synthesized:
    """Compile the mission and compute its gains, verified; nothing is written. An infeasible LMI
    raises NumericalError after ``on_infeasible`` got the section that says so; a failed
    verification is returned as such (``check_verified`` raises for it)."""
    spec = loaded.mission.synthesis
    if spec is None:
        raise InputError(f"{loaded.path}: the mission has no 'synthesis:' section",
                         [Problem("nothing to synthesise", field="synthesis",
                                  hint="add e.g. 'synthesis: {law: pd, pd: {bandwidth: 0.1 rad/s, damping: 0.9}}'")])
    from sms_cli.model import compile_system

    sm = compile_system(loaded)
    sm.require_dynamics("gain synthesis")
    t0 = time.perf_counter()
    if spec.law == "lmi":
        section, gains, poles, regions = _run_lmi(sm, spec, on_infeasible)
    else:
        section, gains, poles, regions = _run_classical(sm, spec)
    section["total_time_s"] = time.perf_counter() - t0
    section["files"] = {}  # write_synthesis names what it writes
    gains.mission = loaded.mission.name
    return Synthesized(section, gains, poles, regions)


def write_synthesis(done: Synthesized, mission: str, out: Path, plots: bool = True) -> dict[str, Any]:
    """Write gains.yaml, the pole map (``plots``) and the ``synthesis`` section with its ``files``."""
    from sms_cli.synthesis.gains_io import write_gains

    section = done.section
    files = {"gains": str(write_gains(out / "gains.yaml", done.gains).name)}
    if plots:
        from sms_cli.synthesis.plots import plot_pole_map

        plot_pole_map(done.poles, done.regions, out / "synthesis_poles.png", f"{mission}: {section['law']} closed-loop poles")
        files["pole_map"] = "synthesis_poles.png"
    section["files"] = files
    ResultsDir(out).update("synthesis", section)
    return section


def check_verified(section: dict[str, Any], written: bool = True) -> None:
    """NumericalError (exit 3) naming the failed checks and what to relax, when verification failed
    (``written``: gains.yaml was written, marked unverified)."""
    if not section["verification"]["passed"]:
        failed = [c for c in section["verification"]["checks"] if not c["passed"]]
        raise NumericalError(
            f"verification of the {section['law']} gains failed ({len(failed)} check(s)); "
            + ("gains.yaml is written but marked unverified" if written else "the gains are unverified"),
            [Problem(f"{c['name']}: {c['detail']}", field="synthesis", hint=HINTS.get(c["name"], "")) for c in failed])


# ---------------------------------------------------------------------------------------
# LMI (Kraiem 2022)


def _run_lmi(sm, spec, on_infeasible: Callable[[dict], None] | None):
    from sms_cli.synthesis.build import lmi_setup
    from sms_cli.synthesis.gains_io import ControllerGains, GainsFile, ObserverGains
    from sms_cli.synthesis.lmi import synthesize
    from sms_cli.synthesis.verify import verify_lmi

    t0 = time.perf_counter()
    setup = lmi_setup(sm, spec)
    req = setup.request
    t_build = time.perf_counter() - t0
    try:
        res = synthesize(req)
    except NumericalError as exc:
        if on_infeasible is not None:
            on_infeasible({"law": "lmi", "status": "infeasible", "message": exc.render()})
        raise
    t1 = time.perf_counter()
    ver = verify_lmi(req, res)
    t_verify = time.perf_counter() - t1
    lin = req.linearisations()
    regions = {"controller": req.controller_region, "observer": req.observer_region}
    poles = [{k: (np.asarray(v) if k != "label" else v) for k, v in p.items()} for p in ver.poles]
    table = [{"actuator": n, "kp_1_s2": float(kp), "kv_1_s": float(kv), "torque_limit": float(t),
              "accel_limit": None if req.accel_limit is None else float(req.accel_limit[i]),
              "bandwidth_rad_s": float(np.sqrt(kp)), "damping": float(kv / (2 * np.sqrt(kp)))}
             for i, (n, kp, kv, t) in enumerate(zip(setup.actuators, res.K_p, res.K_v, setup.torque_limit))]
    lspec = spec.lmi
    section = {
        "law": "lmi", "variant": res.variant, "status": "verified" if ver.passed else "verification_failed",
        "gamma": res.gamma, "gamma_certified": ver.certified_gamma,
        "worst_cost": {"gramian": ver.gramian_cost, "simulated": ver.simulated_cost, "gamma_squared": res.gamma**2},
        "regions": {k: r.as_dict() for k, r in regions.items()},
        "robustness": {"relaxation": req.relaxation, "linearisations": len(lin), "samples": len(req.samples),
                       "spread": float(lspec.sampling.spread), "rho": [list(r) for r in res.rho]},
        "initial_errors": lspec.initial_errors.model_dump(), "tracking_box": req.tracking[0].tolist(),
        "lmi": {"size": res.lmi_rows, "n_q": req.nominal[0].n_q, "n_e": req.nominal[0].n_e,
                "n_variables": res.n_variables, "solver": res.solver, "solver_status": res.status,
                "solve_time_s": res.solve_time, "build_time_s": t_build, "verify_time_s": t_verify},
        "gains": table,
        "observer": {"states": setup.state_names, "outputs": ["w0_x", "w0_y", "w0_z"],
                     "L_norm": float(np.linalg.norm(res.L, 2))},
        "poles": [{"label": p["label"], **{k: _c(v) for k, v in p.items() if k != "label"}} for p in poles],
        "verification": ver.as_dict(),
    }
    gains = GainsFile(
        mission="", law="lmi", variant=res.variant, actuators=setup.actuators,
        controller=ControllerGains(units="acceleration", kp=res.K_p.tolist(), kv=res.K_v.tolist()),
        observer=ObserverGains(states=setup.state_names, outputs=["w0_x", "w0_y", "w0_z"], L=res.L.tolist(),
                               Q_d=None if res.Q_d is None else res.Q_d.tolist()),
        guarantee={"gamma": res.gamma, "regions": section["regions"], "initial_errors": section["initial_errors"],
                   "tracking_box": section["tracking_box"], "linearisations": len(lin)},
        verification={"passed": ver.passed, "checks": [c.as_dict() for c in ver.checks]})
    return section, gains, poles, regions


# ---------------------------------------------------------------------------------------
# classical laws on the base attitude axes


def _axis_capacity(sm) -> np.ndarray:
    """Torque the wheels can give about each base axis (N m): Σ_k |a_k,i| τ_max,k; inf without wheels."""
    if not sm.wheels:
        return np.full(3, np.inf)
    return np.sum([np.abs(np.asarray(w.axis, dtype=float)) * float(w.max_torque) for w in sm.wheels], axis=0)


def _check(name, ok, detail, value=None, limit=None) -> dict:
    return {"name": name, "passed": bool(ok), "detail": detail, "value": value, "limit": limit}


def _run_classical(sm, spec):
    from sms_cli.synthesis import classical
    from sms_cli.synthesis.build import inertia_range, region_of_pd, workspace_configurations
    from sms_cli.synthesis.gains_io import ControllerGains, GainsFile, SmcGainsFile, TwistingGains
    from sms_cli.synthesis.regions import PoleRegion

    qs = workspace_configurations(sm, spec)
    Jmax, Jmin = inertia_range(sm, qs)
    cap = _axis_capacity(sm)
    checks: list[dict] = []
    section: dict[str, Any] = {"law": spec.law, "axes": AXES, "frame": "base",
                               "inertia": {"worst_kg_m2": Jmax.tolist(), "min_kg_m2": Jmin.tolist(),
                                           "configurations": len(qs)},
                               "wheel_torque_capacity_n_m": cap.tolist()}
    poles: list[dict] = []
    regions: dict[str, PoleRegion] = {}
    gains = GainsFile(mission="", law=spec.law, actuators=[f"base_{a}" for a in AXES])
    if spec.law in ("pd", "lqr"):
        if spec.law == "pd":
            g = classical.pd_gains(Jmax, float(spec.pd.bandwidth), float(spec.pd.damping), Jmin)
            kp, kd = g.kp, g.kd
            regions["controller"] = region_of_pd(spec.pd)
        else:
            ks = [classical.axis_lqr(J, float(spec.lqr.q_position), float(spec.lqr.q_velocity), float(spec.lqr.r_effort))
                  for J in Jmax]
            kp, kd = np.array([k[0] for k in ks]), np.array([k[1] for k in ks])
            # residual of the Riccati equation of each axis (independent of the gain formula)
            worst = 0.0
            for J, a, b in zip(Jmax, kp, kd):
                A = np.array([[0.0, 1.0], [0.0, 0.0]])
                B = np.array([[0.0], [1.0 / J]])
                Qw = np.diag([float(spec.lqr.q_position), float(spec.lqr.q_velocity)])
                _, P = classical.lqr(A, B, Qw, np.array([[float(spec.lqr.r_effort)]]))
                res = A.T @ P + P @ A - P @ B @ B.T @ P / float(spec.lqr.r_effort) + Qw
                worst = max(worst, float(np.max(np.abs(res)) / max(1.0, np.max(np.abs(P)))))
            checks.append(_check("riccati_residual", worst < 1e-8, f"relative Riccati residual {worst:.2e}", worst, 1e-8))
        # closed-loop poles of J s² + k_d s + k_p at every sampled inertia (independent: np.roots)
        wn_min, ze_min, re_max = np.inf, np.inf, -np.inf
        for q in qs:
            from sms_cli.synthesis.build import locked_inertia

            J = np.diag(locked_inertia(sm, q))
            ev = np.concatenate([np.roots([J[i], kd[i], kp[i]]) for i in range(3)])
            poles.append({"label": "workspace", "controller": ev})
            for i in range(3):
                r = np.roots([J[i], kd[i], kp[i]])
                wn_min = min(wn_min, float(np.sqrt(np.prod(np.abs(r)))))
                ze_min = min(ze_min, float(kd[i] / (2 * np.sqrt(kp[i] * J[i]))))
                re_max = max(re_max, float(np.max(r.real)))
        if spec.law == "pd":
            bw, ze = float(spec.pd.bandwidth), float(spec.pd.damping)
            checks.append(_check("bandwidth", wn_min >= bw * (1 - 1e-9),
                                 f"least ω_n over {len(qs)} configurations: {wn_min:.4g} rad/s (requested {bw:.4g})", wn_min, bw))
            checks.append(_check("damping", ze_min >= ze * (1 - 1e-9),
                                 f"least damping ratio: {ze_min:.4g} (requested {ze:.4g})", ze_min, ze))
        else:
            checks.append(_check("stable_over_workspace", re_max < 0, f"largest Re s = {re_max:.4g} 1/s", re_max, 0.0))
        # a step of 1 rad saturates the wheels beyond θ_sat = capacity / k_p (informational)
        theta_sat = cap / kp
        section["saturation_angle_rad"] = theta_sat.tolist()
        gains.controller = ControllerGains(units="torque", kp=kp.tolist(), kv=kd.tolist())
        gains.simulation = {"attitude": {"law": "quaternion_pd", "kp": kp.tolist(), "kd": kd.tolist()}}
        if spec.law == "pd" and spec.pd.target_law != "quaternion_pd":
            gains.simulation = {"attitude": momentum_law_gains(sm, spec.pd, kp, kd)}
            section["target_law"] = gains.simulation["attitude"]
        section["gains"] = [{"axis": a, "kp_n_m_rad": float(p), "kd_n_m_s_rad": float(d)} for a, p, d in zip(AXES, kp, kd)]
    else:
        from sms_cli.synthesis.build import arm_disturbance_bound

        s = spec.smc
        td = arm_disturbance_bound(sm, qs, float(s.max_joint_acceleration), float(s.max_joint_rate))
        lam = float(s.surface_slope)
        section["disturbance_bound_n_m"] = td.tolist()
        section["arm_motion"] = {"max_joint_acceleration": float(s.max_joint_acceleration),
                                 "max_joint_rate": float(s.max_joint_rate)}
        if s.kind == "first_order":
            g = classical.smc_gains(Jmin, td, lam, float(s.margin))
            peak = g.c * Jmax  # |τ| ≤ c J on the heaviest configuration
            checks.append(_check("switching_gain", bool(np.all(g.c * Jmin >= td * (1 - 1e-12))),
                                 f"c·J_min = {np.round(g.c * Jmin, 6).tolist()} N m ≥ disturbance bound "
                                 f"{np.round(td, 6).tolist()} N m", float(np.min(g.c * Jmin - td)), 0.0))
            gains.smc = SmcGainsFile(axes=AXES, slope=g.slope.tolist(), c=g.c.tolist(), mu=g.mu.tolist(),
                                     disturbance_bound=td.tolist())
            gains.simulation = {"attitude": {"law": "smc", "k": lam, "c": g.c.tolist(), "mu": float(np.min(g.mu))}}
            section["gains"] = [{"axis": a, "slope_1_s": lam, "c_rad_s2": float(c), "mu_s_rad": float(m)}
                                for a, c, m in zip(AXES, g.c, g.mu)]
        else:
            C = float(np.max(td / Jmin))
            Km, KM = float(1.0 / np.max(Jmax)), float(1.0 / np.min(Jmin))
            r1, r2 = classical.twisting_gains(C, Km, KM, float(s.margin))
            peak = np.full(3, r1 + r2)
            ok = classical.twisting_ok(C, Km, KM, r1, r2)
            checks.append(_check("twisting_conditions", ok,
                                 f"Ruggiero 2020 (4.6) with C = {C:.3g} rad/s², K_m = {Km:.3g}, K_M = {KM:.3g} 1/(kg m²): "
                                 f"r1 = {r1:.4g}, r2 = {r2:.4g} N m", None, None))
            gains.smc = SmcGainsFile(axes=AXES, slope=[lam] * 3, c=[0.0] * 3, mu=[1.0] * 3, disturbance_bound=td.tolist(),
                                     twisting=TwistingGains(r1=r1, r2=r2, C=C, K_m=Km, K_M=KM))
            gains.simulation = {"attitude": {"law": "twisting_smc", "k1": r1, "k2": r2, "lambda": lam}}
            section["gains"] = {"k1_n_m": r1, "k2_n_m": r2, "lambda_1_s": lam, "C": C, "K_m": Km, "K_M": KM}
        checks.append(_check("wheel_authority", bool(np.all(peak <= cap * (1 + 1e-12))),
                             f"peak SMC torque per axis {np.round(peak, 6).tolist()} N m vs wheel capacity "
                             f"{np.round(cap, 4).tolist()} N m", float(np.max(peak / cap)), 1.0))
        regions["controller"] = PoleRegion(lam * (1 - 1e-9), 0.0, lam * 5.0)
        poles.append({"label": "sliding surface", "controller": np.full(3, -lam, dtype=complex)})
    passed = all(c["passed"] for c in checks)
    section["status"] = "verified" if passed else "verification_failed"
    section["verification"] = {"passed": passed, "checks": checks}
    section["regions"] = {k: r.as_dict() for k, r in regions.items()}
    section["poles"] = [{"label": p["label"], "controller": _c(p["controller"])} for p in poles[:1]]
    gains.verification = section["verification"]
    return section, gains, poles, regions


# ---------------------------------------------------------------------------------------


def format_synthesis(section: dict) -> str:
    """A short human summary of the synthesis section."""
    lines = [f"law: {section['law']}" + (f" ({section['variant']})" if section.get("variant") else "")
             + f" — {section['status']}"]
    if section["law"] == "lmi":
        lm = section["lmi"]
        lines.append(f"γ = {section['gamma']:.4g} (certified {section['gamma_certified']:.4g}); worst ∫ε_c² = "
                     f"{section['worst_cost']['gramian']:.4g} (Gramian), {section['worst_cost']['simulated']:.4g} (simulated)")
        lines.append(f"LMI: size {lm['size']} (n_q = {lm['n_q']}, n_e = {lm['n_e']}), {section['robustness']['linearisations']} "
                     f"linearisation(s), solve {lm['solve_time_s']:.2f} s, total {section['total_time_s']:.2f} s")
        lines.append(f"{'actuator':<16}{'kp (1/s²)':>12}{'kv (1/s)':>12}{'ω_n':>9}{'ζ':>7}")
        for g in section["gains"]:
            lines.append(f"{g['actuator']:<16}{g['kp_1_s2']:>12.4g}{g['kv_1_s']:>12.4g}{g['bandwidth_rad_s']:>9.3g}{g['damping']:>7.3f}")
    else:
        lines.append(f"worst-case locked inertia (base x, y, z): {np.round(section['inertia']['worst_kg_m2'], 4).tolist()} kg m²")
        lines.append(f"gains: {section['gains']}")
    for c in section["verification"]["checks"]:
        lines.append(f"  [{'ok' if c['passed'] else 'FAIL'}] {c['name']}: {c['detail']}")
    if section.get("files"):
        lines.append("files: " + ", ".join(section["files"].values()))
    return "\n".join(lines)


def momentum_law_gains(sm, pd, kp: np.ndarray, kd: np.ndarray) -> dict:
    """The attitude block of a Vicariotto 2023 momentum law (sms_cli.sim.laws.momentum) with the per-axis
    closed loop I φ̈ + K_d φ̇ + K_p φ = 0 of the PD gains (K_p = I ω_n², K_d = 2ζω_n I), linearised at rest with
    wheel i along base axis i, Λ_i = J_i / I_i:

    - wheels_free_floating (4.13): I φ̈ = −Λ k_p φ − (k_d/Λ) φ̇, so k_p = K_p/Λ, k_d = K_d Λ;
    - inertia_shaping (§4.2.2): I φ̈ = −k_p φ − (k_d/Λ²) φ̇, so k_p = K_p, k_d = K_d Λ²;
    - free_flying (4.15)/(4.16), se3_pd (3.9): k_p = K_p, k_d^b (k_d) = K_d; the shaped wheels' rates decay
      at 2ζω_n: k_d^w = 2ζω_n (ΛᵀM_θ)_ii; hierarchical: task 1 k_d^b = K_d, task 2 as inertia_shaping."""
    from sms_cli.dynamics.locked import locked_shape
    from sms_cli.errors import InputError, Problem

    law = pd.target_law
    if law != "se3_pd":
        if len(sm.wheels) != 3:
            raise InputError(problems=[Problem(f"target_law {law}: the per-axis mapping needs 3 wheels", field="synthesis.pd.target_law")])
        ls = locked_shape(sm, sm.q0)
        G = ls.G
        if np.abs(np.abs(G) - np.eye(3)).max() > 1e-9 or np.abs(ls.I - np.diag(np.diag(ls.I))).max() > 1e-9 * np.abs(ls.I).max():
            raise InputError(problems=[Problem(f"target_law {law}: the per-axis mapping needs wheel i along base axis i and a "
                                               "diagonal locked inertia (A = I, Vicariotto 2023 L762)", field="synthesis.pd.target_law",
                                               hint="write the gains in simulation.attitude instead")])
        lam = np.abs(np.diag(ls.Lambda))
        X = np.diag(ls.Lambda.T @ ls.M_theta_wheels)
    wz = 2.0 * float(pd.damping) * float(pd.bandwidth)
    if law == "wheels_free_floating":
        return {"law": law, "kp": (kp / lam).tolist(), "kd": (kd * lam).tolist()}
    if law == "inertia_shaping":
        return {"law": "wheels_free_floating", "inertia_shaping": True, "kp": kp.tolist(), "kd": (kd * lam**2).tolist()}
    if law == "free_flying":
        return {"law": law, "kp": kp.tolist(), "kd_base": kd.tolist(), "kd_wheels": (wz * X).tolist()}
    if law == "hierarchical":
        return {"law": law, "kp": kp.tolist(), "kd_base": kd.tolist(), "kd_wheels": (kd * lam**2).tolist(),
                "mu_threshold": float(pd.mu_threshold)}
    return {"law": "se3_pd", "kp": kp.tolist(), "kd": kd.tolist()}
