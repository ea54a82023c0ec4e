"""``sms run``: every configured stage into one results folder, requirements, then the report.

A failing stage is reported and the stages that do not need it still run; the exit code is the
worst one met (0 ok < 1 requirements < 2 input < 3 numerical < 4 internal; 130 interrupted is
raised as KeyboardInterrupt). results.json gets two extra sections: ``run`` (provenance, the
writer's PID and the stage outcomes; ``state`` running → done or interrupted, read back as
``killed`` when the writer is gone) and ``requirements`` (the specs and their verdicts).

The results folder is locked for the whole run: a second writer gets exit 2 naming this one. A
folder holding the results of another mission (neither its name nor its mission file match) is
started afresh, and stderr says so: results of two missions are never mixed (``ResultsDir.writing``).

``RunSummary.as_dict`` is what ``sms run --json`` prints (keys documented there).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

from sms_cli.errors import EXIT_OK, EXIT_REQUIREMENTS, SmsError
from sms_cli.failures import failure, interrupted
from sms_cli.results import ResultsDir
from sms_cli.run.stages import STAGES, call_stage

#: sections `sms run` rewrites (stale ones from an earlier run are dropped first)
OWNED_SECTIONS = ("run", "requirements") + tuple(s.section for s in STAGES)


@dataclass
class StageOutcome:
    name: str
    status: str  # ok | failed | skipped | not configured | interrupted
    seconds: float = 0.0
    exit_code: int = 0
    message: str = ""


@dataclass
class RunSummary:
    mission: str
    out: Path
    stages: list[StageOutcome] = field(default_factory=list)
    verdicts: list = field(default_factory=list)
    report: Path | None = None

    @property
    def exit_code(self) -> int:
        codes = [s.exit_code for s in self.stages]
        if any(not v.passed for v in self.verdicts):
            codes.append(EXIT_REQUIREMENTS)
        return max(codes, default=EXIT_OK)

    def as_dict(self) -> dict:
        """The run as JSON data (``sms run --json``). Keys: ``mission``; ``results`` (the folder);
        ``stages`` (in order: name, status (ok | failed | skipped | not configured | interrupted),
        seconds, exit_code, message); ``verdicts`` (one per requirement: name, metric, stage, status,
        value, bound, unit, message, margin); ``report`` (its path, or null); ``exit_code``;
        ``passed`` (exit code 0); ``verdict`` (pass | requirements not met | failed)."""
        code = self.exit_code
        return {
            "mission": self.mission, "results": str(self.out), "stages": [asdict(s) for s in self.stages],
            "verdicts": [v.as_dict() for v in self.verdicts], "report": str(self.report) if self.report else None,
            "exit_code": code, "passed": code == EXIT_OK,
            "verdict": "pass" if code == EXIT_OK else "requirements not met" if code == EXIT_REQUIREMENTS else "failed",
        }


def _failure(exc: BaseException, debug: bool) -> tuple[int, str]:
    if debug and not isinstance(exc, SmsError):
        raise exc
    return failure(exc)


def _fresh(rd: ResultsDir) -> None:
    """Drop the sections an earlier run left, so nothing stale reaches the report or the check."""
    current = rd.read()
    kept = {k: v for k, v in current.items() if k not in OWNED_SECTIONS}
    if kept != current or not rd.file("results.json").exists():
        from sms_cli.results import write_json_atomic

        write_json_atomic(rd.file("results.json"), kept)


def _echo_err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def run_mission(mission_path: Path, out: Path, *, progress: bool | None = None, report: bool = True,
                debug: bool = False, echo: Callable[[str], None] = _echo_err) -> RunSummary:
    """Run the mission's stages into ``out``; returns the summary (never raises for a stage failure)."""
    from sms_cli.mission.load import load_mission

    loaded = load_mission(mission_path)
    rd = ResultsDir(out)
    with rd.writing(loaded.mission.name, loaded.path):
        return _run(loaded, mission_path, out, rd, progress, report, debug, echo)


