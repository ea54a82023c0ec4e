"""Basilisk's scenarioAttitudeFeedbackRW timed side by side with sms, attitude histories compared.

    /tmp/venv/bin/python benches/bench_basilisk.py [--repeat 3] [--profile]

sms half (this interpreter): missions/basilisk_rw_reference.yaml, 6000 plant steps of 0.1 s with
the controller at 10 Hz (one plant step per control period), by both engines: the compiled one
(numba; what ``sms simulate`` runs for this mission, the number compared with Basilisk) and the
Python one (``engine: python``, the reference loop). Timed, per engine:
  - ``Simulation.run`` + ``finish`` with the MCAP recorder taking every step (the issue's "recording
    on"), and without a recorder; wall and process CPU time;
  - an instrumented run (wrappers installed here, the engines are not edited) splitting the cost:
    compiled — loop kernel (plant, controller, per-tick trace), recording (sample selection,
    poses, bulk encoding, compression), metrics summary; Python — plant (RKMK4 step with the
    forward dynamics, wheel speed limit, divergence check), controller (sensors, reference,
    attitude law + allocation + torque clip), recording (state → MCAP sample), metrics (per-tick
    trace: momentum, energy, errors) and the rest of the loop;
  - set-up (load + compile + recorder) and, once, the whole ``sms simulate`` CLI in a subprocess.
The two engines' recordings are compared with each other, and the compiled one's with Basilisk.
Basilisk half: benches/basilisk_reference.py run with the Basilisk environment's Python
(``--bsk-python``, else $SMS_BSK_PYTHON, else /tmp/bskenv/bin/python); skipped with instructions
when that environment does not exist. Its time is ``ExecuteSimulation`` only (recorders on every
step). Histories: σ_BN (MRP), ω_BN (body frame) and wheel speeds, read back from sms's MCAP and
from Basilisk's recorders, compared at every common step. µs per step = wall / 6000.
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import io
import json
import math
import os
import pstats
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MISSION = ROOT / "missions" / "basilisk_rw_reference.yaml"
BSK_SCRIPT = ROOT / "benches" / "basilisk_reference.py"
DEFAULT_BSK_PYTHON = "/tmp/bskenv/bin/python"
TARGET_RATIO = 1.0  # issue #19: <= 1.0x with recording on (goal 0.7x)


# ----------------------------------------------------------------------------- sms side
def _setup(record_path: Path | None, engine: str = "auto"):
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.model.summary import model_summary
    from sms_cli.recording.recorder import McapRecorder
    from sms_cli.sim.stage import versions

    loaded = load_mission(MISSION)
    sm = compile_system(loaded)
    spec = loaded.mission.simulation.model_copy(update={"engine": engine})
    rec = None
    if record_path is not None:
        rec = McapRecorder(record_path, mission_text=loaded.text, mission_name=loaded.mission.name,
                           model_summary=model_summary(sm), urdf_text=sm.urdf_text, versions=versions(),
                           record_rate_hz=spec.record_rate)
        links = list(sm.link_parents)
        rec.add_transform_tree(links, [sm.link_parents[n] for n in links])
    return sm, spec, rec


def _run_once(record_path: Path | None, profiler: cProfile.Profile | None = None, engine: str = "auto") -> dict:
    """One sms run; returns wall times (s) of the set-up and of run (+ finish)."""
    from sms_cli.sim.engine import Simulation

    t0 = time.perf_counter()
    sm, spec, rec = _setup(record_path, engine)
    sim = Simulation(sm, spec, rec, progress=False)
    t1, c1 = time.perf_counter(), time.process_time()
    if profiler is not None:
        profiler.enable()
    if rec is not None:
        with rec:
            result = sim.run()
            rec.finish(result.status)
    else:
        result = sim.run()
    if profiler is not None:
        profiler.disable()
    t2, c2 = time.perf_counter(), time.process_time()
    if result.status != "completed":
        raise RuntimeError(f"sms run {result.status}: {result.divergence}")
    return {"setup_s": t1 - t0, "run_s": t2 - t1, "cpu_s": c2 - c1, "steps": result.steps,
            "conservation": result.conservation, "engine": result.timing["engine"]}


class _Timers:
    """Wall-time accumulators installed around engine functions (restored afterwards)."""

    def __init__(self):
        self.acc: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._undo = []

    def wrap(self, owner, name: str, bucket: str) -> None:
        orig = getattr(owner, name)
        acc, calls = self.acc, self.calls
        acc.setdefault(bucket, 0.0)
        calls.setdefault(bucket, 0)
        perf = time.perf_counter

        @functools.wraps(orig)
        def timed(*a, **k):
            t = perf()
            try:
                return orig(*a, **k)
            finally:
                acc[bucket] += perf() - t
                calls[bucket] += 1

        setattr(owner, name, timed)
        self._undo.append((owner, name, orig))

    def restore(self) -> None:
        for owner, name, orig in reversed(self._undo):
            setattr(owner, name, orig)
        self._undo.clear()


def _instrumented_split(record_path: Path) -> dict:
    """Run the Python engine once with timing wrappers; returns seconds per bucket and the run's wall time."""
    import sms_cli.sim.engine as E
    from sms_cli.sim.actuators import WheelArray
    from sms_cli.sim.references import AttitudeProfile
    from sms_cli.sim.sensors import Sensors

    tm = _Timers()
    tm.wrap(E, "rkmk4_step", "plant")
    tm.wrap(WheelArray, "speed_limited", "plant")
    tm.wrap(E.Simulation, "_check", "plant")
    tm.wrap(Sensors, "measure", "controller")
    tm.wrap(AttitudeProfile, "at", "controller")
    tm.wrap(E.Simulation, "_control", "controller")
    tm.wrap(E.Simulation, "_record", "recording")
    tm.wrap(E.Simulation, "_trace", "metrics")
    tm.wrap(E, "attitude_error", "metrics")
    try:
        r = _run_once(record_path, engine="python")
    finally:
        tm.restore()
    # the wrappers' own cost, measured on an empty function, is charged to "rest" below
    def nothing():
        return None

    probe = _Timers()
    holder = type("H", (), {"f": staticmethod(nothing)})
    probe.wrap(holder, "f", "x")
    n = 20000
    t = time.perf_counter()
    for _ in range(n):
        holder.f()
    per_call = (time.perf_counter() - t) / n
    return {"buckets": tm.acc, "calls": tm.calls, "run_s": r["run_s"], "steps": r["steps"],
            "wrapper_s_per_call": per_call}


