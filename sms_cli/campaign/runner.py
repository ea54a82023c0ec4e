"""One campaign run, in-process: the mission with its samples → stages → metrics and read-back.

``execute_run`` is what a worker (or its sandbox) calls. It writes nothing: the metrics, the
requirement verdicts and the parameters read back from the built model go back to the client in
a ``RunOutcome``; ``sms campaign rerun`` replays one run with its recording (``record_run``).
"""

from __future__ import annotations

import copy
from dataclasses import replace
import math
import os
import socket
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from sms_cli.campaign import paths
from sms_cli.campaign.tasks import RunOutcome, RunTask, one_line
from sms_cli.errors import EXIT_INPUT, EXIT_NUMERICAL, EXIT_OK, EXIT_REQUIREMENTS, InputError, NumericalError

#: results.json keys that are not outcomes of the physics (times, files) and stay out of the metrics
_NOT_METRICS = {"timing", "files", "artifacts", "wall_s", "us_per_step", "real_time_factor"}
#: longest list flattened into metrics (longer ones are per-sample data, not figures)
_MAX_LIST = 64


def dispersed_tree(task: RunTask) -> dict[str, Any]:
    """The run's mission data: the campaign's tree with each sample written at its path (the
    undispersed mission is validated only when a vector component needs its SI numbers)."""
    from sms_cli.mission.load import load_mission_dict

    tree = copy.deepcopy(task.tree)
    tree.pop("campaign", None)
    if not task.samples:
        return tree
    pristine = {k: v for k, v in task.tree.items() if k != "campaign"}
    nominal = paths.Lazy(lambda: load_mission_dict(pristine, base_dir=task.base_dir, name=task.name).mission)
    for path, value in task.samples.values():
        if paths.is_link_path(paths.split(path)):
            _write_link(tree, path, value)
        else:
            paths.write(tree, path, np.asarray(value, float) if isinstance(value, list) else value, nominal)
    return tree


def _write_link(tree: dict, path: str, value) -> None:
    _, _, link, field = paths.split(path)
    links = tree.setdefault("robot", {}).setdefault("links", {})
    entry = links.setdefault(link, {})
    entry[field] = [float(x) for x in value] if isinstance(value, (list, np.ndarray)) else float(value)


def flatten(section: Any, prefix: str, out: dict[str, float]) -> None:
    """Every finite-or-NaN number of a results section by dotted key (list items as [name] or [i])."""
    if isinstance(section, dict):
        for k, v in section.items():
            if k not in _NOT_METRICS:
                flatten(v, f"{prefix}.{k}" if prefix else str(k), out)
    elif isinstance(section, (list, tuple)) and len(section) <= _MAX_LIST:
        for i, v in enumerate(section):
            name = v.get("name") if isinstance(v, dict) else None
            flatten(v, f"{prefix}[{name if isinstance(name, str) else i}]", out)
    elif isinstance(section, (bool, np.bool_)):
        out[prefix] = float(bool(section))
    elif isinstance(section, (int, float, np.integer, np.floating)):
        out[prefix] = float(section)
    elif section is None:
        out[prefix] = math.nan


def read_back(loaded, sm, task: RunTask) -> dict[str, float | list[float]]:
    """The value of each dispersed path in what ran: the built model for robot links and payloads,
    the validated mission (the specs the stages consumed) for the rest."""
    out: dict[str, float | list[float]] = {}
    for name, (path, _) in task.samples.items():
        parts = paths.split(path)
        if parts[0] == "payloads" and len(parts) == 3:
            value = _payload_value(loaded.mission, sm, parts[1], parts[2])
        else:
            value = paths.nominal(loaded.mission, path, sm)
        out[name] = [float(x) for x in value] if isinstance(value, np.ndarray) else float(value)
    return out


def _payload_value(mission, sm, ref: str, field: str):
    """A payload's mass from the built model (kg); its CoM and inertia as the model was given them."""
    spec = paths._child(mission.payloads, ref, "payloads")
    if field == "mass":
        return float(sm.payloads[spec.name].inertia_in_joint.mass)
    return paths.nominal(mission, f"payloads.{ref}.{field}")


def variant_task(task: RunTask, overlay: dict[str, Any]) -> RunTask:
    """The task on the mission with a variant's overlay merged in (as ``extends`` merges)."""
    from sms_cli.mission.load import _merge

    return replace(task, tree=_merge(task.tree, overlay), variants=())


#: which status a run with variants takes when its variants end differently (the worst one)
_WORST = {"ok": 0, "diverged": 1, "invalid": 2}


