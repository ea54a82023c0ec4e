"""``sms check``: requirements and a regression baseline against a results folder → exit code.

Requirements come from ``--mission`` (its ``requirements:`` list), else from the copy ``sms run``
stored in results.json (section ``requirements.specs``). Exit 1 when a requirement or a baseline
metric fails (a missing metric is a failure too), 2 when there is nothing to check or an input is
invalid. A check that cannot run still writes the ``--junit`` report asked for: one failing test
case that carries the error, so CI shows why (``run_check``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from sms_cli.check.baseline import Drift, compare, format_drifts, make_baseline, read_baseline
from sms_cli.check.metrics import damaged_sections, section
from sms_cli.check.requirements import Verdict, evaluate_all, format_verdicts
from sms_cli.check.schema import RequirementSpec
from sms_cli.errors import EXIT_INPUT, EXIT_NUMERICAL, EXIT_OK, EXIT_REQUIREMENTS, InputError, Location, Problem
from sms_cli.outputs import key_line, kind_of, read_json_file
from sms_cli.results import RESULTS_FILE, with_run_state, write_json_atomic


def _rerun(folder: Path) -> str:
    return f"re-run the mission into it: sms run MISSION.yaml -o {folder}"


def load_results(folder: Path) -> tuple[dict[str, Any], bytes, Path]:
    """(results, raw bytes, file) of a results folder or of its results.json; InputError naming the
    file and line when it is absent, damaged or not a mapping of sections."""
    f = folder / RESULTS_FILE if folder.is_dir() else folder
    if not f.exists():
        raise InputError(problems=[Problem(f"no {RESULTS_FILE} in {folder}", Location(folder),
                                           hint="run the mission first: sms run MISSION.yaml -o " + str(folder))])
    data, raw = read_json_file(f, "results file", _rerun(f.parent))
    if not isinstance(data, dict):
        raise InputError(problems=[Problem(f"is {kind_of(data)}, not the results of a run (a mapping of stage sections)",
                                           Location(f, 1), hint=_rerun(f.parent))])
    return with_run_state(data), raw, f


def read_results(folder: Path) -> tuple[dict[str, Any], Path]:
    """(results, file) of a results folder, every section readable (InputError otherwise)."""
    results, raw, f = load_results(folder)
    damaged = damaged_sections(results)
    if damaged:
        probs = [Problem(what, Location(f, key_line(raw, name))) for name, what in damaged.items()]
        probs[-1].hint = _rerun(f.parent)
        raise InputError(f"{f} is damaged", problems=probs)
    return results, f


def stored_requirements(results: dict[str, Any], where: Path) -> list[RequirementSpec] | None:
    """The requirement specs ``sms run`` copied into results.json (None when there are none)."""
    specs = section(results, "requirements").get("specs")
    if specs is None:
        return None
    hint = "pass --mission MISSION.yaml to read them from the mission file, or " + _rerun(where.parent)
    if not isinstance(specs, list):
        raise InputError(problems=[Problem(f"requirements.specs is {kind_of(specs)}, not a list", Location(where),
                                           hint=hint)])
    try:
        return [RequirementSpec.model_validate(s) for s in specs]
    except ValidationError as exc:
        raise InputError(problems=[Problem(f"the stored requirements are invalid ({exc.error_count()} problems)",
                                           Location(where), "requirements.specs", hint)]) from None


@dataclass
class CheckOutcome:
    mission: str
    verdicts: list[Verdict] | None = None
    drifts: list[Drift] | None = None
    notes: list[str] = field(default_factory=list)
    incomplete: str = ""  # why the results are not those of a whole run (killed, interrupted): the check fails
    results: str = ""  # the results folder checked

    @property
    def exit_code(self) -> int:
        bad = any(not v.passed for v in self.verdicts or []) or any(not d.passed for d in self.drifts or [])
        return EXIT_REQUIREMENTS if bad or self.incomplete else EXIT_OK

    def format(self) -> str:
        out = []
        if self.verdicts is not None:
            out.append(format_verdicts(self.verdicts))
        if self.drifts is not None:
            out.append(format_drifts(self.drifts))
        out.extend(n + "\n" for n in self.notes)
        if self.incomplete:
            out.append(f"FAIL: {self.incomplete}\n")
        out.append(("PASS" if self.exit_code == 0 else "FAIL") + f": {self.mission}\n")
        return "".join(out)

    def as_dict(self) -> dict[str, Any]:
        """The outcome as JSON data (``sms check --json``). Keys: ``mission``; ``results`` (the folder
        checked); ``passed`` and
        ``exit_code`` (0 or 1); ``verdicts`` (one per requirement: name, metric, stage, status, value,
        bound, unit, message, margin; null when no requirements were checked); ``drifts`` (one per
        baseline metric: metric, status, value, expected, allowed, message; null without
        ``--baseline``); ``notes``; ``incomplete`` (why the results are not those of a whole run, or
        null)."""
        return {
            "mission": self.mission, "results": self.results, "passed": self.exit_code == EXIT_OK, "exit_code": self.exit_code,
            "verdicts": None if self.verdicts is None else [v.as_dict() for v in self.verdicts],
            "drifts": None if self.drifts is None else [asdict(d) for d in self.drifts],
            "notes": list(self.notes), "incomplete": self.incomplete or None,
        }


def run_check(results_dir: Path, mission: Path | None = None, baseline: Path | None = None,
              junit: Path | None = None, write_baseline: Path | None = None) -> CheckOutcome:
    """Evaluate requirements and/or a baseline; write JUnit / a new baseline when asked. When the
    check cannot run, its error is raised after writing ``junit`` (if given) as one failing test case."""
    try:
        return _check(results_dir, mission, baseline, junit, write_baseline)
    except Exception as exc:
        if junit is not None:
            _junit_of_failure(junit, mission.stem if mission is not None else _folder_name(results_dir), exc)
        raise


def _folder_name(results_dir: Path) -> str:
    p = Path(results_dir)
    return (p.parent if p.name == RESULTS_FILE else p).resolve().name or str(p)


def _junit_of_failure(junit: Path, suite: str, exc: Exception) -> None:
    from sms_cli.check.junit import write_error_junit
    from sms_cli.failures import failure

    code, message = failure(exc)
    kind = {EXIT_INPUT: "input error", EXIT_NUMERICAL: "numerical failure"}.get(code, "internal error")
    try:
        write_error_junit(junit, suite, kind, f"sms check could not run (exit {code}): {message}")
    except OSError:
        pass  # the check's own error is the one to report


def _check(results_dir: Path, mission: Path | None, baseline: Path | None, junit: Path | None,
           write_baseline: Path | None) -> CheckOutcome:
    from sms_cli.check.campaign import check_campaign, is_campaign

    if is_campaign(results_dir):
        return check_campaign(results_dir, mission, baseline, junit, write_baseline)
    results, results_file = read_results(results_dir)
    if isinstance(results.get("campaign"), dict):  # campaign.json is missing: check_campaign says so
        return check_campaign(results_dir, mission, baseline, junit, write_baseline)
    name = str(section(results, "run").get("mission") or section(results, "compile").get("name") or Path(results_dir).name)
    outcome = CheckOutcome(name, results=str(results_dir))
    state = section(results, "run").get("state")
    if state in ("killed", "interrupted"):
        outcome.incomplete = (f"the run into {Path(results_dir)} was {state}: its results are incomplete; "
                              "re-run the mission to check it")
    reqs: list[RequirementSpec] | None
    if mission is not None:
        from sms_cli.mission.load import load_mission

        loaded = load_mission(mission)
        name = outcome.mission = loaded.mission.name
        reqs = list(loaded.mission.requirements)
        if not reqs:
            outcome.notes.append(f"note: {mission} has no requirements")
    else:
        reqs = stored_requirements(results, results_file)
    if write_baseline is not None:
        data = make_baseline(results)
        write_json_atomic(write_baseline, data)
        outcome.notes.append(f"wrote baseline {write_baseline} ({len(data['metrics'])} metrics)")
    if reqs:
        outcome.verdicts = evaluate_all(reqs, results)
    if baseline is not None:
        outcome.drifts = compare(results, read_baseline(baseline))
    if outcome.verdicts is None and outcome.drifts is None and write_baseline is None:
        raise InputError(problems=[Problem(
            "nothing to check: no requirements and no baseline", Location(results_dir),
            hint="pass --mission MISSION.yaml (with a requirements: list), --baseline FILE, or --write-baseline FILE")])
    if junit is not None:
        from sms_cli.check.junit import write_junit

        write_junit(junit, name, outcome.verdicts if outcome.verdicts is not None else ([] if reqs is not None else None),
                    outcome.drifts)
    return outcome
