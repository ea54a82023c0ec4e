"""LMI synthesis solve time against LMI size, and the pulsar_simple synthesis time.

Size = rows of the thesis's Ω = 3 n_q + n_e (n_q actuators, n_e = 2 n_modes + 3 observer states).
Problems: random physically shaped mass matrices (tests/test_synthesis_lmi.py's generator),
one linearisation, relaxation 'none' (the structured, exactly decoupled form of lmi.py), solved
with solver 'auto' (the dedicated interior-point solver of sdp.py; Clarabel through cvxpy if it
fails). Every result is checked by ``verify_lmi`` (the solver status is never trusted).
Each sweep case runs in its own process with a wall-clock limit (--limit, default 600 s): the
sweep stops at the first size that does not solve within it.

Kraiem 2022 Table 4.3 (L2885–2887; YALMIP + MOSEK on an Intel i7) is printed alongside with a
ratio column. Caveat: the thesis's "size of T" is the number of tasks (linearisations) of the
chapter 4 problem, each a 106×106 LMI (4.27) (L2881); here size is the number of LMI rows of one
linearisation. Both grow the dense Schur complement the solvers factor, but the ratio compares
different problem families at equal nominal "size", and machines a decade apart (the dense
1000×1000 Cholesky calibration is saved so that runs on different machines compare). --tasks
measures the thesis's own axis (|T| linearisations sharing the variables) at a smaller task.

    python benches/bench_synthesis.py            # pulsar_simple (its line in the saved JSON is updated)
                                                 # and sizes up to 50 (about a minute)
    python benches/bench_synthesis.py --full     # sizes up to 175, within --limit s each; writes
                                                 # benches/data/synthesis_sweep.json
    python benches/bench_synthesis.py --tasks    # |T| = 1, 2, 5, … linearisations at LMI size 50 (the
                                                 # axis of Table 4.3), added to the saved JSON
    python benches/bench_synthesis.py --table    # print the saved sweep against Table 4.3
    python benches/bench_synthesis.py --clarabel # also cvxpy + Clarabel (pulsar; γ on sizes ≤ 67)
    python benches/bench_synthesis.py --full --min-size 89 --solver ipm@1e-6 --key rows_ipm_tol6
                                                 # an extra labelled list: the dedicated solver
                                                 # alone at tolerance 1e-6 (no Clarabel fallback)
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
SWEEP_JSON = ROOT / "benches" / "data" / "synthesis_sweep.json"

# Kraiem 2022 Table 4.3: size of the task set T → (MOSEK resolution time s, iterations)
THESIS_T43 = {10: (35.0, 27), 20: (130.0, 53), 30: (122.0, 33), 40: (186.0, 38), 50: (245.0, 39),
              80: (426.0, 38), 100: (550.0, 39), 154: (833.0, 43)}
# (n_q, n_modes) → size 3 n_q + 2 n_modes + 3
SMALL = [(2, 1), (3, 2), (5, 4), (6, 8), (9, 10)]
LARGE = [(12, 14), (14, 22), (16, 24), (18, 27), (20, 30), (24, 36), (28, 44)]
# per-task problem of the |T| sweep: LMI size 50 (pulsar_simple's size). The thesis's task is
# larger (Q_z 28×28: n_q = 14, P_e 50×50, L2881), but at n_e ≈ 49 the dedicated solver does not
# reach its tolerance (see sdp.py), and Clarabel alone needs minutes per linearisation
TASKS_MODEL = (9, 10)
TASKS = [1, 2, 5, 10, 20, 30, 40, 50, 80, 100, 154]  # with every |T| of Table 4.3


def calibration() -> float:
    """Seconds of one dense 1000×1000 Cholesky on one BLAS thread, as the solver runs (best of 5)."""
    from sms_cli.synthesis.sdp import single_thread_blas

    a = np.random.default_rng(0).normal(size=(1000, 1000))
    a = a @ a.T + 1000 * np.eye(1000)
    best = np.inf
    with single_thread_blas():
        for _ in range(5):
            t = time.perf_counter()
            np.linalg.cholesky(a)
            best = min(best, time.perf_counter() - t)
    return best


def thesis_seconds(size: int) -> float | None:
    """Table 4.3 time at this size (log–log interpolation), None outside 10–154."""
    xs = np.array(sorted(THESIS_T43), dtype=float)
    if not xs[0] <= size <= xs[-1]:
        return None
    ys = np.array([THESIS_T43[int(x)][0] for x in xs])
    return float(np.exp(np.interp(np.log(size), np.log(xs), np.log(ys))))


def _solver(spec: str) -> str:
    """'auto', 'ipm', 'clarabel', or 'ipm@TOL': the dedicated solver alone at tolerance TOL
    (lmi.IPM_TOL overridden in this process; no Clarabel fallback)."""
    if spec.startswith("ipm@"):
        from sms_cli.synthesis import lmi

        lmi.IPM_TOL = float(spec[4:])
        return "ipm"
    return spec


def _tol_note(spec: str) -> str:
    return f", tol {float(spec[4:]):g}" if spec.startswith("ipm@") else ""


def one(n_q: int, n_modes: int, solver: str = "auto") -> dict:
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
    res = synthesize(req, diagnose=False, solver=_solver(solver))
    total = time.perf_counter() - t
    ok = verify_lmi(req, res).passed
    return {"n_q": n_q, "n_modes": n_modes, "n_e": m.n_e, "size": 3 * n_q + m.n_e, "variables": res.n_variables,
            "seconds": res.solve_time, "total_s": total, "verified": bool(ok), "gamma": res.gamma,
            "solver": res.solver + _tol_note(solver)}


def one_tasks(n_q: int, n_modes: int, tasks: int, solver: str = "auto") -> dict:
    """``tasks`` linearisations sharing the variables (relaxation 'polytopic'): the axis of
    Table 4.3 (its "size of T"). The linearisations differ by the inertia coupling (0.25–0.40)."""
    from test_synthesis_lmi import toy_model

    from sms_cli.synthesis.lmi import SynthesisRequest, ellipsoid_from_box, synthesize
    from sms_cli.synthesis.regions import PoleRegion
    from sms_cli.synthesis.verify import verify_lmi

    scales = [1e3] * 3 + [2e3] * 3 + list(np.geomspace(0.1, 50.0, n_q))
    couplings = [0.3] + list(np.linspace(0.25, 0.4, tasks - 1))
    models = [toy_model(scales, n_modes=n_modes, seed=n_q + 7 * n_modes, coupling=c, label=f"task {j}")
              for j, c in enumerate(couplings)]
    m = models[0]
    b = [0.05] * n_modes + [0.01] * 3 + [0.05] * n_modes
    req = SynthesisRequest([m], PoleRegion(0.3, 0.5, 5.0), PoleRegion(0.1, 0.0, 40.0), ellipsoid_from_box(b),
                           samples=models[1:], relaxation="polytopic" if tasks > 1 else "none")
    t = time.perf_counter()
    res = synthesize(req, diagnose=False, solver=_solver(solver))
    total = time.perf_counter() - t
    ok = verify_lmi(req, res).passed
    return {"n_q": n_q, "n_modes": n_modes, "n_e": m.n_e, "size": 3 * n_q + m.n_e, "tasks": tasks,
            "variables": res.n_variables, "seconds": res.solve_time, "total_s": total, "verified": bool(ok),
            "gamma": res.gamma, "solver": res.solver + _tol_note(solver)}


def pulsar(solver: str = "auto") -> dict:
    """The synthesize stage on pulsar_simple (solve, verification, gains.yaml; no plot)."""
    import tempfile

    from sms_cli.mission.load import load_mission
    from sms_cli.synthesis import lmi
    from sms_cli.synthesis.stage import run_synthesis

    original = lmi.synthesize
    lmi.synthesize = lambda req, diagnose=True, solver_=solver: original(req, diagnose, solver_)
    try:
        with tempfile.TemporaryDirectory() as d:
            cpu = time.process_time()
            sec = run_synthesis(load_mission(ROOT / "missions" / "pulsar_simple.yaml"), d, plots=False)
            cpu = time.process_time() - cpu
    finally:
        lmi.synthesize = original
    return {"size": sec["lmi"]["size"], "linearisations": sec["robustness"]["linearisations"],
            "solve_s": sec["lmi"]["solve_time_s"], "verify_s": sec["lmi"]["verify_time_s"],
            "total_s": sec["total_time_s"], "cpu_s": cpu, "gamma": sec["gamma"], "solver": sec["lmi"]["solver"],
            "verified": sec["verification"]["passed"]}


def run_case(n_q: int, n_modes: int, solver: str, limit: float, tasks: int = 0) -> dict | None:
    """``one`` (``one_tasks`` when tasks > 0) in a child process; None when it does not finish
    within ``limit`` s."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--case", str(n_q), str(n_modes), "--solver", solver,
           "--case-tasks", str(tasks)]
    t = time.perf_counter()
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=limit, check=True)
    except subprocess.TimeoutExpired:
        return None
    except subprocess.CalledProcessError as exc:  # e.g. 'ipm' did not converge (NumericalError)
        lines = exc.stderr.strip().splitlines()
        return {"n_q": n_q, "n_modes": n_modes, "size": 3 * n_q + 2 * n_modes + 3, "tasks": tasks or 1,
                "seconds": None, "error": lines[-1] if lines else "failed", "after_s": time.perf_counter() - t}
    return json.loads(out.stdout.strip().splitlines()[-1])


