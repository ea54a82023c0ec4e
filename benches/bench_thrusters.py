"""Real thrusters (sms_cli.thrusters): µs per allocation solve (HiGHS LP, 24-thruster cube, random
6-D and torque-only wrenches inside its reach, and saturated ones out of it: the reach LP and the minimum-thrust
LP at the scaled command), persistent HiGHS against fresh linprog calls, and µs per plant step of a thruster mission (allocation + modulation +
piecewise plant + propellant) against the same mission with the ideal torque source, in the same run
and the same loop (the Python loop with the compiled plant step); the ideal mission in the compiled
loop is shown for reference. Each simulation runs twice; the second run is reported.

Usage: python benches/bench_thrusters.py [mission.yaml]   (default missions/vicariotto_s3c_free_flying.yaml,
Vicariotto 2023 S3c: the free-flying Lyapunov law with the 24-thruster cube; tests/data/thrusters_cube.yaml is
the MRP law on Basilisk's hub). The ideal-torque run removes the thrusters: section, so the law's wrench is
applied exactly.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sms_cli.mission.load import load_mission  # noqa: E402
from sms_cli.model import compile_system  # noqa: E402
from sms_cli.sim.compiled.plant import CompiledPlant  # noqa: E402
from sms_cli.sim.engine import Simulation  # noqa: E402
from sms_cli.thrusters.allocation import Allocator  # noqa: E402
from sms_cli.thrusters.modulation import on_times  # noqa: E402


def _wrenches(ts, n: int) -> dict:
    """Command sets [f; n] (N, N m): inside the cube's reach (random 6-D, torque only) and out of it (random 6-D
    at 1.5 to 5 times the bound Σ |b_i| F_i on any reachable |w|; a direction turning by 0.05 rad per command at
    twice that bound, as successive control ticks of a saturated mission)."""
    rng = np.random.default_rng(0)
    big = float(np.linalg.norm(ts.B, axis=0) @ ts.max_force)
    u, v = np.linalg.qr(rng.normal(size=(6, 2)))[0].T
    return {"6-D wrench": [np.concatenate([rng.uniform(-40, 40, 3), rng.uniform(-60, 60, 3)]) for _ in range(n)],
            "torque only": [np.concatenate([np.zeros(3), rng.uniform(-60, 60, 3)]) for _ in range(n)],
            "saturated": [d / np.linalg.norm(d) * big * rng.uniform(1.5, 5) for d in rng.normal(size=(n, 6))],
            "sat. turning": [2 * big * (np.cos(0.05 * k) * u + np.sin(0.05 * k) * v) for k in range(n)]}


def bench_allocation(ts, n: int = 300, warm: bool = True, repeats: int = 3, allocator=None) -> dict:
    """µs of CPU (process_time: the machine may be shared) per allocation + modulation, best of ``repeats``
    passes over each command set, and the fraction of saturated commands; ``allocator`` the class (A/B runs)."""
    alloc = (allocator or Allocator)(ts.B, ts.max_force, warm=warm)
    out = {}
    for label, ws in _wrenches(ts, n).items():
        sat = sum(alloc.solve(w).saturated for w in ws) / n
        best = np.inf
        for _ in range(repeats):
            t0 = time.process_time()
            for w in ws:
                on_times(alloc.solve(w).thrust, ts.max_force, ts.firing_cycle, ts.mib, ts.quantization)
            best = min(best, time.process_time() - t0)
        out[label] = (1e6 * best / n, sat)
    return out


def run(path: Path, thrusters: bool, python_loop: bool) -> tuple[float, int, str]:
    loaded = load_mission(path)
    sm = compile_system(loaded)
    if not thrusters:
        sm.thrusters = None
    spec = loaded.mission.simulation
    best = None
    for _ in range(2):
        sim = Simulation(sm, spec, recorder=None, progress=False)
        if python_loop and sim.compiled_loop:
            sim.compiled_loop, sim.plant = False, CompiledPlant(sm)
        t0 = time.perf_counter()
        res = sim.run()
        wall = time.perf_counter() - t0
        best = (1e6 * wall / res.steps, res.steps, res.timing["engine"])
        sm = compile_system(loaded)  # fresh masses (the thruster run spent propellant)
        if not thrusters:
            sm.thrusters = None
    return best


def main() -> None:
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "missions" / "vicariotto_s3c_free_flying.yaml"
    sm = compile_system(load_mission(path))
    print(f"mission {path.name}: {sm.thrusters.n} thrusters")
    for warm, how in ((True, "persistent HiGHS, warm start"), (False, 'linprog(method="highs")')):
        for label, (us, sat) in bench_allocation(sm.thrusters, warm=warm).items():
            print(f"  allocation + modulation, {label:<12} {us:8.1f} µs/solve CPU ({how}; {100 * sat:3.0f}% saturated)")
    thr = run(path, True, True)
    ideal = run(path, False, True)
    ideal_c = run(path, False, False)
    print(f"  thrusters       {thr[0]:8.1f} µs/plant step  ({thr[1]} steps, {thr[2]})")
    print(f"  ideal torques   {ideal[0]:8.1f} µs/plant step  ({ideal[1]} steps, {ideal[2]})")
    print(f"  ideal torques   {ideal_c[0]:8.1f} µs/plant step  ({ideal_c[1]} steps, {ideal_c[2]})")
    print(f"  thrusters / ideal (same loop): {thr[0] / ideal[0]:.2f}; thruster cost {thr[0] - ideal[0]:.1f} µs/plant step "
          f"against the dynamics and law's {ideal[0]:.1f} µs/plant step")


if __name__ == "__main__":
    main()
