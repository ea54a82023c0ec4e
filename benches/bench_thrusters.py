"""Real thrusters (sms_cli.thrusters): µs per allocation solve (HiGHS LP, 24-thruster cube, random
6-D and torque-only wrenches), and µs per plant step of a thruster mission (allocation + modulation +
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


def bench_allocation(ts, n: int = 500, warm: bool = True) -> dict:
    alloc = Allocator(ts.B, ts.max_force, warm=warm)
    rng = np.random.default_rng(0)
    out = {}
    for label, make in (("6-D wrench", lambda: np.concatenate([rng.uniform(-40, 40, 3), rng.uniform(-60, 60, 3)])),
                        ("torque only", lambda: np.concatenate([np.zeros(3), rng.uniform(-60, 60, 3)]))):
        ws = [make() for _ in range(n)]
        alloc.solve(ws[0])
        t0 = time.perf_counter()
        for w in ws:
            on_times(alloc.solve(w).thrust, ts.max_force, ts.firing_cycle, ts.mib, ts.quantization)
        out[label] = 1e6 * (time.perf_counter() - t0) / n
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
        for label, us in bench_allocation(sm.thrusters, warm=warm).items():
            print(f"  allocation + modulation, {label:<12} {us:8.1f} µs/solve ({how})")
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