def machine() -> dict:
    return {"calibration_cholesky_1000_s": calibration(), "cpu_count": os.cpu_count(),
            "processor": platform.processor() or platform.machine(), "python": platform.python_version(),
            "numpy": np.__version__, "load_average": list(os.getloadavg()),
            "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def _unsolved(r: dict) -> str:
    return f"> {r['limit_s']:g}" if "limit_s" in r else "failed"


def print_table(data: dict) -> None:
    mc = data["machine"]
    end = ""
    if "calibration_end_s" in mc:
        end = (f" (at the end: {mc['calibration_end_s'] * 1e3:.1f} ms, load {mc['load_average_end'][0]:.1f}; "
               "the machine is shared)")
    print(f"sweep of {mc['date_utc']}: dense Cholesky 1000×1000 = {mc['calibration_cholesky_1000_s'] * 1e3:.1f} ms, "
          f"{mc['cpu_count']} cores, load {mc['load_average'][0]:.1f} at start{end}")
    print(f"{'size':>5}{'n_q':>5}{'modes':>6}{'vars':>6}{'seconds':>10}{'γ':>10}  verified  {'solver':<46}"
          f"{'T4.3 s':>8}{'ratio':>8}{'γ clarabel':>12}")
    rows = [(r, "") for r in data["rows"]]
    for key in data:
        if key.startswith("rows_") and isinstance(data[key], list):
            rows += [(r, f" [{data.get(key + '_solver', key)}]") for r in data[key]]
    for r, tag in rows:
        th = thesis_seconds(r["size"])
        ratio = "" if th is None or r["seconds"] is None else f"{r['seconds'] / th:8.3f}"
        if r["seconds"] is None:
            why = r.get("error", "not solved within the limit")
            why = ("did not converge" if "converge" in why else why[-40:]) + tag
            print(f"{r['size']:>5}{r['n_q']:>5}{r['n_modes']:>6}{'':>6}{_unsolved(r):>10}"
                  f"{'':>10}  {'':<9} {why:<46}{'' if th is None else format(th, '8.0f')}")
            continue
        gc = f"{r['gamma_clarabel']:12.5g}" if r.get("gamma_clarabel") is not None else ""
        print(f"{r['size']:>5}{r['n_q']:>5}{r['n_modes']:>6}{r['variables']:>6}{r['seconds']:>10.2f}"
              f"{r['gamma']:>10.5g}  {str(r['verified']):<9} {r['solver'] + tag:<46}"
              f"{'' if th is None else format(th, '8.0f')}{ratio:>8}{gc}")
    print("T4.3 s: Kraiem 2022 Table 4.3 (YALMIP + MOSEK, Intel i7), log–log interpolated at the same nominal size; "
          "its size is the number of tasks |T| (each a 106×106 LMI), not LMI rows (see the module docstring).")
    print_tasks(data)
    if data.get("pulsar"):
        p = data["pulsar"]
        print(f"pulsar_simple [{p['solver']}]: size {p['size']}, {p['linearisations']} linearisation(s), "
              f"solve {p['solve_s']:.2f} s, stage total {p['total_s']:.2f} s "
              f"(CPU {p.get('cpu_s', float('nan')):.2f} s), "
              f"γ = {p['gamma']:.5g}, "
              f"verified {p['verified']}")


def save(data: dict) -> None:
    SWEEP_JSON.parent.mkdir(parents=True, exist_ok=True)
    tmp = SWEEP_JSON.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(SWEEP_JSON)


def sweep_tasks(limit: float, solver: str, start: int = 1) -> None:
    """Solve time against the number of linearisations, saved with the sweep (from |T| = start
    on, appended to the saved rows when start > 1)."""
    data = json.loads(SWEEP_JSON.read_text())
    if start <= 1 or "tasks_rows" not in data:
        data["tasks_machine"] = machine()
        data["tasks_rows"] = []
    else:
        data["tasks_rows"] = [r for r in data["tasks_rows"] if r["tasks"] < start]
        data["tasks_machine_from_%d" % start] = machine()
    n_q, n_m = TASKS_MODEL
    for tasks in [t for t in TASKS if t >= start]:
        r = run_case(n_q, n_m, solver, limit, tasks)
        if r is None:
            r = {"n_q": n_q, "n_modes": n_m, "size": 3 * n_q + 2 * n_m + 3, "tasks": tasks, "seconds": None,
                 "limit_s": limit}
        data["tasks_rows"].append(r)
        save(data)
        print_tasks(data)
        if r["seconds"] is None:
            break


def print_tasks(data: dict) -> None:
    if not data.get("tasks_rows"):
        return
    print(f"{'|T|':>5}{'size':>6}{'vars':>6}{'seconds':>10}{'γ':>10}  verified  {'solver':<26}"
          f"{'T4.3 s':>8}{'ratio':>8}")
    for r in data["tasks_rows"]:
        th = THESIS_T43.get(r["tasks"], (None,))[0]
        if r["seconds"] is None:
            print(f"{r['tasks']:>5}{r['size']:>6}{'':>6}{_unsolved(r):>10}  {r.get('error', '')}")
            continue
        ratio = "" if th is None else f"{r['seconds'] / th:8.2f}"
        print(f"{r['tasks']:>5}{r['size']:>6}{r['variables']:>6}{r['seconds']:>10.2f}{r['gamma']:>10.5g}  "
              f"{str(r['verified']):<9} {r['solver']:<26}{'' if th is None else format(th, '8.0f')}{ratio:>8}")
    print("|T| linearisations of one LMI of the given size (chapter 3, relaxation 'polytopic'); Table 4.3: |T| tasks "
          "of the chapter 4 LMI, 106×106 each (with the NDO rows).")


def one_ndo(tasks: int, n_arm: int, n_modes: int) -> dict:
    """Chapter 4 (NDO) over ``tasks`` linearisations: tests/test_synthesis_ndo_scale.ndo_request
    (PULSAR-shaped: 6 wheels, rail, n_arm joints, n_modes modes; the thesis's size is n_arm 7,
    n_modes 22), dedicated solver on the decoupled form, every result through verify_lmi."""
    from test_synthesis_ndo_scale import ndo_request

    from sms_cli.synthesis.lmi import synthesize
    from sms_cli.synthesis.verify import verify_lmi

    req = ndo_request(tasks, n_arm=n_arm, n_modes=n_modes)
    m = req.nominal[0]
    row = {"tasks": tasks, "n_q": m.n_q, "n_e": m.n_e, "theta_rows": 4 * m.n_q + m.n_e,
           "mosek_s": THESIS_T43.get(tasks, (None,))[0]}
    t, c = time.perf_counter(), time.process_time()
    try:
        res = synthesize(req, diagnose=False, solver="ipm")
    except Exception as exc:  # noqa: BLE001 — the bench records why a size failed
        row.update(seconds=None, cpu_s=time.process_time() - c, wall_s=time.perf_counter() - t, error=str(exc)[:80],
                   peak_rss_mb=peak_rss_mb())
        return row
    row.update(seconds=res.solve_time, wall_s=time.perf_counter() - t, cpu_s=time.process_time() - c,
               iterations=res.solver, gamma=res.gamma, verified=bool(verify_lmi(req, res).passed),
               peak_rss_mb=peak_rss_mb())
    return row


def peak_rss_mb() -> float:
    """The process's peak resident memory so far (MB; ru_maxrss, kB on Linux): a sweep's row
    holds the largest of its own and the earlier rows' peaks (run one |T| per process to separate them)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def sweep_ndo(n_arm: int, n_modes: int, tasks: list[int]) -> None:
    """--ndo: Table 4.3's axis on the chapter 4 problem; saved under 'ndo_rows' with the calibration."""
    data = json.loads(SWEEP_JSON.read_text())
    data["ndo_machine"] = machine()
    data["ndo_rows"] = []
    print(f"{'|T|':>5}{'n_q':>4}{'n_e':>4}{'Θ rows':>7}{'wall s':>9}{'CPU s':>9}{'γ':>10}  verified  "
          f"{'solver':<26}{'MOSEK s':>8}{'ratio':>7}")
    for T in tasks:
        r = one_ndo(T, n_arm, n_modes)
        data["ndo_rows"].append(r)
        save(data)
        ratio = "" if r["seconds"] is None or not r["mosek_s"] else f"{r['wall_s'] / r['mosek_s']:7.3f}"
        print(f"{T:>5}{r['n_q']:>4}{r['n_e']:>4}{r['theta_rows']:>7}{r['wall_s']:>9.2f}{r['cpu_s']:>9.2f}"
              f"{'' if r['seconds'] is None else format(r['gamma'], '10.5g'):>10}  "
              f"{str(r.get('verified', False)):<9} {r.get('iterations', r.get('error', ''))[:26]:<26}"
              f"{r['mosek_s'] or '':>8}{ratio}  peak {r['peak_rss_mb'] / 1024:.2f} GB", flush=True)
    print("MOSEK s: Kraiem 2022 Table 4.3 (YALMIP + MOSEK, Intel i7; 106-row Θ per task). "
          f"Calibration: dense Cholesky 1000×1000 = {data['ndo_machine']['calibration_cholesky_1000_s'] * 1e3:.1f} ms.")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--full", action="store_true", help="long sweep (sizes up to 175), saved as JSON")
    ap.add_argument("--limit", type=float, default=600.0, help="wall-clock limit per sweep case (s)")
    ap.add_argument("--no-pulsar", action="store_true")
    ap.add_argument("--clarabel", action="store_true", help="also cvxpy + Clarabel (pulsar; γ on sizes ≤ 67)")
    ap.add_argument("--table", action="store_true", help="print the saved sweep and exit")
    ap.add_argument("--case", nargs=2, type=int, metavar=("N_Q", "N_MODES"), help=argparse.SUPPRESS)
    ap.add_argument("--solver", default="auto",
                    help="auto (default), ipm, clarabel, or ipm@TOL (dedicated solver alone at tolerance TOL)")
    ap.add_argument("--tasks-from", type=int, default=1,
                    help="--tasks: start at this |T|, keeping the saved smaller ones")
    ap.add_argument("--min-size", type=int, default=0, help="skip sweep sizes below this")
    ap.add_argument("--max-size", type=int, default=10**6, help="skip sweep sizes above this")
    ap.add_argument("--key", default="rows", help="JSON list the --full/--tasks rows go to (default: a new sweep)")
    ap.add_argument("--case-tasks", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--tasks", action="store_true",
                    help=f"sweep the number of linearisations |T| at LMI size "
                         f"{3 * TASKS_MODEL[0] + 2 * TASKS_MODEL[1] + 3} "
                         "(Table 4.3's axis), added to the saved JSON")
    ap.add_argument("--ndo", nargs="*", type=int, metavar="N",
                    help="chapter 4 (NDO) sweep over |T| (default Table 4.3's 10 … 154), saved under 'ndo_rows'")
    ap.add_argument("--ndo-size", nargs=2, type=int, default=[7, 22], metavar=("N_ARM", "N_MODES"),
                    help="--ndo problem: arm joints and modes (default the thesis's 7 and 22)")
    args = ap.parse_args()
    if args.ndo is not None:
        sweep_ndo(*args.ndo_size, args.ndo or sorted(THESIS_T43))
        return
    if args.case:
        if args.case_tasks:
            print(json.dumps(one_tasks(*args.case, args.case_tasks, solver=args.solver)))
        else:
            print(json.dumps(one(*args.case, solver=args.solver)))
        return
    if args.table:
        print_table(json.loads(SWEEP_JSON.read_text()))
        return
    if args.tasks:
        sweep_tasks(args.limit, args.solver, args.tasks_from)
        return
    key = args.key
    if key != "rows" and SWEEP_JSON.exists():  # an extra list in the saved sweep
        data = json.loads(SWEEP_JSON.read_text())
        data[key] = []
        data[key + "_machine"] = machine()
        data[key + "_solver"] = args.solver
        data["machine_now"] = data[key + "_machine"]
    elif args.full and SWEEP_JSON.exists():  # a new main sweep; the other lists are kept
        data = json.loads(SWEEP_JSON.read_text())
        data.update(machine=machine(), rows_solver=args.solver, rows=[])
        data["machine_now"] = data["machine"]
    else:
        data = {"machine": machine(), "thesis_table_4_3": {str(k): {"seconds": v[0], "iterations": v[1]}
                                                            for k, v in THESIS_T43.items()},
                "problem": "chapter 3 structured LMI, one linearisation, relaxation 'none'; "
                           "size = 3 n_q + n_e LMI rows", "rows_solver": args.solver, "rows": [], "pulsar": None}
        data["machine_now"] = data["machine"]
    mc = data.pop("machine_now")
    print(f"calibration: dense Cholesky 1000×1000, one thread = {mc['calibration_cholesky_1000_s'] * 1e3:.1f} ms "
          f"(load average {mc['load_average'][0]:.1f})")
    if not args.no_pulsar:
        for solver in ("auto", "clarabel") if args.clarabel else ("auto",):
            p = pulsar(solver)
            if solver == "auto":
                data["pulsar"] = p
                if not args.full and SWEEP_JSON.exists():  # keep the saved sweep's pulsar line current
                    saved = json.loads(SWEEP_JSON.read_text())
                    saved["pulsar"] = dict(p, machine=mc)
                    save(saved)
            print(f"pulsar_simple [{p['solver']}]: size {p['size']}, {p['linearisations']} linearisation(s), "
                  f"solve {p['solve_s']:.2f} s, verify {p['verify_s']:.2f} s, stage total {p['total_s']:.2f} s "
                  f"(CPU {p['cpu_s']:.2f} s), "
                  f"γ = {p['gamma']:.5g}, verified {p['verified']}", flush=True)
    cases = [c for c in SMALL + (LARGE if args.full else [])
             if args.min_size <= 3 * c[0] + 2 * c[1] + 3 <= args.max_size]
    print(f"{'n_q':>4}{'modes':>6}{'size':>6}{'solve s':>10}{'total s':>10}{'γ':>10}  verified  solver")
    for n_q, n_m in cases:
        r = run_case(n_q, n_m, args.solver, args.limit)
        if r is None:
            print(f"{n_q:>4}{n_m:>6}{3 * n_q + 2 * n_m + 3:>6}  not solved within {args.limit:g} s: stopping")
            r = {"n_q": n_q, "n_modes": n_m, "size": 3 * n_q + 2 * n_m + 3, "seconds": None, "limit_s": args.limit}
            data[key].append(r)
        elif r["seconds"] is None:
            print(f"{n_q:>4}{n_m:>6}{3 * n_q + 2 * n_m + 3:>6}  failed after {r['after_s']:.0f} s "
                  f"({r['error']}): stopping")
            data[key].append(r)
        else:
            if args.clarabel and r["size"] <= 67:
                rc = run_case(n_q, n_m, "clarabel", args.limit)
                r["gamma_clarabel"] = None if rc is None else rc["gamma"]
                r["clarabel_s"] = None if rc is None else rc["seconds"]
            data[key].append(r)
            print(f"{r['n_q']:>4}{r['n_modes']:>6}{r['size']:>6}{r['seconds']:>10.2f}{r['total_s']:>10.2f}"
                  f"{r['gamma']:>10.5g}  {str(r['verified']):<9} {r['solver']}", flush=True)
        if args.full:
            save(data)
        if r["seconds"] is None:
            break
    if args.full:
        mc["calibration_end_s"] = calibration()
        mc["load_average_end"] = list(os.getloadavg())
        save(data)
        print()
        print_table(data)


if __name__ == "__main__":
    main()
