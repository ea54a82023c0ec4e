"""Per-call cost of the SystemModel's dynamics on pulsar_simple (15 DoF + 10 modes).

Prints µs per call of: mass matrix with modes, bias forces, forward dynamics with modes, and
the Pinocchio calls alone (crba + nonLinearEffects + aba) as the floor.
Usage: python benches/bench_model.py [mission.yaml]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sms_cli.mission.load import load_mission  # noqa: E402
from sms_cli.model import compile_system  # noqa: E402


def per_call_us(fn, n: int) -> float:
    fn()
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def main() -> None:
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "missions" / "pulsar_simple.yaml"
    sm = compile_system(load_mission(path))
    rng = np.random.default_rng(0)
    q = sm.q0.copy()
    v = rng.normal(size=sm.nv) * 0.01
    eta = rng.normal(size=sm.n_modes) * 0.01
    etadot = rng.normal(size=sm.n_modes) * 0.01
    tau = rng.normal(size=sm.nv)
    m, d = sm.model, sm.data
    n = 2000
    rows = [
        ("mass_matrix (with modes)", per_call_us(lambda: sm.mass_matrix(q), n)),
        ("bias_forces (with modes)", per_call_us(lambda: sm.bias_forces(q, v, etadot), n)),
        ("forward_dynamics (with modes)", per_call_us(lambda: sm.forward_dynamics(q, v, eta, etadot, tau), n)),
        ("floor: pin.crba", per_call_us(lambda: pin.crba(m, d, q), n)),
        ("floor: pin.nonLinearEffects", per_call_us(lambda: pin.nonLinearEffects(m, d, q, v), n)),
        ("floor: pin.aba (rigid)", per_call_us(lambda: pin.aba(m, d, q, v, tau), n)),
    ]
    print(f"{sm.name}: nq={sm.nq} nv={sm.nv} modes={sm.n_modes} (numpy {np.__version__}, pinocchio {pin.__version__})")
    for label, us in rows:
        print(f"  {label:<34} {us:8.2f} µs/call")
    total = rows[0][1] + rows[1][1] + rows[2][1]
    floor = rows[3][1] + rows[4][1] + rows[5][1]
    print(f"  M + bias + FD with modes          {total:8.2f} µs  (Pinocchio floor {floor:.2f} µs, ratio {total / floor:.1f}×)")


if __name__ == "__main__":
    main()
