"""LMI synthesis solve time against LMI size (seed 004 Table 4.3: YALMIP + MOSEK, 35 s at size 10,
245 s at 50, 833 s at 154), and the pulsar_simple synthesis time.

Size = rows of the thesis's Ω = 3 n_q + n_e (n_q actuators, n_e = 2 n_modes + 3 observer states).
Problems: random physically shaped mass matrices (tests/test_synthesis_lmi.py's generator),
one linearisation, relaxation 'none' (the structured, exactly decoupled form of lmi.py).
A dense 1000×1000 Cholesky is timed first so that numbers from different machines compare.

    python benches/bench_synthesis.py            # sizes up to ~40 and pulsar_simple (a few minutes)
    python benches/bench_synthesis.py --full     # up to size ~160 or until one solve exceeds --limit s
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


def one(n_q: int, n_modes: int) -> dict:
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
    res = synthesize(req, diagnose=False)
    total = time.perf_counter() - t
    ok = verify_lmi(req, res).passed
    return {"n_q": n_q, "n_modes": n_modes, "size": 3 * n_q + m.n_e, "solve_s": res.solve_time, "total_s": total,
            "verified": ok}


def pulsar() -> dict:
    from sms_cli.mission.load import load_mission
    from sms_cli.synthesis.stage import run_synthesis
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        sec = run_synthesis(load_mission(ROOT / "missions" / "pulsar_simple.yaml"), d, plots=False)
    return {"size": sec["lmi"]["size"], "linearisations": sec["robustness"]["linearisations"],
            "solve_s": sec["lmi"]["solve_time_s"], "total_s": sec["total_time_s"], "gamma": sec["gamma"],
            "verified": sec["verification"]["passed"]}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--full", action="store_true", help="long sweep (sizes up to ~160)")
    ap.add_argument("--limit", type=float, default=600.0, help="stop the sweep after a solve longer than this (s)")
    ap.add_argument("--no-pulsar", action="store_true")
    args = ap.parse_args()
    print(f"calibration: dense Cholesky 1000×1000 = {calibration() * 1e3:.1f} ms (≈10–20 ms on an idle laptop)")
    cases = [(2, 1), (3, 2), (5, 4), (6, 8), (9, 10)]
    if args.full:
        cases += [(12, 14), (14, 22), (20, 30), (30, 40), (40, 55)]
    print(f"{'n_q':>4}{'modes':>6}{'size':>6}{'solve s':>10}{'total s':>10}  verified   (seed 004 MOSEK: 35 s @10, 245 s @50, 833 s @154)")
    for n_q, n_m in cases:
        r = one(n_q, n_m)
        print(f"{r['n_q']:>4}{r['n_modes']:>6}{r['size']:>6}{r['solve_s']:>10.2f}{r['total_s']:>10.2f}  {r['verified']}", flush=True)
        if r["solve_s"] > args.limit:
            print(f"stopping: solve time above {args.limit:g} s")
            break
    if not args.no_pulsar:
        p = pulsar()
        print(f"pulsar_simple: size {p['size']}, {p['linearisations']} linearisation(s), solve {p['solve_s']:.2f} s, "
              f"total {p['total_s']:.2f} s, γ = {p['gamma']:.4g}, verified {p['verified']}")


if __name__ == "__main__":
    main()
