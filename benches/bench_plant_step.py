"""µs per compiled RKMK4 plant step (``sms_cli.sim.compiled.dynamics.rkmk4_step``) on a mission's model.

    .venv/bin/python benches/bench_plant_step.py [missions/pulsar_simple.yaml ...] [--steps 20000] [--repeat 5]

Calls the kernel directly on the ``CompiledPlant`` arrays (no Python wrapper per step: a numba loop of
``--steps`` steps from q0 with a small constant torque), CPU time (``time.process_time``), best of
``--repeat``. Also prints the first call's CPU seconds of ``rkmk4_step`` alone (its compile time on a fresh
``NUMBA_CACHE_DIR``). 2 cores shared: compare A/B
interleaved.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from numba import njit

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("missions", nargs="*", default=["missions/pulsar_simple.yaml", "missions/basilisk_rw_reference.yaml"])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    from sms_cli.dynamics.integrator import State
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.sim.compiled.dynamics import rkmk4_step
    from sms_cli.sim.compiled.plant import _NONE, CompiledPlant

    @njit
    def run(n, t, md, sp, q, v, eta, ed, tau, dt, q2, v2, e2, ed2, ws, locked):
        for _ in range(n):
            rkmk4_step(t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], t[9], md[0], md[1], md[2], md[3],
                       sp[0], sp[1], sp[2], sp[3], sp[4], q, v, eta, ed, tau, dt, q2, v2, e2, ed2, ws, locked)
            q[:] = q2
            v[:] = v2
            eta[:] = e2
            ed[:] = ed2

    for m in a.missions:
        sm = compile_system(load_mission(ROOT / m))
        P = CompiledPlant(sm)
        q, v = sm.q0.astype(float).copy(), np.zeros(sm.nv)
        eta, ed = np.zeros(sm.n_modes), np.zeros(sm.n_modes)
        tau = 0.01 * np.ones(sm.nv)
        args = (P._tree, P._modal, P._springs)
        t0 = time.process_time()
        P.step(State(q, v, eta, ed), tau, 0.01)  # compiles (or loads) rkmk4_step alone
        first = time.process_time() - t0
        run(1, *args, q.copy(), v.copy(), eta.copy(), ed.copy(), tau, 0.01, q.copy(), v.copy(), eta.copy(), ed.copy(), P._ws, _NONE)
        best = np.inf
        for _ in range(a.repeat):
            qq, vv, ee, dd = q.copy(), v.copy(), eta.copy(), ed.copy()
            t0 = time.process_time()
            run(a.steps, *args, qq, vv, ee, dd, tau, 0.01, q.copy(), v.copy(), eta.copy(), ed.copy(), P._ws, _NONE)
            best = min(best, time.process_time() - t0)
        print(f"{Path(m).stem:<26} n {P._tree[0].size:>2} nv {sm.nv:>2} modes {sm.n_modes:>2}  "
              f"{1e6 * best / a.steps:6.2f} µs/step (CPU, best of {a.repeat})  rkmk4_step first call {first:5.1f} s CPU  "
              f"|q| {np.linalg.norm(qq):.15g} |v| {np.linalg.norm(vv):.15g}")


if __name__ == "__main__":
    main()
