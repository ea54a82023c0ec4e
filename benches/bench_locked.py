"""Cost of the locked velocity μ (``/momentum/locked``, sms_cli/dynamics/locked.py) in the recordings.

    .venv/bin/python benches/bench_locked.py [--repeat 3]

1. µs per sample of μ itself: the stack path of the compiled loop (``locked_velocities``: one mass matrix
   per block when it does not depend on q, as for balanced rotors on the base; one CRBA per sample
   otherwise) and the per-sample path of the Python loop (``locked_velocity``: CRBA + two 3×3 solves).
2. The compiled loop's recording on Basilisk's RW scenario (missions/basilisk_rw_reference.yaml, 6000 plant
   steps, MCAP every step), timed in ``CompiledSimulation._record`` (selection, poses, μ, encoding), with
   the topic and with it removed (μ not computed, topic not written): the difference is its cost per step.
Best of ``--repeat`` runs, wall time, 2 cores shared.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]


def _per_sample(repeat: int) -> None:
    from sms_cli.dynamics.locked import locked_velocities, locked_velocity, shape_invariant
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    for name, n in (("basilisk_rw_reference", 6000), ("caldera_s1_slew", 2000), ("pulsar_simple", 1000)):
        sm = compile_system(load_mission(ROOT / "missions" / f"{name}.yaml"))
        rng = np.random.default_rng(0)
        qs = np.array([pin.integrate(sm.model, sm.q0, 0.3 * rng.normal(size=sm.nv)) for _ in range(n)])
        vs = rng.normal(size=(n, sm.nv))
        best_stack = best_one = np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            locked_velocities(sm, qs, vs)
            best_stack = min(best_stack, time.perf_counter() - t0)
            t0 = time.perf_counter()
            for i in range(n):
                locked_velocity(sm, qs[i], vs[i], np.zeros(sm.n_modes))
            best_one = min(best_one, time.perf_counter() - t0)
        print(f"{name:<24} nv {sm.nv:>2} modes {sm.n_modes:>2}  stack path {1e6 * best_stack / n:6.2f} µs/sample"
              f" ({'one mass matrix per block' if shape_invariant(sm) else 'CRBA per sample'}),"
              f" per-sample path {1e6 * best_one / n:6.2f} µs/sample")


@contextmanager
def _without_topic():
    """μ not computed and /momentum/locked not written (the recording before this topic)."""
    import sms_cli.recording.buffer as rb

    orig = rb.numeric_topics

    def topics(sm, **kw):
        kw["locked"] = None
        return orig(sm, **kw)

    import sms_cli.dynamics.locked as L

    orig_lv = L.locked_velocities
    L.locked_velocities = lambda sm, qs, vs: None
    rb.numeric_topics = topics
    try:
        yield
    finally:
        rb.numeric_topics = orig
        L.locked_velocities = orig_lv


def _recording(repeat: int) -> None:
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.model.summary import model_summary
    from sms_cli.sim.compiled.runner import CompiledSimulation
    from sms_cli.sim.engine import Simulation
    from sms_cli.recording.recorder import McapRecorder

    loaded = load_mission(ROOT / "missions" / "basilisk_rw_reference.yaml")
    spent = {"t": 0.0}
    orig = CompiledSimulation._record

    def timed(self, *a, **k):
        t0 = time.perf_counter()
        try:
            return orig(self, *a, **k)
        finally:
            spent["t"] += time.perf_counter() - t0

    CompiledSimulation._record = timed
    try:
        out = {}
        for label in ("with /momentum/locked", "without"):
            best = np.inf
            for _ in range(repeat):
                sm = compile_system(loaded)
                spec = loaded.mission.simulation
                with tempfile.TemporaryDirectory() as d:
                    rec = McapRecorder(Path(d) / "s.mcap", mission_text=loaded.text, mission_name=loaded.mission.name,
                                       model_summary=model_summary(sm), urdf_text=sm.urdf_text, versions={},
                                       record_rate_hz=spec.record_rate)
                    links = list(sm.link_parents)
                    rec.add_transform_tree(links, [sm.link_parents[n] for n in links])
                    spent["t"] = 0.0
                    if label == "without":
                        with _without_topic():
                            Simulation(sm, spec, rec, progress=False).run()
                    else:
                        Simulation(sm, spec, rec, progress=False).run()
                    rec.finish("completed")
                best = min(best, spent["t"])
            out[label] = best
            print(f"compiled loop, Basilisk scenario, recording {label:<22}: {1e6 * best / 6000:6.2f} µs/step")
        print(f"/momentum/locked adds {1e6 * (out['with /momentum/locked'] - out['without']) / 6000:.2f} µs per recorded step")
    finally:
        CompiledSimulation._record = orig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    _per_sample(args.repeat)
    _recording(args.repeat)


if __name__ == "__main__":
    main()
