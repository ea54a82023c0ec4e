"""µs per plant step and real-time factor of the two-spacecraft missions (Vicariotto 2023 ch. 5), whole
``sms simulate`` path with recording (MCAP, relative_motion.csv, plots excluded), with the cost split between
the plant step (RKMK4 of both free-flyers: ABA, the internal pair's reaction and the capture interface at every
stage), the law (locked/shape state, C*, potentials) and sampling/recording. The issue's target for S6:
≥ 200× real time. CPU time is printed next to wall time (the machine may be shared); each mission runs twice and
the second run is reported. ``--integrator decomposed`` runs them on Vicariotto's HIL integrator instead.

Usage: python benches/bench_formation.py [mission.yaml ...] [--integrator decomposed]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sms_cli.formation import simulate as fsim  # noqa: E402
from sms_cli.formation.stage import prepared  # noqa: E402
from sms_cli.formation.urdf_pair import pair_urdf  # noqa: E402
from sms_cli.formation.stage import root_link  # noqa: E402
from sms_cli.mission.load import load_mission, load_mission_text  # noqa: E402
from sms_cli.recording.recorder import McapRecorder  # noqa: E402
from sms_cli.sim.stage import versions  # noqa: E402

MISSIONS = ["vicariotto_s6_relative_hil", "vicariotto_s6_thrusters", "vicariotto_s4_relative_free_flying",
            "caldera_capture_tumbling"]
TARGET = {"vicariotto_s6_relative_hil": 200.0}  # the real-time target


class Spent:
    """CPU time accumulated inside wrapped methods."""

    def __init__(self):
        self.s = {"plant": 0.0, "law": 0.0, "state+sample": 0.0}

    def wrap(self, key, fn):
        clock, s = time.process_time, self.s

        def timed(*a, **k):
            t0 = clock()
            try:
                return fn(*a, **k)
            finally:
                s[key] += clock() - t0

        return timed


def run_once(path: Path, integrator: str | None) -> dict:
    loaded = load_mission(path)
    if integrator:
        loaded = load_mission_text(f"extends: {path}\nformation: {{integrator: {integrator}}}\n", base_dir=path.parent,
                                   name=f"{path.stem}_{integrator}.yaml")
    servicer, client = prepared(loaded)
    sim = fsim.FormationSimulation(loaded.mission, servicer, client, None, False, loaded.source.locate)
    spent = Spent()
    sim.step = spent.wrap("plant", sim.step)
    law_call = fsim.RelativeLaw.__call__
    fsim.RelativeLaw.__call__ = spent.wrap("law", law_call)
    sim.body_states = spent.wrap("state+sample", sim.body_states)
    sim._sample = spent.wrap("state+sample", sim._sample)
    with tempfile.TemporaryDirectory() as tmp:
        rec = McapRecorder(Path(tmp) / "run.mcap", mission_text=loaded.text, mission_name=loaded.mission.name,
                           model_summary={}, urdf_text=pair_urdf([(b.name, b.system.urdf_text, root_link(b.system))
                                                                  for b in sim.plant.bodies]),
                           versions=versions(), record_rate_hz=None)
        rec.add_transform_tree(sim.links.names, sim.links.parents)
        sim.recorder = rec
        w0, c0 = time.perf_counter(), time.process_time()
        try:
            with rec:
                res = sim.run()
                rec.finish(res.status)
        finally:
            fsim.RelativeLaw.__call__ = law_call
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    n = max(res.steps, 1)
    split = {k: 1e6 * v / n for k, v in spent.s.items()}
    split["other"] = 1e6 * cpu / n - sum(split.values())
    return {"mission": path.stem, "steps": res.steps, "dt": float(loaded.mission.formation.dt), "sim_s": res.t_end,
            "wall_us": 1e6 * wall / n, "cpu_us": 1e6 * cpu / n, "rtf_wall": res.t_end / wall, "rtf_cpu": res.t_end / cpu,
            **split}


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    integrator = sys.argv[sys.argv.index("--integrator") + 1] if "--integrator" in sys.argv else None
    if integrator:
        args = [a for a in args if a != integrator]
    paths = [Path(a).resolve() for a in args] or [ROOT / "missions" / f"{m}.yaml" for m in MISSIONS]
    print(f"two-spacecraft missions, {integrator or 'plain'} integrator, recording on; µs per plant step (CPU unless "
          "noted); RTF = simulated / elapsed time")
    print(f"{'mission':<36}{'steps':>7}{'dt':>7}{'wall':>8}{'cpu':>8}{'RTF wall':>10}{'RTF cpu':>9}"
          f"{'plant':>8}{'law':>7}{'state+rec':>10}{'other':>7}  target")
    for p in paths:
        run_once(p, integrator)  # first run: numba kernels loaded/compiled, caches warm
        r = run_once(p, integrator)
        target = TARGET.get(r["mission"])
        verdict = "" if target is None else (f"≥ {target:g}x: {'met' if r['rtf_wall'] >= target else 'NOT met'} "
                                             f"({r['rtf_wall'] / target:.2f} of it)")
        print(f"{r['mission']:<36}{r['steps']:>7}{r['dt']:>7.3g}{r['wall_us']:>8.1f}{r['cpu_us']:>8.1f}"
              f"{r['rtf_wall']:>10.1f}{r['rtf_cpu']:>9.1f}{r['plant']:>8.1f}{r['law']:>7.1f}{r['state+sample']:>10.1f}"
              f"{r['other']:>7.1f}  {verdict}", flush=True)


if __name__ == "__main__":
    main()
