"""``sms check``: requirements and a regression baseline against a results folder → exit code.

Requirements come from ``--mission`` (its ``requirements:`` list), else from the copy ``sms run``
stored in results.json (section ``requirements.specs``). Exit 1 when a requirement or a baseline
metric fails (a missing metric is a failure too), 2 when there is nothing to check or an input is
invalid.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from sms_cli.check.baseline import Drift, compare, format_drifts, make_baseline, read_baseline
from sms_cli.check.requirements import Verdict, evaluate_all, format_verdicts
from sms_cli.check.schema import RequirementSpec
from sms_cli.errors import EXIT_OK, EXIT_REQUIREMENTS, InputError, Location, Problem
from sms_cli.results import RESULTS_FILE, write_json_atomic


def read_results(folder: Path) -> dict[str, Any]:
    """results.json of a results folder (InputError when absent or unreadable)."""
    f = folder / RESULTS_FILE if folder.is_dir() else folder
    if not f.exists():
        raise InputError(problems=[Problem(f"no {RESULTS_FILE} in {folder}", Location(folder),
                                           hint="run the mission first: sms run MISSION.yaml -o " + str(folder))])
    try:
        return json.loads(f.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(problems=[Problem(f"not JSON: {exc.msg}", Location(f, exc.lineno, exc.colno))]) from None


def stored_requirements(results: dict[str, Any]) -> list[RequirementSpec] | None:
    """The requirement specs ``sms run`` copied into results.json (None when there are none)."""
    specs = results.get("requirements", {}).get("specs")
    if specs is None:
        return None
    try:
        return [RequirementSpec.model_validate(s) for s in specs]
    except ValidationError as exc:
        raise InputError(f"results.json: stored requirements are invalid ({exc.error_count()} problems); "
                         "pass --mission to read them from the mission file") from None


@dataclass
class CheckOutcome:
    mission: str
    verdicts: list[Verdict] | None = None
    drifts: list[Drift] | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        bad = any(not v.passed for v in self.verdicts or []) or any(not d.passed for d in self.drifts or [])
        return EXIT_REQUIREMENTS if bad else EXIT_OK

    def format(self) -> str:
        out = []
        if self.verdicts is not None:
            out.append(format_verdicts(self.verdicts))
        if self.drifts is not None:
            out.append(format_drifts(self.drifts))
        out.extend(n + "\n" for n in self.notes)
        out.append(("PASS" if self.exit_code == 0 else "FAIL") + f": {self.mission}\n")
        return "".join(out)


def run_check(results_dir: Path, mission: Path | None = None, baseline: Path | None = None,
              junit: Path | None = None, write_baseline: Path | None = None) -> CheckOutcome:
    """Evaluate requirements and/or a baseline; write JUnit / a new baseline when asked."""
    results = read_results(results_dir)
    name = results.get("run", {}).get("mission") or results.get("compile", {}).get("name") or Path(results_dir).name
    outcome = CheckOutcome(name)
    reqs: list[RequirementSpec] | None
    if mission is not None:
        from sms_cli.mission.load import load_mission

        loaded = load_mission(mission)
        name = outcome.mission = loaded.mission.name
        reqs = list(loaded.mission.requirements)
        if not reqs:
            outcome.notes.append(f"note: {mission} has no requirements")
    else:
        reqs = stored_requirements(results)
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
