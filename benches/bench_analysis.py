"""Benchmark of ``sms analyze`` on the Kraiem 2022 Demeter study (19^3 = 6859 samples over the half
workspace, nominal wheels and H_r -> 2 H_r), all index groups.

Reports (best of --repeat runs, one process, one core):
- floor: the Pinocchio calls alone (crba + computeFrameJacobian per sample, nothing stored),
  for one pass (6859 samples) and for the naive two-model study (2 x 6859);
- study: every index of both variants (configurations, Pinocchio loop, batched numpy; the
  doubled-wheel variant reuses the nominal CRBA with the exact rank-update, see workspace.py);
- samples per second and the ratio study / floor;
- figures (issue #19): ms per figure by kind, drawn one after the other in this process (the
  index maps of a variant share one figure, redrawn per column), and their sum;
- the whole command ``sms analyze missions/demeter_3dof.yaml -o DIR`` (22 figures, Parquet tables;
  a subprocess, best of --command-repeat) against the 3 s target, with the figure workers it used;
- a 2^20-sample Sobol study of Demeter (generated in a temporary folder) with ``--no-plots``:
  the whole command with Parquet tables and with ``--csv`` as well (best of --sobol-repeat),
  its wall time against the 10 s target, its CPU time (user + system, all threads) and its
  evaluation time (``timing.compute_s`` of results.json: sampling, Pinocchio and the compiled
  indices, on a thread of its own since the blocks are evaluated one ahead, so it overlaps the
  tables and statistics). The machine is shared: compare wall and CPU in one session.
Run: python benches/bench_analysis.py [--repeat 7] [--command-repeat 3] [--sobol-n 1048576]
     [--sobol-repeat 1] [--skip-command] [--skip-sobol] [--sobol-only]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pinocchio as pin

from sms_cli.analysis.schema import AnalysisSpec
from sms_cli.analysis.workspace import build_variants, evaluate_block, make_sampler
from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system

ROOT = Path(__file__).resolve().parents[1]
STUDY = {"sampling": {"method": "grid", "n": 19, "symmetry": {"joint": "joint_1", "keep": "upper", "about": 0}, "chunk": 8192},
         "variants": [{"name": "doubled_wheels", "wheel_inertia_scale": 2}]}


TARGET_COMMAND_S = 3.0
TARGET_SOBOL_S = 10.0


def sms_command() -> list[str]:
    """The ``sms`` console script of this interpreter, else ``python -m sms_cli.cli``."""
    script = Path(sys.executable).with_name("sms")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "sms_cli.cli"]


def timed_command(args: list[str], out: Path, repeat: int) -> tuple[float, dict, float]:
    """Best wall time of ``sms <args> -o out`` (a fresh folder each run), the results.json of that run
    and its CPU time (user + system, every thread of the command and its children)."""
    runs = []
    for _ in range(repeat):
        shutil.rmtree(out, ignore_errors=True)
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        subprocess.run(sms_command() + args + ["-o", str(out), "--no-progress"], check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
        runs.append((wall, json.loads((out / "results.json").read_text()), cpu))
    return min(runs, key=lambda r: r[0])


class SerialTimer:
    """A ``FigurePool`` stand-in that draws every job here, in order, and times it per figure kind."""

    def __init__(self):
        self.cost: dict[str, list[float]] = defaultdict(list)

    def run(self, jobs):
        out = []
        for fn, args in jobs:
            kind = args[1].__name__ if fn.__name__ == "_figure" else fn.__name__
            figures = 1 if fn.__name__ == "_figure" else len(args[1])
            t = time.perf_counter()
            out.append(fn(*args))
            self.cost[kind].append((time.perf_counter() - t, figures))
        return out


def figure_costs(mission: Path) -> None:
    from sms_cli.analysis.stage import analyze_mission
    from sms_cli.report import figstyle

    figstyle.warm_up()
    loaded = load_mission(mission)
    with tempfile.TemporaryDirectory() as tmp:
        analyze_mission(loaded, Path(tmp), plots=True, pool=SerialTimer())  # first figures of the process
        timer = SerialTimer()
        analyze_mission(loaded, Path(tmp), plots=True, pool=timer)
    label = {"clouds": "index maps (8 per variant, one figure)", "histograms_png": "histograms",
             "slices_png": "slices", "compare_figures": "variant comparison maps"}
    total_s, total_n = 0.0, 0
    print("Figures of `sms analyze` on it, drawn in one process (ms per figure):")
    for kind, runs in timer.cost.items():
        t, n = sum(r[0] for r in runs), sum(r[1] for r in runs)
        total_s, total_n = total_s + t, total_n + n
        print(f"  {label.get(kind, kind):40s}: {t / n * 1e3:6.0f} ms x {n:2d} = {t:5.2f} s")
    print(f"  {'all figures':40s}: {total_s / total_n * 1e3:6.0f} ms x {total_n:2d} = {total_s:5.2f} s")


def sobol_mission(folder: Path, n: int) -> Path:
    import yaml

    d = yaml.safe_load((ROOT / "missions" / "demeter_3dof.yaml").read_text())
    d["robot"]["urdf"] = str((ROOT / "missions" / d["robot"]["urdf"]).resolve())
    d["analysis"]["sampling"] = {"method": "sobol", "n": n}
    d.pop("requirements", None)
    p = folder / "demeter_sobol.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--command-repeat", type=int, default=3, help="runs of the whole sms analyze command (best kept)")
    ap.add_argument("--sobol-n", type=int, default=1 << 20, help="samples of the Sobol study")
    ap.add_argument("--sobol-repeat", type=int, default=1, help="runs of each Sobol command (best kept)")
    ap.add_argument("--skip-command", action="store_true", help="no whole-command timing")
    ap.add_argument("--skip-sobol", action="store_true", help="no Sobol study")
    ap.add_argument("--sobol-only", action="store_true", help="only the Sobol study's whole command, Parquet tables")
    args = ap.parse_args()
    if args.sobol_only:
        with tempfile.TemporaryDirectory() as tmp:
            sobol_commands(Path(tmp), args)
        return
    sm = compile_system(load_mission(ROOT / "missions" / "demeter_3dof.yaml"))
    spec = AnalysisSpec.model_validate(STUDY)
    sampler, sampled = make_sampler(sm, spec)
    variants = build_variants(sm, spec, sampled)
    samples = np.vstack(list(sampler.chunks()))
    n = len(samples)
    Q = variants[0].kernel.configurations(samples)
    model, data, fid = sm.model, sm.model.createData(), sm.ee_frame_id
    crba, jac, local = pin.crba, pin.computeFrameJacobian, pin.ReferenceFrame.LOCAL

    def floor():
        for q in Q:
            crba(model, data, q)
            jac(model, data, q, fid, local)

    def study():
        evaluate_block(variants, samples)

    def nominal_only():
        evaluate_block(variants[:1], samples)

    study()
    t_floor = best(floor, args.repeat)
    t_study = best(study, args.repeat)
    t_nom = best(nominal_only, args.repeat)
    Ms, Js = variants[0].kernel.pinocchio_terms(Q)
    t_loop = best(lambda: variants[0].kernel.pinocchio_terms(Q), args.repeat)
    t_batch = best(lambda: variants[0].kernel.from_terms(Q, Ms, Js), args.repeat)
    _, (nom, dbl) = evaluate_block(variants, samples)
    print(f"Demeter study: {n} samples x 2 variants, all index groups ({len(nom)} columns)")
    print(f"  floor, Pinocchio calls only, 1 pass      : {t_floor * 1e3:7.1f} ms  ({t_floor / n * 1e6:.2f} us/sample)")
    print(f"  floor, naive study (2 models x {n})    : {2 * t_floor * 1e3:7.1f} ms")
    print(f"  Pinocchio loop with storage (1 pass)     : {t_loop * 1e3:7.1f} ms")
    print(f"  batched indices, one variant             : {t_batch * 1e3:7.1f} ms")
    print(f"  nominal only, all indices                : {t_nom * 1e3:7.1f} ms  = {t_nom / t_floor:.2f} x the 1-pass floor")
    print(f"  whole study (nominal + doubled wheels)   : {t_study * 1e3:7.1f} ms  = {t_study / (2 * t_floor):.2f} x the naive floor,"
          f" {t_study / t_floor:.2f} x the 1-pass floor")
    print(f"  throughput                               : {2 * n / t_study:,.0f} variant-samples/s")
    print(f"  K_m worst case: nominal {nom['K_m'].max():.3f}, doubled wheels {dbl['K_m'].max():.3f}"
          f" (Kraiem 2022: 0.65 -> 0.4); lower at {np.mean(dbl['K_m'] < nom['K_m']) * 100:.1f}% of samples")
    print()
    mission = ROOT / "missions" / "demeter_3dof.yaml"
    figure_costs(mission)
    from sms_cli.report.figpool import default_workers

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if not args.skip_command:
            t, res, _ = timed_command(["analyze", str(mission)], tmp / "demeter", args.command_repeat)
            a = res["analysis"]
            print(f"Whole command `sms analyze missions/demeter_3dof.yaml -o DIR` ({len(a['artifacts'])} files, "
                  f"{sum(f.endswith('.png') for f in a['artifacts'])} figures, {default_workers()} figure worker(s) "
                  f"+ the command, {os.cpu_count()} cores):")
            print(f"  best of {args.command_repeat}: {t:5.2f} s  = {t / TARGET_COMMAND_S:.2f} x the {TARGET_COMMAND_S:g} s "
                  f"target (study {a['timing']['total_s']:.2f} s of it)")
        if not args.skip_sobol:
            sobol_commands(tmp, args)


def sobol_commands(tmp: Path, args) -> None:
    """The Sobol study's whole command (Parquet, then Parquet + CSV unless --sobol-only): wall time
    (best of --sobol-repeat) against the 10 s target, its CPU time and its evaluation time."""
    m = sobol_mission(tmp, args.sobol_n)
    print(f"Sobol study, {args.sobol_n:,} samples x 2 variants, --no-plots (best of {args.sobol_repeat}):")
    base = None
    for label, extra in (("Parquet", []), ("Parquet + CSV (--csv)", ["--csv"])):
        t, res, cpu = timed_command(["analyze", str(m), "--no-plots"] + extra, tmp / "sobol", args.sobol_repeat)
        a = res["analysis"]
        size = sum((tmp / "sobol" / f).stat().st_size for f in a["artifacts"]) / 1e6
        base = base or t
        print(f"  {label:22s}: {t:6.2f} s  = {t / TARGET_SOBOL_S:.2f} x the {TARGET_SOBOL_S:g} s target "
              f"({'met' if t <= TARGET_SOBOL_S else 'NOT met'}), CPU {cpu:6.2f} s, {t / base:.2f} x Parquet; "
              f"evaluation {a['timing']['compute_s']:.2f} s, tables {size:,.0f} MB")
        shutil.rmtree(tmp / "sobol", ignore_errors=True)
        if args.sobol_only:
            break


if __name__ == "__main__":
    main()