def _compiled_split(record_path: Path) -> dict:
    """Run the compiled engine once with wrappers on its three parts: the loop kernel (plant,
    controller and per-tick trace), the recording (sample selection, poses, encoding,
    compression) and the metrics summary; seconds per part and the run's wall time."""
    import sms_cli.sim.compiled.loop as loop
    import sms_cli.sim.engine as E
    from sms_cli.sim.compiled.runner import CompiledSimulation

    tm = _Timers()
    tm.wrap(loop, "run_ticks", "loop kernel")
    tm.wrap(CompiledSimulation, "_record", "recording")
    tm.wrap(E, "build_result", "metrics")
    try:
        r = _run_once(record_path, engine="compiled")
    finally:
        tm.restore()
    return {"buckets": tm.acc, "run_s": r["run_s"], "steps": r["steps"]}


def _profile(record_path: Path, top: int) -> str:
    pr = cProfile.Profile()
    r = _run_once(record_path, pr, engine="python")
    buf = io.StringIO()
    st = pstats.Stats(pr, stream=buf)
    st.sort_stats("tottime")
    steps = r["steps"]
    lines = [f"cProfile of Simulation.run (recording on; profiler overhead inflates the total: "
             f"{1e6 * r['run_s'] / steps:.0f} us/step under the profiler)",
             f"  {'own us/step':>11} {'cum us/step':>11} {'calls/step':>10}  function"]
    rows = sorted(st.stats.items(), key=lambda kv: -kv[1][2])[:top]
    for (fn, line, name), (cc, nc, tt, ct, _) in rows:
        where = f"{Path(fn).name}:{line}({name})" if fn != "~" else name
        lines.append(f"  {1e6 * tt / steps:11.2f} {1e6 * ct / steps:11.2f} {nc / steps:10.2f}  {where}")
    return "\n".join(lines)