def execute_run(task: RunTask) -> RunOutcome:
    """Run the task's stages on its dispersed mission (nothing written, no recording). With variants,
    each runs on the same samples; metrics and requirements are then keyed ``<variant>.<metric>`` and
    ``<variant>: <requirement>``, the parameters read back from the first variant."""
    if task.variants:
        return _combined([(name, execute_run(variant_task(task, overlay))) for name, overlay in task.variants])
    t0 = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    base = dict(run=task.run, worker=worker, attempt=task.attempt)
    try:
        loaded, sm = _build(task)
    except InputError as exc:
        return RunOutcome(status="invalid", exit_status=EXIT_INPUT, message=one_line(exc) or type(exc).__name__,
                          wall_s=time.perf_counter() - t0, **base)
    params = read_back(loaded, sm, task)
    results, status, message = _stages(loaded, task.stages, task.gains_yaml)
    metrics: dict[str, float] = {}
    for key, section in results.items():
        flatten(section, key, metrics)
    verdicts = _requirements(loaded, results)
    failed = any(v is False for v in verdicts.values())
    exit_status = EXIT_NUMERICAL if status == "diverged" else EXIT_REQUIREMENTS if failed else EXIT_OK
    return RunOutcome(status=status, exit_status=exit_status, message=message, metrics=metrics,
                      params={k: (v if isinstance(v, float) else v) for k, v in params.items()},
                      requirements=verdicts, wall_s=time.perf_counter() - t0, **base)


def _combined(outcomes: list[tuple[str, RunOutcome]]) -> RunOutcome:
    first = outcomes[0][1]
    worst = max((o for _, o in outcomes), key=lambda o: (_WORST.get(o.status, 0), o.exit_status))
    return RunOutcome(
        run=first.run, status=worst.status, exit_status=max(o.exit_status for _, o in outcomes),
        message="; ".join(f"{name}: {o.message}" for name, o in outcomes if o.message),
        metrics={f"{name}.{k}": v for name, o in outcomes for k, v in o.metrics.items()},
        params=first.params, requirements={f"{name}: {k}": v for name, o in outcomes for k, v in o.requirements.items()},
        wall_s=sum(o.wall_s for _, o in outcomes), worker=first.worker, attempt=first.attempt)


def _build(task: RunTask):
    """(LoadedMission, SystemModel) of the dispersed mission; InputError when a draw is refused."""
    import sms_cli.api as api
    from sms_cli.mission.load import load_mission_dict

    loaded = load_mission_dict(dispersed_tree(task), base_dir=task.base_dir, name=task.name)
    return loaded, api.compile(loaded)


def _stages(loaded, stages: tuple[str, ...], gains_yaml: str | None = None) -> tuple[dict[str, Any], str, str]:
    """results.json sections of the stages, the run's status and why it stopped early. The simulation
    reads the gains its own synthesize stage wrote, else ``gains_yaml`` (the nominal mission's)."""
    import sms_cli.api as api

    results: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="sms-campaign-") as gains_dir:
        if gains_yaml is not None:
            Path(gains_dir, "gains.yaml").write_text(gains_yaml, encoding="utf-8")
        for stage in stages:
            try:
                if stage == "analyze":
                    results["analysis"] = api.analyze(loaded, plots=False).section
                elif stage == "synthesize":
                    done = api.synthesize(loaded, out=gains_dir, plots=False)
                    results["synthesis"] = done.section
                else:
                    gains = gains_dir if "synthesize" in stages or gains_yaml is not None else None
                    results["simulate"] = api.simulate(loaded, gains_dir=gains).section
            except NumericalError as exc:
                partial = getattr(exc, "result", None)
                if partial is not None:
                    results["simulate" if stage == "simulate" else "synthesis"] = partial.section
                return results, "diverged", one_line(exc) or type(exc).__name__
    return results, "ok", ""


def _requirements(loaded, results: dict[str, Any]) -> dict[str, bool | None]:
    """The mission's requirements on the stages that ran: passed, failed (False) or unreadable (None)."""
    from sms_cli.check.requirements import evaluate

    out: dict[str, bool | None] = {}
    for req in loaded.mission.requirements:
        if req.section() not in results:
            continue
        v = evaluate(req, results)
        out[req.name] = None if v.status == "error" else v.passed
    return out


def record_run(task: RunTask, out: Path) -> dict[str, Any]:
    """Replay one run with the recording (``sms campaign rerun``): the CLI's stages into ``out``
    (each variant into ``out/<variant>/``). Returns the run's metrics (keyed as ``execute_run`` keys them)."""
    import sms_cli.api as api

    if task.variants:
        return {f"{name}.{k}": v for name, overlay in task.variants
                for k, v in record_run(variant_task(task, overlay), out / name).items()}
    loaded, _ = _build(task)
    results: dict[str, Any] = {}
    out.mkdir(parents=True, exist_ok=True)
    if task.gains_yaml is not None and "synthesize" not in task.stages:
        from sms_cli.results import write_text_atomic

        write_text_atomic(out / "gains.yaml", task.gains_yaml)
    for stage in task.stages:
        try:
            if stage == "analyze":
                results["analysis"] = api.analyze(loaded, out=out, plots=False).section
            elif stage == "synthesize":
                results["synthesis"] = api.synthesize(loaded, out=out, plots=False).section
            else:
                results["simulate"] = api.simulate(loaded, out=out).section
        except NumericalError as exc:
            partial = getattr(exc, "result", None)
            if partial is not None:
                results["simulate" if stage == "simulate" else "synthesis"] = partial.section
            break
    metrics: dict[str, float] = {}
    for key, section in results.items():
        flatten(section, key, metrics)
    return metrics
