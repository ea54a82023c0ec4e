"""``sms analyze``: workspace study (indices per sample, per variant), plots, table, modal analysis.

Writes into the results folder: ``analysis_<variant>.parquet`` (one row per sample; ``.csv`` as
well or instead when the mission's ``analysis.table`` or ``--csv`` asks), PNG plots
``analysis_<variant>_<index>.png`` / ``_hist.png`` / ``_slices.png``, ``analysis_compare_<index>.png``,
``modal_<k>.npz|.mat``, and the ``analysis`` section of results.json.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import numpy as np

from sms_cli.analysis.modal import LinearModel
from sms_cli.analysis.schema import AnalysisSpec
from sms_cli.errors import InputError, Problem
from sms_cli.results import ResultsDir


def _modal_configuration(sm, conf: dict, loaded, i: int) -> np.ndarray:
    """q0 with the named joints (arm joints or spring joints) set."""
    q = sm.q0.copy()
    known = {a.name: (a.q_index, a.kind) for a in sm.arm}
    known.update({s.joint: (s.q_index, "revolute") for s in sm.springs})
    for name, value in conf.items():
        if name not in known:
            import difflib

            close = difflib.get_close_matches(name, list(known), n=1)
            raise InputError(problems=[Problem(
                f"analysis.modal.configurations[{i}]: no arm or spring joint named '{name}'",
                loaded.source.locate(("analysis", "modal", "configurations", i, name)) if loaded else None,
                hint=f"did you mean '{close[0]}'?" if close else f"joints: {', '.join(known)}")])
        qi, kind = known[name]
        if kind == "continuous":
            q[qi:qi + 2] = [np.cos(value), np.sin(value)]
        else:
            q[qi] = value
    return q


def run_modal(sm, spec: AnalysisSpec, out: Path | None, loaded=None) -> list[tuple[dict, LinearModel]]:
    """Linear models and coupled modes at each configuration of ``analysis.modal``: per configuration
    its ``analysis.modal`` entry and its model, exported as ``out/modal_<k>.npz|.mat`` when ``out`` is given."""
    sm.require_dynamics("the modal analysis (analysis.modal)")
    from sms_cli.analysis.modal import coupled_modes, export, linearize

    results = []
    clamped = sorted(float(w) for a in sm.appendages for w in a.omega)
    for i, conf in enumerate(spec.modal.configurations):
        q = _modal_configuration(sm, conf, loaded, i)
        lin = linearize(sm, q, spec.modal.joints)
        files = export(lin, out / f"modal_{i}", spec.modal.export) if out is not None else []
        results.append(({
            "configuration": {k: float(v) for k, v in conf.items()}, "joints": spec.modal.joints,
            "states": len(lin.states), "inputs": lin.inputs, "equilibrium_residual": lin.residual,
            "modes": coupled_modes(lin), "clamped_frequencies_rad_s": clamped,
            "files": [p.name for p in files]}, lin))
    return results


def run_analysis(loaded, results_dir: Path | str, *, plots: bool | None = None, progress: bool | None = None,
                 pool=None, csv: bool = False) -> dict:
    """Run the study of a loaded mission; return the ``analysis`` section written to results.json."""
    return analyze_into(loaded, results_dir, plots=plots, progress=progress, pool=pool, csv=csv)[0]


def analyze_into(loaded, results_dir: Path | str, *, plots: bool | None = None,
                 progress: bool | None = None, pool=None, csv: bool = False) -> tuple[dict, list[LinearModel]]:
    """``analyze_mission`` writing its files and the ``analysis`` section into ``results_dir``,
    holding the folder for the whole command (``ResultsDir.writing``)."""
    out = Path(results_dir)
    with ResultsDir(out).writing(loaded.mission.name, loaded.path):
        section, models = analyze_mission(loaded, out, plots=plots, progress=progress, pool=pool, csv=csv)
        ResultsDir(out).update("analysis", section)
    return section, models


def analyze_mission(loaded, out: Path | None = None, *, plots: bool | None = None,
                    progress: bool | None = None, pool=None, csv: bool = False) -> tuple[dict, list[LinearModel]]:
    """The study of a loaded mission: its ``analysis`` section and the linear models of ``analysis.modal``.

    With ``out`` (an existing folder) the per-sample tables (Parquet, and CSV when the mission's
    ``analysis.table`` lists it or ``csv`` is true; ``sms_cli.analysis.table``) are streamed there as the samples are
    evaluated (a study may not fit in memory), then the plots and the modal exports are written and
    listed in ``artifacts``; without it nothing is written and ``artifacts`` is empty. results.json
    is not touched (``run_analysis`` writes the section). The figures are drawn by ``pool``
    (:class:`sms_cli.report.figpool.FigurePool`; default: one started here)."""
    from sms_cli.report.figpool import FigurePool

    spec = loaded.mission.analysis or AnalysisSpec()
    draw = out is not None and (spec.plots if plots is None else plots)
    formats = spec.table_formats(csv) if out is not None else ()
    if pool is not None:
        return _study(loaded, spec, out, draw, formats, progress, pool)
    with FigurePool(None if draw else 0) as own:  # its workers start now, while the samples are evaluated
        return _study(loaded, spec, out, draw, formats, progress, own)


def analysis_kernel_calls(kernel) -> list[list]:
    """The kernel calls of a study (``sms_cli.sim.compiled.warmup``): the nominal system's index kernel
    (``kernel``, an ``IndexKernel``; the variants' have the same argument types), the statistics' kernels."""
    from sms_cli.analysis.summary import warm_calls

    return [[kernel.warm_call()], warm_calls()]


def _study(loaded, spec: AnalysisSpec, out: Path | None, draw: bool, formats: tuple[str, ...], progress: bool | None,
           pool) -> tuple[dict, list[LinearModel]]:
    from sms_cli.analysis import plots as P
    from sms_cli.analysis.sampling import Progress
    from sms_cli.analysis.summary import Comparison, StudyStats
    from sms_cli.analysis.table import sample_tables, table_names
    from sms_cli.analysis.workspace import build_variants, evaluate_block, make_sampler
    from sms_cli.model import compile_system
    from sms_cli.sim.compiled.warmup import warm

    sm = compile_system(loaded)
    section: dict = {"defaults_used": loaded.mission.analysis is None}
    if not sm.arm:
        raise InputError(problems=[Problem("the robot has no arm joint to sample", hint="list robot.arm_joints")])
    sampler, sampled = make_sampler(sm, spec, loaded)
    variants = build_variants(sm, spec, sampled, loaded)
    qcols = [f"q_{n}" for n in sampler.names]
    grid_values = [r.grid(spec.sampling.n) for r in sampler.ranges] if sampler.method == "grid" else None
    stats = {v.name: StudyStats(v.kernel.columns, sampler.names, [(r.lower, r.upper) for r in sampler.ranges], grid_values,
                                best=spec.best, seed=spec.sampling.seed) for v in variants}
    comps = {v.name: Comparison(v.kernel.columns) for v in variants[1:]}
    bar = Progress(sampler.total * len(variants), f"analyze {loaded.mission.name}", enabled=progress)
    warm(analysis_kernel_calls(variants[0].kernel), what="analysis")  # a cold cache compiles here, not in the study
    t_compute = 0.0
    t0 = time.perf_counter()
    tables = {}
    with contextlib.ExitStack() as stack:
        if formats:
            for v in variants:
                tables[v.name] = stack.enter_context(sample_tables(out, f"analysis_{v.name}", qcols + v.kernel.columns,
                                                                   formats))
        done = 0
        for block, res, dt in _ahead(_evaluated(sampler, variants, evaluate_block)):
            t_compute += dt
            for v, r in zip(variants, res):
                if v.name in tables:
                    tables[v.name].write({**{c: block[:, j] for j, c in enumerate(qcols)}, **r})
                stats[v.name].add(block, r, done)
                if v.name in comps:
                    comps[v.name].add(res[0], r)
            done += len(block)
            bar.update(len(block) * len(variants))
    bar.close()
    t_total = time.perf_counter() - t0

    section.update({
        "samples": sampler.total, "method": sampler.method, "n": spec.sampling.n,
        "joints": [{"name": r.name, "lower": r.lower, "upper": r.upper} for r in sampler.ranges],
        "symmetry": spec.sampling.symmetry.model_dump() if spec.sampling.symmetry else None,
        "task": variants[0].kernel.task, "singular_tolerance": spec.singular_tolerance,
        "timing": {"compute_s": t_compute, "total_s": t_total,
                   "samples_per_s": sampler.total * len(variants) / t_compute if t_compute > 0 else None},
        "variants": {}, "comparison": {}, "artifacts": [],
    })
    for v in variants:
        st = stats[v.name].summary()
        idx = st["indices"]
        section["variants"][v.name] = {
            **st, "limits": v.limits, "skipped": dict(v.kernel.L.skipped),
            "singular_fraction": idx["singular"]["mean"] if "singular" in idx else None,
            "K_m_worst": idx["K_m"]["max"] if "K_m" in idx else None,
            "h_ratio_worst": idx["h_ratio"]["max"] if "h_ratio" in idx else None,
        }
        if v.name in tables:
            section["artifacts"] += table_names(f"analysis_{v.name}", formats)
    for name, comp in comps.items():
        section["comparison"][name] = comp.summary()

    if draw:
        section["artifacts"] += [p.name for p in _plots(P, out, variants, stats, loaded.mission.name, pool)]
    models = []
    if spec.modal is not None:
        modal = run_modal(sm, spec, out, loaded)
        section["modal"] = [m for m, _ in modal]
        models = [lin for _, lin in modal]
        for m in section["modal"]:
            section["artifacts"] += m["files"]
    return section, models


def _evaluated(sampler, variants, evaluate_block):
    """(block, indices per variant, seconds spent evaluating) for each block of the study, in order."""
    for block in sampler.chunks():
        tc = time.perf_counter()
        _, res = evaluate_block(variants, block)
        yield block, res, time.perf_counter() - tc


def _ahead(items):
    """The items of an iterator, in order, each produced on a background thread while the caller uses
    the previous one (one item ahead: the next block is sampled and evaluated, Pinocchio and the
    compiled kernels, while this thread writes the tables and the statistics of the current one).
    An error of the producer is raised here; leaving early stops it after its current item."""
    import queue
    import threading

    q: queue.Queue = queue.Queue(maxsize=1)
    stop = threading.Event()
    end = object()

    def send(message) -> bool:
        """Queue a message unless the consumer left (then False)."""
        while not stop.is_set():
            try:
                q.put(message, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def produce():
        try:
            for item in items:
                if not send((item, None)):
                    return
            send((end, None))
        except BaseException as exc:  # noqa: BLE001 - handed to the consumer
            send((end, exc))

    worker = threading.Thread(target=produce, name="sms-evaluate", daemon=True)
    worker.start()
    try:
        while True:
            item, exc = q.get()
            if exc is not None:
                raise exc
            if item is end:
                return
            yield item
    finally:
        stop.set()
        worker.join()


def _plots(P, out: Path, variants, stats, mission: str, pool) -> list[Path]:
    """Every workspace figure, drawn by ``pool`` (:class:`sms_cli.report.figpool.FigurePool`) and written
    here in a fixed order: per variant its index maps, histograms and slices, then the comparisons."""
    from sms_cli.results import write_bytes_atomic

    clouds = {}
    order, heavy, light = [], [], []  # figure files in artifact order; jobs, the costly ones first
    for v in variants:
        st = stats[v.name]
        rows = st.plot.rows
        cols = st.columns
        if not rows.size:
            continue
        xyz = rows[:, [cols.index("ee_x"), cols.index("ee_y"), cols.index("ee_z")]]
        clouds[v.name] = (xyz, rows, cols)
        items = [(out / f"analysis_{v.name}_{c}.png", rows[:, cols.index(c)], c,
                  f"{mission} ({v.name}): {P.LABELS.get(c, c)}, EE positions in the satellite frame")
                 for c in P.KEY_COLUMNS if c in cols]
        hist, sl = out / f"analysis_{v.name}_hist.png", out / f"analysis_{v.name}_slices.png"
        order += [p for p, *_ in items] + [hist, sl]
        heavy.append((P.clouds, (xyz, items)))
        light.append((_figure, (hist, P.histograms_png, (st.res.rows, cols, f"{mission} ({v.name})"))))
        light.append((_figure, (sl, P.slices_png, (st.slices(), cols, f"{mission} ({v.name})"))))
    if len(clouds) > 1:
        items = [(out / f"analysis_compare_{c}.png", [rows[:, cols.index(c)] for xyz, rows, cols in clouds.values()], c,
                  f"{mission}: {P.LABELS.get(c, c)} per variant (Kraiem 2022 Fig. 3.6-3.8 views)")
                 for c in ("K_m", "mu_null_lin_norm") if all(c in cl[2] for cl in clouds.values())]
        if items:
            order += [p for p, *_ in items]
            heavy.append((P.compare_figures, ([(n, xyz) for n, (xyz, _, _) in clouds.items()], items)))
    pngs = dict(item for result in pool.run(heavy + light) for item in result)
    return [write_bytes_atomic(p, pngs[p]) for p in order]


def _figure(path: Path, draw, args: tuple) -> list[tuple[Path, bytes]]:
    """A one-figure job of :func:`_plots`: ``draw(*args)`` (PNG bytes) for ``path``."""
    return [(path, draw(*args))]


def format_analysis(section: dict) -> str:
    """A short human-readable summary of the ``analysis`` section."""
    lines = [f"samples: {section['samples']:,} ({section['method']}, task rows: {section['task']}), "
             f"compute {section['timing']['compute_s']:.3f} s, total {section['timing']['total_s']:.2f} s"]
    keys = ("K_m", "mu_gjm", "mu_ratio", "mu_dyn", "mu_null_lin_norm", "h_ratio", "joint_limit_margin")
    for name, v in section["variants"].items():
        lines.append(f"[{name}]")
        shown = keys if "mu_gjm" in v["indices"] else ("mu_fixed",) + keys  # kinematics-only: the fixed-base μ
        for k in shown:
            d = v["indices"].get(k)
            if d and d["min"] is not None:
                lines.append(f"  {k:20s} min {d['min']:.4g}  p50 {d.get('p50', float('nan')):.4g}  max {d['max']:.4g}")
        if v.get("singular_fraction") is not None:
            lines.append(f"  singular fraction     {v['singular_fraction']:.4f}")
        for g, why in v["skipped"].items():
            lines.append(f"  skipped {g}: {why}")
    for name, comp in section.get("comparison", {}).items():
        if "K_m" in comp:
            c = comp["K_m"]
            lines.append(f"[{name} vs nominal] K_m lower at {100 * c['fraction_lower']:.1f}% of samples "
                         f"(change {c['min_change']:.3g} .. {c['max_change']:.3g})")
    for i, m in enumerate(section.get("modal", [])):
        fr = ", ".join(f"{x['frequency_hz']:.3g}" for x in m["modes"][:12])
        lines.append(f"modal[{i}] ({m['joints']} joints): coupled modes (Hz): {fr or 'none'}")
    lines.append(f"wrote {len(section['artifacts'])} files")
    return "\n".join(lines)