def _micro(record_path: Path, n: int = 3000) -> list[tuple[str, float]]:
    """µs per call of the pieces of one step, at the initial state (no profiler; best of 5 rounds)."""
    import pinocchio as pin

    from sms_cli.dynamics.integrator import State, rkmk4_step
    from sms_cli.sim.attitude_math import attitude_error
    from sms_cli.sim.engine import Simulation
    from sms_cli.sim.interfaces import ArmRef, AttitudeRef
    from sms_cli.sim.metrics import Trace

    sm, spec, rec = _setup(record_path, "python")
    sim = Simulation(sm, spec, rec, progress=False)
    s = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
    tau = np.zeros(sm.nv)
    tau[sm.idx.wheels] = [0.1, -0.1, 0.05]
    ref = AttitudeRef(np.array([0.0, 0.0, 0.0, 1.0]))
    arm_ref = ArmRef(np.zeros(0), np.zeros(0), np.zeros(0))
    sensed = sim.sensors.measure(0.0, s.q, s.v, s.eta, s.etadot)
    phase = spec.phases[0]
    a3, b3 = np.array([0.1, 0.2, 0.3]), np.array([-0.3, 0.5, 0.7])
    out = []

    def bench(label, fn, calls=n, rounds=5):
        fn()
        best = math.inf
        for _ in range(rounds):  # the fastest round: least disturbed by other processes
            t = time.perf_counter()
            for _ in range(calls // rounds):
                fn()
            best = min(best, (time.perf_counter() - t) / (calls // rounds))
        out.append((label, 1e6 * best))

    accel = sim._accel(tau)
    bench("pin.aba (3 wheels + free flyer)", lambda: pin.aba(sm.model, sm.data, s.q, s.v, tau))
    bench("SystemModel.forward_dynamics", lambda: sm.forward_dynamics(s.q, s.v, s.eta, s.etadot, tau))
    bench("pin.integrate", lambda: pin.integrate(sm.model, s.q, 0.1 * s.v))
    bench("rkmk4_step (4 FD + 4 integrate)", lambda: rkmk4_step(sm.model, s, 0.1, accel))
    bench("np.cross (3-vectors)", lambda: np.cross(a3, b3))
    bench("np.linalg.norm (3-vector)", lambda: np.linalg.norm(a3))
    bench("Sensors.measure", lambda: sim.sensors.measure(0.0, s.q, s.v, s.eta, s.etadot))
    bench("MrpFeedback.torque", lambda: sim.att_law.torque(sensed, ref))
    bench("Simulation._control (law + allocation + clip)", lambda: sim._control(phase, sensed, ref, arm_ref))
    bench("WheelArray.speed_limited", lambda: sim.wheels.speed_limited(tau[sm.idx.wheels], s.v[sm.idx.wheels], 0.1))
    bench("Simulation._check", lambda: sim._check(s))
    bench("attitude_error", lambda: attitude_error(ref.quat, s.q[3:7]))
    bench("SystemModel.momentum", lambda: sm.momentum(s.q, s.v, s.etadot, about="origin"))
    bench("SystemModel.energy", lambda: sm.energy(s.q, s.v, s.eta, s.etadot))
    tr = Trace()
    err = np.zeros(3)
    bench("Simulation._trace (per control tick)",
          lambda: sim._trace(tr, 0.0, 0, err, arm_ref, s, tau[sm.idx.wheels], np.zeros(0), False, float("nan")))
    tick = iter(range(1, 10**9))
    with rec:
        bench("Simulation._record (FK + momentum + MCAP sample)",
              lambda: sim._record(0.1 * next(tick), s, ref, arm_ref, tau[sm.idx.wheels], np.zeros(0), err))
        rec.finish("completed")
    return out


def _read_mcap(path: Path) -> dict:
    """σ_BN, ω (body), wheel speeds and wheel torques from sms's recording, by step index."""
    from sms_cli.recording.read import messages

    want = {"/attitude": [], "/base/rate": [], "/wheels/speed": [], "/wheels/torque": []}
    times = {k: [] for k in want}
    for topic, log_time, data in messages(path, list(want)):
        want[topic].append(data)
        times[topic].append(log_time)
    t = np.array(times["/attitude"], dtype=np.int64)
    q = np.array([[m["qx"], m["qy"], m["qz"], m["qw"]] for m in want["/attitude"]])
    q[q[:, 3] < 0] *= -1.0
    sigma = q[:, :3] / (1.0 + q[:, 3:4])  # MRP of the base→world quaternion = Basilisk's σ_BN
    omega = np.array([[m["x"], m["y"], m["z"]] for m in want["/base/rate"]])
    speeds = np.array([list(m.values()) for m in want["/wheels/speed"]])
    torque = np.array([list(m.values()) for m in want["/wheels/torque"]])
    return {"t": t * 1e-9, "sigma": sigma, "omega": omega, "speeds": speeds, "torque": torque}


# ----------------------------------------------------------------------------- Basilisk side
def _bsk_python(arg: str | None) -> str | None:
    cand = arg or os.environ.get("SMS_BSK_PYTHON") or DEFAULT_BSK_PYTHON
    return cand if Path(cand).exists() else None


def _run_basilisk(py: str, repeat: int, out: Path) -> dict:
    cmd = [py, str(BSK_SCRIPT), "--repeat", str(repeat), "--json", "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        raise RuntimeError(f"Basilisk run failed ({' '.join(cmd)}):\n{proc.stdout}\n{proc.stderr}")
    timings = json.loads(proc.stdout.strip().splitlines()[-1])
    data = np.load(out)
    timings["hist"] = {k: data[k] for k in ("t", "sigma_BN", "omega_BN_B", "wheel_speeds", "wheel_torque")}
    return timings


def _compare(sms: dict, bsk: dict, dt: float) -> dict:
    """Max differences at the common steps (sms records after each step, Basilisk from t = 0)."""
    ks = np.rint(sms["t"] / dt).astype(int)
    kb = np.rint(bsk["t"] / dt).astype(int)
    common, i_s, i_b = np.intersect1d(ks, kb, return_indices=True)
    ds = np.abs(sms["sigma"][i_s] - bsk["sigma_BN"][i_b])
    dw = np.abs(sms["omega"][i_s] - bsk["omega_BN_B"][i_b])
    dW = np.abs(sms["speeds"][i_s] - bsk["wheel_speeds"][i_b])
    # applied torque over [t_k, t_k + dt] is the one commanded at t_k: sms records it after the step
    i_s2, i_b2 = [], []
    for a, k in enumerate(ks):
        j = np.searchsorted(kb, k - 1)
        if j < kb.size and kb[j] == k - 1:
            i_s2.append(a)
            i_b2.append(j)
    du = np.abs(sms["torque"][i_s2] - bsk["wheel_torque"][i_b2])
    angle = lambda s: 4.0 * np.arctan(np.linalg.norm(s, axis=1))  # noqa: E731
    dang = np.abs(angle(sms["sigma"][i_s]) - angle(bsk["sigma_BN"][i_b]))
    return {"samples": int(common.size), "sigma": float(ds.max()), "omega_rad_s": float(dw.max()),
            "wheel_speed_rad_s": float(dW.max()), "wheel_speed_rel": float(dW.max() / np.abs(bsk["wheel_speeds"]).max()),
            "wheel_torque_Nm": float(du.max()), "angle_rad": float(dang.max()),
            "final_sigma_sms": sms["sigma"][-1].tolist(), "final_sigma_bsk": bsk["sigma_BN"][-1].tolist()}


# ----------------------------------------------------------------------------- main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per variant; the fastest is reported")
    ap.add_argument("--bsk-python", help=f"Python of the Basilisk environment (default $SMS_BSK_PYTHON or {DEFAULT_BSK_PYTHON})")
    ap.add_argument("--profile", action="store_true", help="print a cProfile table of the sms run (µs per step)")
    ap.add_argument("--sms-only", action="store_true", help="skip the Basilisk half")
    ap.add_argument("--top", type=int, default=25, help="rows of the profile table")
    ap.add_argument("--micro", action="store_true", help="print µs per call of the pieces of a step (no profiler)")
    ap.add_argument("--no-cli", action="store_true", help="skip the end-to-end `sms simulate` subprocess")
    ap.add_argument("--json", help="also write every number to this JSON file")
    args = ap.parse_args(argv)
    repeat = max(args.repeat, 1)

    tmp = Path(tempfile.mkdtemp(prefix="bench_basilisk_"))
    report: dict = {}
    try:
        # --- sms: the compiled engine (what `sms simulate` picks for this mission), then the Python loop
        _run_once(tmp / "warm.mcap", engine="compiled")  # imports; compiles the kernels on a cold cache
        _run_once(tmp / "warm.mcap", engine="python")
        sms_t: dict = {}
        for engine in ("compiled", "python"):
            rec_runs = [_run_once(tmp / f"{engine}{i}.mcap", engine=engine) for i in range(repeat)]
            norec_runs = [_run_once(None, engine=engine) for _ in range(repeat)]
            steps = rec_runs[0]["steps"]
            best_rec = min(rec_runs, key=lambda r: r["run_s"])
            best_norec = min(norec_runs, key=lambda r: r["run_s"])
            us = lambda s: 1e6 * s / steps  # noqa: E731
            sms_t[engine] = {
                "steps": steps, "us_per_step_record": us(best_rec["run_s"]), "us_per_step_no_record": us(best_norec["run_s"]),
                "us_per_step_with_setup": us(best_rec["run_s"] + best_rec["setup_s"]), "setup_s": best_rec["setup_s"],
                "all_record": [us(r["run_s"]) for r in rec_runs], "all_no_record": [us(r["run_s"]) for r in norec_runs],
                "cpu_us_per_step_record": min(us(r["cpu_s"]) for r in rec_runs),
                "cpu_us_per_step_no_record": min(us(r["cpu_s"]) for r in norec_runs),
                "real_time_factor_record": 600.0 / best_rec["run_s"], "conservation": best_rec["conservation"],
                "mcap": str(tmp / f"{engine}{rec_runs.index(best_rec)}.mcap")}
        split = _instrumented_split(tmp / "split.mcap")
        py_t = sms_t["python"]
        py_t["split_us_per_step"] = {k: us(v) for k, v in split["buckets"].items()}
        n_wrapped = sum(split["calls"].values())
        py_t["split_us_per_step"]["rest of loop"] = us(split["run_s"] - sum(split["buckets"].values()))
        py_t["split_instrumented_total"] = us(split["run_s"])
        py_t["split_wrapper_overhead_us_per_step"] = us(n_wrapped * split["wrapper_s_per_call"])
        csplit = _compiled_split(tmp / "csplit.mcap")
        cc_t = sms_t["compiled"]
        cc_t["split_us_per_step"] = {k: us(v) for k, v in csplit["buckets"].items()}
        cc_t["split_us_per_step"]["rest"] = us(csplit["run_s"] - sum(csplit["buckets"].values()))
        cc_t["split_instrumented_total"] = us(csplit["run_s"])
        if not args.no_cli:
            t = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "sms_cli", "simulate", str(MISSION), "-o", str(tmp / "cli"),
                                   "--no-progress"], capture_output=True, text=True, cwd=ROOT)
            wall = time.perf_counter() - t
            cc_t["cli_wall_s"] = wall if proc.returncode == 0 else None
        sms_hist = _read_mcap(Path(cc_t["mcap"]))
        py_hist = _read_mcap(Path(py_t["mcap"]))
        report["sms"] = sms_t
        report["engines_difference"] = {k: float(np.abs(sms_hist[k] - py_hist[k]).max())
                                        for k in ("sigma", "omega", "speeds", "torque")}

        print("sms  missions/basilisk_rw_reference.yaml: 6000 steps of 0.1 s, controller 10 Hz")
        for engine, label in (("compiled", "compiled engine (what `sms simulate` runs here)"),
                              ("python", "Python engine (engine: python, the reference loop)")):
            e = sms_t[engine]
            print(f" {label}")
            print(f"  Simulation.run, MCAP every step : {e['us_per_step_record']:8.1f} us/step "
                  f"({', '.join(f'{x:.1f}' for x in e['all_record'])}); {e['real_time_factor_record']:.0f}x real time")
            print(f"  Simulation.run, no recorder     : {e['us_per_step_no_record']:8.1f} us/step "
                  f"({', '.join(f'{x:.1f}' for x in e['all_no_record'])})")
            print(f"  CPU time (process), best run    : {e['cpu_us_per_step_record']:8.1f} us/step recording, "
                  f"{e['cpu_us_per_step_no_record']:.1f} without")
            print(f"  with set-up (load+compile+rec)  : {e['us_per_step_with_setup']:8.1f} us/step (set-up {1e3 * e['setup_s']:.0f} ms)")
        if cc_t.get("cli_wall_s"):
            print(f"  `sms simulate` end to end       : {cc_t['cli_wall_s']:.2f} s wall (interpreter, imports, plots, CSV included)")
        print(f"  compiled engine split (instrumented run, {cc_t['split_instrumented_total']:.1f} us/step):")
        for k in ("loop kernel", "recording", "metrics", "rest"):
            print(f"    {k:<12} {cc_t['split_us_per_step'][k]:8.1f} us/step")
        print(f"  Python engine split (instrumented run, {py_t['split_instrumented_total']:.1f} us/step; wrappers add "
              f"≈{py_t['split_wrapper_overhead_us_per_step']:.1f} us/step, charged to their buckets):")
        for k in ("plant", "controller", "recording", "metrics", "rest of loop"):
            print(f"    {k:<12} {py_t['split_us_per_step'][k]:8.1f} us/step")
        d = report["engines_difference"]
        print(f"  engines' recordings differ by at most: sigma {d['sigma']:.1e}, omega {d['omega']:.1e} rad/s, "
              f"wheel speeds {d['speeds']:.1e} rad/s, torques {d['torque']:.1e} N m")
        c = cc_t["conservation"]
        if c:
            print(f"  conservation (compiled): {json.dumps(c)}")
        sms_t = cc_t  # the headline numbers below are the compiled engine's

        # --- Basilisk
        py = None if args.sms_only else _bsk_python(args.bsk_python)
        if args.sms_only:
            pass
        elif py is None:
            print("\nBasilisk half skipped: no Basilisk environment. Create it with\n"
                  "    python3 -m venv /tmp/bskenv && /tmp/bskenv/bin/pip install bsk\n"
                  "or point --bsk-python / $SMS_BSK_PYTHON at a Python that imports Basilisk.")
        else:
            bsk = _run_basilisk(py, repeat, tmp / "bsk.npz")
            report["basilisk"] = {k: v for k, v in bsk.items() if k != "hist"}
            cmp_ = _compare(sms_hist, bsk["hist"], 0.1)
            report["difference"] = cmp_
            ratio = sms_t["us_per_step_record"] / bsk["us_per_step_execute"]
            report["ratio_record"] = ratio
            print(f"\nBasilisk ({py}): lean scenarioAttitudeFeedbackRW, recorders every step")
            print(f"  ExecuteSimulation               : {bsk['us_per_step_execute']:8.1f} us/step "
                  f"({', '.join(f'{x:.1f}' for x in bsk['all_execute'])})")
            print(f"  CPU time (process), best run    : {bsk['cpu_us_per_step_execute']:8.1f} us/step")
            print(f"  with set-up                     : {bsk['us_per_step_with_setup']:8.1f} us/step")
            print(f"\nratio sms (compiled engine)/Basilisk (recording on): {ratio:.2f}x  (target <= {TARGET_RATIO}x: "
                  f"{'met' if ratio <= TARGET_RATIO else 'NOT met'}); without sms recording: "
                  f"{sms_t['us_per_step_no_record'] / bsk['us_per_step_execute']:.1f}x")
            cpu_ratio = sms_t["cpu_us_per_step_record"] / bsk["cpu_us_per_step_execute"]
            report["cpu_ratio_record"] = cpu_ratio
            print(f"ratio of CPU times (robust when other processes share the machine): {cpu_ratio:.1f}x recording on, "
                  f"{sms_t['cpu_us_per_step_no_record'] / bsk['cpu_us_per_step_execute']:.1f}x without")
            print(f"Python engine / Basilisk: {py_t['us_per_step_record'] / bsk['us_per_step_execute']:.1f}x recording on "
                  f"(CPU {py_t['cpu_us_per_step_record'] / bsk['cpu_us_per_step_execute']:.1f}x)")
            print(f"history differences over {cmp_['samples']} common steps (max abs; sms read back from its MCAP, "
                  "which holds the doubles exactly):")
            print(f"  sigma_BN (MRP)   {cmp_['sigma']:.3e}      attitude angle {cmp_['angle_rad']:.3e} rad")
            print(f"  omega_BN (body)  {cmp_['omega_rad_s']:.3e} rad/s")
            print(f"  wheel speeds     {cmp_['wheel_speed_rad_s']:.3e} rad/s ({cmp_['wheel_speed_rel']:.1e} of the peak)")
            print(f"  wheel torques    {cmp_['wheel_torque_Nm']:.3e} N m")
        if args.profile:
            print()
            print(_profile(tmp / "prof.mcap", args.top))  # the Python engine (the compiled loop is one call)
        if args.micro:
            rows = _micro(tmp / "micro.mcap")
            report["micro_us_per_call"] = dict(rows)
            print("\nmicro-benchmarks at the initial state (us per call):")
            for label, v in rows:
                print(f"  {v:8.2f}  {label}")
        if args.json:
            Path(args.json).write_text(json.dumps(report, indent=2, default=float) + "\n")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
