"""µs per simulated step and real-time factor of every shipped mission with a simulation, with the
cost split between plant (RKMK4 + dynamics), controller (sensors, references, laws, actuators),
recording (MCAP) and metrics. CPU time (process_time) is reported next to wall time because
the machine may be shared. The engine column says which loop ran (simulation.engine: auto);
for the compiled engine the whole loop is one kernel call, so "plant" holds plant, controller
and per-tick trace together, "metrics" the summary. Each mission runs twice; the second run is
reported (the first loads the compiled kernels, and compiles them on a cold cache). Engines:
compiled = the compiled loop; py+plant = the Python loop with the compiled plant step;
python = Python and Pinocchio only (simulation.engine: python).

Usage: python benches/bench_simulate.py [mission.yaml ...] [--no-record]
"""

from __future__ import annotations

import atexit
import functools
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sms_cli.sim.compiled.loop as compiled_loop  # noqa: E402
import sms_cli.sim.engine as engine  # noqa: E402
from sms_cli.sim.compiled.plant import CompiledPlant  # noqa: E402
from sms_cli.sim.compiled.runner import CompiledSimulation  # noqa: E402
from sms_cli.mission.load import load_mission  # noqa: E402
from sms_cli.model import compile_system  # noqa: E402
from sms_cli.model.summary import model_summary  # noqa: E402
from sms_cli.recording.recorder import McapRecorder  # noqa: E402
from sms_cli.sim.stage import planned_simulation, versions  # noqa: E402
from sms_cli.synthesis.stage import run_synthesis  # noqa: E402


class Timer:
    """Accumulates CPU time spent inside wrapped callables."""

    def __init__(self):
        self.spent = {"plant": 0.0, "controller": 0.0, "recording": 0.0, "metrics": 0.0}

    def wrap(self, key, fn):
        spent = self.spent
        clock = time.process_time

        @functools.wraps(fn)  # __wrapped__: the warm-up sees the kernel behind it (warmup.cached), not a cold one
        def timed(*a, **k):
            t0 = clock()
            try:
                return fn(*a, **k)
            finally:
                spent[key] += clock() - t0

        return timed


GAINS = Path(tempfile.mkdtemp(prefix="sms_bench_gains_"))
atexit.register(shutil.rmtree, GAINS, True)


def gains_for(loaded, path: Path) -> Path | None:
    """The folder holding the mission's gains.yaml when its simulation reads synthesized gains (NDI,
    attitude: from_gains): synthesized once here (not timed), as `sms run` does."""
    spec = loaded.mission.simulation
    if loaded.mission.synthesis is None or not (spec.ndi is not None or spec.attitude == "from_gains"):
        return None
    out = GAINS / path.stem
    if not (out / "gains.yaml").exists():
        run_synthesis(loaded, out, plots=False)
    return out


def bench(path: Path, record: bool) -> dict:
    loaded = load_mission(path)
    sm = compile_system(loaded)
    spec, _ = planned_simulation(sm, loaded)  # phases of duration 'auto' sized as `sms simulate` does
    results_dir = gains_for(loaded, path)
    timer = Timer()
    orig_step = engine.rkmk4_step
    engine.rkmk4_step = timer.wrap("plant", orig_step)
    cls = engine.Simulation
    saved = {name: getattr(cls, name) for name in ("_control", "_record", "_trace")}
    cls._control = timer.wrap("controller", saved["_control"])
    cls._record = timer.wrap("recording", saved["_record"])
    cls._trace = timer.wrap("metrics", saved["_trace"])
    orig_kernel, orig_crec, orig_result = compiled_loop.run_ticks, CompiledSimulation._record, engine.build_result
    orig_plant = CompiledPlant.step
    CompiledPlant.step = timer.wrap("plant", orig_plant)
    compiled_loop.run_ticks = timer.wrap("plant", orig_kernel)
    CompiledSimulation._record = timer.wrap("recording", orig_crec)
    engine.build_result = timer.wrap("metrics", orig_result)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            rec = None
            if record:
                rec = McapRecorder(Path(tmp) / "run.mcap", mission_text=loaded.text, mission_name=loaded.mission.name,
                                   model_summary=model_summary(sm), urdf_text=sm.urdf_text, versions=versions(),
                                   record_rate_hz=spec.record_rate)
                links = list(sm.link_parents)
                rec.add_transform_tree(links, [sm.link_parents[n] for n in links])
            sim = cls(sm, spec, rec, False, results_dir=results_dir, mission_dir=path.parent)
            sim.sensors.measure = timer.wrap("controller", sim.sensors.measure)
            w0, c0 = time.perf_counter(), time.process_time()
            if rec is not None:
                with rec:
                    res = sim.run()
                    rec.finish(res.status)
            else:
                res = sim.run()
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    finally:
        engine.rkmk4_step = orig_step
        compiled_loop.run_ticks, CompiledSimulation._record, engine.build_result = orig_kernel, orig_crec, orig_result
        CompiledPlant.step = orig_plant
        for name, fn in saved.items():
            setattr(cls, name, fn)
    n = max(res.steps, 1)
    split = {k: 1e6 * v / n for k, v in timer.spent.items()}
    split["other"] = 1e6 * cpu / n - sum(split.values())
    return {"mission": path.stem, "engine": res.timing["engine"], "steps": res.steps, "dt": spec.dt, "sim_s": res.t_end, "wall_us": 1e6 * wall / n,
            "cpu_us": 1e6 * cpu / n, "rtf_cpu": res.t_end / cpu, "rtf_wall": res.t_end / wall, **split}


def _simulates(mission) -> bool:
    """A mission with a simulation that is not a campaign definition (campaigns run many missions)."""
    return mission.simulation is not None and getattr(mission, "campaign", None) is None


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    record = "--no-record" not in sys.argv
    paths = [Path(a) for a in args] or sorted(p for p in (ROOT / "missions").glob("*.yaml")
                                              if _simulates(load_mission(p).mission))
    print(f"recording {'on' if record else 'off'}; µs per plant step (CPU unless noted); RTF = simulated / elapsed time")
    head = f"{'mission':<28}{'engine':>10}{'steps':>7}{'dt':>7}{'wall':>8}{'cpu':>8}{'RTF cpu':>9}{'RTF wall':>9}" \
           f"{'plant':>8}{'control':>9}{'record':>8}{'metrics':>9}{'other':>8}"
    print(head)
    for p in paths:
        bench(p, record)
        r = bench(p, record)
        short = {"compiled": "compiled", "python": "python", "python, compiled plant": "py+plant"}[r["engine"]]
        print(f"{r['mission']:<28}{short:>10}{r['steps']:>7}{r['dt']:>7.3g}{r['wall_us']:>8.1f}{r['cpu_us']:>8.1f}{r['rtf_cpu']:>9.1f}"
              f"{r['rtf_wall']:>9.1f}{r['plant']:>8.1f}{r['controller']:>9.1f}{r['recording']:>8.1f}{r['metrics']:>9.1f}"
              f"{r['other']:>8.1f}")


if __name__ == "__main__":
    main()