def _run(loaded, mission_path: Path, out: Path, rd: ResultsDir, progress, report: bool, debug: bool,
         echo: Callable[[str], None]) -> RunSummary:
    from sms_cli.check.requirements import evaluate_all
    from sms_cli.run.provenance import provenance

    mission = loaded.mission
    _fresh(rd)
    prov = provenance(loaded, f"sms run {mission_path} -o {out}")
    summary = RunSummary(mission.name, rd.path)
    todo = [s for s in STAGES if s.configured(mission)]
    echo(f"sms run {mission.name} → {rd.path}/ ({len(todo)} stage{'s' if len(todo) != 1 else ''}: "
         f"{', '.join(s.name for s in todo) or 'none'})")

    def save_run(state: str) -> None:
        rd.update("run", {**prov, "state": state, "pid": os.getpid(), "stages": [asdict(s) for s in summary.stages],
                          "exit_code": summary.exit_code})

    save_run("running")
    failed: set[str] = set()
    for stage in STAGES:
        if not stage.configured(mission):
            why = "no robot" if stage.mission_key == "robot" else f"no '{stage.mission_key}:' section"
            summary.stages.append(StageOutcome(stage.name, "not configured", message=why))
            continue
        k = todo.index(stage) + 1
        blocked = [n for n in stage.needs if n in failed]
        if blocked:
            failed.add(stage.name)
            summary.stages.append(StageOutcome(stage.name, "skipped", message=f"needs {', '.join(blocked)}, which failed"))
            echo(f"[{k}/{len(todo)}] {stage.name}: skipped ({', '.join(blocked)} failed)")
            continue
        echo(f"[{k}/{len(todo)}] {stage.name} …")
        t0 = time.perf_counter()
        try:
            call_stage(stage, stage.load(), loaded, rd.path, progress)
            outcome = StageOutcome(stage.name, "ok", time.perf_counter() - t0)
        except KeyboardInterrupt:
            summary.stages.append(StageOutcome(stage.name, "interrupted", time.perf_counter() - t0, 130))
            save_run("interrupted")
            raise
        except Exception as exc:  # noqa: BLE001 - reported per stage, the run goes on
            if interrupted(exc):  # an interrupt Python wrapped while importing (failures.interrupted)
                summary.stages.append(StageOutcome(stage.name, "interrupted", time.perf_counter() - t0, 130))
                save_run("interrupted")
                raise KeyboardInterrupt from exc
            code, msg = _failure(exc, debug)
            outcome = StageOutcome(stage.name, "failed", time.perf_counter() - t0, code, msg)
            failed.add(stage.name)
        summary.stages.append(outcome)
        save_run("running")  # what a killed run leaves says which stages ended
        mark = "ok" if outcome.status == "ok" else f"FAILED (exit {outcome.exit_code})"
        echo(f"[{k}/{len(todo)}] {stage.name}: {mark} in {outcome.seconds:.2f} s")
        if outcome.message:
            echo("    " + outcome.message.replace("\n", "\n    "))

    results = rd.read()
    summary.verdicts = evaluate_all(list(mission.requirements), results)
    rd.update("requirements", {
        "specs": [r.model_dump(mode="json", exclude_defaults=True) for r in mission.requirements],
        "verdicts": [v.as_dict() for v in summary.verdicts],
        "passed": all(v.passed for v in summary.verdicts),
    })
    save_run("done")
    if report:
        from sms_cli.report.build import write_report

        t0 = time.perf_counter()
        try:
            summary.report = write_report(rd.path, rd.path / "report.html")
            summary.stages.append(StageOutcome("report", "ok", time.perf_counter() - t0))
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # noqa: BLE001
            code, msg = _failure(exc, debug)
            summary.stages.append(StageOutcome("report", "failed", time.perf_counter() - t0, code, msg))
            echo(f"report: FAILED: {msg}")
        save_run("done")
    return summary


def format_run(summary: RunSummary) -> str:
    """The verdict table: stage, status, time, requirement verdicts per stage."""
    per_stage: dict[str, list] = {}
    for v in summary.verdicts:
        per_stage.setdefault(v.stage, []).append(v)
    section_of = {s.name: s.section for s in STAGES}
    head = ["stage", "status", "time [s]", "requirements"]
    rows = []
    for s in summary.stages:
        vs = per_stage.pop(section_of.get(s.name, s.name), [])
        req = f"{sum(v.passed for v in vs)}/{len(vs)} met" if vs else "—"
        status = s.status if s.status != "failed" else f"FAILED ({s.exit_code})"
        rows.append([s.name, status, f"{s.seconds:.2f}" if s.status in ("ok", "failed", "interrupted") else "—", req])
    for stage, vs in per_stage.items():
        rows.append([stage, "—", "—", f"{sum(v.passed for v in vs)}/{len(vs)} met"])
    from sms_cli.check.requirements import text_table

    table, lines = text_table(head, rows)
    out = [f"== {summary.mission}: results in {summary.out}/ =="] + table + sum(lines, [])
    if summary.verdicts:
        from sms_cli.check.requirements import format_verdicts

        out += ["", format_verdicts(summary.verdicts).rstrip()]
    if summary.report:
        out.append(f"report: {summary.report}")
    code = summary.exit_code
    out.append("verdict: " + ("PASS" if code == 0 else "REQUIREMENTS NOT MET" if code == EXIT_REQUIREMENTS
                              else f"FAILED (exit {code})"))
    return "\n".join(out) + "\n"
