"""LMI synthesis solve time against LMI size (seed 004 Table 4.3: YALMIP + MOSEK, 35 s at size 10,
245 s at 50, 833 s at 154), and the pulsar_simple synthesis time.

Size = rows of the thesis's Ω = 3 n_q + n_e (n_q actuators, n_e = 2 n_modes + 3 observer states).
Problems: random physically shaped mass matrices (tests/test_synthesis_lmi.py's generator),
one linearisation, relaxation 'none' (the structured, exactly decoupled form of lmi.py), solved
by the dedicated interior-point solver (sdp.py); Clarabel through cvxpy is timed on the small
sizes and on pulsar_simple for comparison (same run, same load).
A dense 1000×1000 Cholesky is timed first so that numbers from different machines compare.

    python benches/bench_synthesis.py            # sizes up to ~40 and pulsar_simple (a few minutes)
    python benches/bench_synthesis.py --full     # up to size 147 or until one solve exceeds --limit s
    python benches/bench_synthesis.py --clarabel # also cvxpy + Clarabel on pulsar and the small sizes
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def calibration() -> float:
    a = np.random.default_rng(0).normal(size=(1000, 1000))
    a = a @ a.T + 1000 * np.eye(1000)
    t = time.perf_counter()
    for _ in range(5):
        np.linalg.cholesky(a)
    return (time.perf_counter() - t) / 5


def one(n_q: int, n_modes: int, solver: str = "auto") -> dict:
    from test_synthesis_lmi import toy_model

    from sms_cli.synthesis.lmi import SynthesisRequest, ellipsoid_from_box, synthesize
    from sms_cli.synthesis.regions import PoleRegion
    from sms_cli.synthesis.verify import verify_lmi

    scales = [1e3] * 3 + [2e3] * 3 + list(np.geomspace(0.1, 50.0, n_q))
    m = toy_model(scales, n_modes=n_modes, seed=n_q + 7 * n_modes)
    b = [0.05] * n_modes + [0.01] * 3 + [0.05] * n_modes
    req = SynthesisRequest([m], PoleRegion(0.3, 0.5, 5.0), PoleRegion(0.1, 0.0, 40.0), ellipsoid_from_box(b),
                           relaxation="none")
    t = time.perf_counter()
    res = synthesize(req, diagnose=False, solver=solver)
    total = time.perf_counter() - t
    ok = verify_lmi(req, res).passed
    return {"n_q": n_q, "n_modes": n_modes, "size": 3 * n_q + m.n_e, "solve_s": res.solve_time, "total_s": total,
            "verified": ok, "gamma": res.gamma, "solver": res.solver}


def pulsar(solver: str = "auto") -> dict:
    """The synthesize stage on pulsar_simple (solve, verification, gains.yaml; no plot)."""
    import tempfile

    from sms_cli.mission.load import load_mission
    from sms_cli.synthesis import lmi
    from sms_cli.synthesis.stage import run_synthesis

    original = lmi.synthesize
    lmi.synthesize = lambda req, diagnose=True, solver_=solver: original(req, diagnose, solver_)
    try:
        with tempfile.TemporaryDirectory() as d:
            sec = run_synthesis(load_mission(ROOT / "missions" / "pulsar_simple.yaml"), d, plots=False)
    finally:
        lmi.synthesize = original
    return {"size": sec["lmi"]["size"], "linearisations": sec["robustness"]["linearisations"],
            "solve_s": sec["lmi"]["solve_time_s"], "verify_s": sec["lmi"]["verify_time_s"],
            "total_s": sec["total_time_s"], "gamma": sec["gamma"], "solver": sec["lmi"]["solver"],
            "verified": sec["verification"]["passed"]}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--full", action="store_true", help="long sweep (sizes up to 147)")
    ap.add_argument("--limit", type=float, default=600.0, help="stop the sweep after a solve longer than this (s)")
    ap.add_argument("--no-pulsar", action="store_true")
    ap.add_argument("--clarabel", action="store_true", help="also time cvxpy + Clarabel (pulsar and sizes ≤ 36)")
    args = ap.parse_args()
    print(f"calibration: dense Cholesky 1000×1000 = {calibration() * 1e3:.1f} ms (≈10–20 ms on an idle laptop)")
    if not args.no_pulsar:
        for solver in ("auto", "clarabel") if args.clarabel else ("auto",):
            p = pulsar(solver)
            print(f"pulsar_simple [{p['solver']}]: size {p['size']}, {p['linearisations']} linearisation(s), "
                  f"solve {p['solve_s']:.2f} s, verify {p['verify_s']:.2f} s, stage total {p['total_s']:.2f} s, "
                  f"γ = {p['gamma']:.4g}, verified {p['verified']}", flush=True)
    cases = [(2, 1), (3, 2), (5, 4), (6, 8), (9, 10)]
    if args.full:
        # the dense coefficient storage of sdp.py grows as n_e⁴ (≈ 0.6 GB at n_e = 75): beyond
        # that the structured Kronecker form of the Schur complement would be needed
        cases += [(12, 14), (14, 22), (20, 30), (24, 36)]
    print(f"{'n_q':>4}{'modes':>6}{'size':>6}{'solve s':>10}{'total s':>10}{'γ':>10}  verified  solver"
          "   (seed 004 MOSEK: 35 s @10, 245 s @50, 833 s @154)")
    for n_q, n_m in cases:
        for solver in ("auto", "clarabel") if args.clarabel and n_q <= 9 else ("auto",):
            r = one(n_q, n_m, solver)
            print(f"{r['n_q']:>4}{r['n_modes']:>6}{r['size']:>6}{r['solve_s']:>10.2f}{r['total_s']:>10.2f}"
                  f"{r['gamma']:>10.4g}  {str(r['verified']):<9} {r['solver']}", flush=True)
        if r["solve_s"] > args.limit:
            print(f"stopping: solve time above {args.limit:g} s")
            break


if __name__ == "__main__":
    main()
