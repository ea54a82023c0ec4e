"""``sms check`` on a campaign's results folder: the campaign requirements of campaign.json.

A folder is a campaign's when it holds campaign.json (or its results.json has a ``campaign``
section). Its requirements (pass rates judged on the Wilson lower bound, signs of rank
correlations judged on their Fisher-z bound, :mod:`sms_cli.campaign.requirements`) are evaluated
against the runs of ``metrics/part-*.parquet``; the verdicts are those of a mission's
requirements (same table, same JUnit report). A campaign with runs not yet finished fails the
check, as an interrupted run does.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import ValidationError

from sms_cli.errors import InputError, Location, Problem
from sms_cli.results import RESULTS_FILE


def _folder(results_dir: Path) -> Path:
    p = Path(results_dir)
    return p.parent if p.name == RESULTS_FILE and not p.is_dir() else p


def is_campaign(results_dir: Path) -> bool:
    """Whether the folder (or the folder of a results.json) holds campaign.json."""
    from sms_cli.campaign.stats import CAMPAIGN_FILE

    return (_folder(results_dir) / CAMPAIGN_FILE).is_file()


def check_campaign(results_dir: Path, mission: Path | None = None, baseline: Path | None = None,
                   junit: Path | None = None, write_baseline: Path | None = None):
    """The :class:`~sms_cli.check.check.CheckOutcome` of a campaign folder's requirements; InputError
    when there is nothing to check or an option applies to a single run only."""
    from sms_cli.campaign import stats as S
    from sms_cli.campaign.requirements import evaluate_all, stored_specs
    from sms_cli.check.check import CheckOutcome

    folder = _folder(results_dir)
    f = folder / S.CAMPAIGN_FILE
    if not f.is_file():
        raise InputError(problems=[Problem(f"results.json has a campaign section but {S.CAMPAIGN_FILE} is missing: "
                                           "the campaign requirements are stored there", Location(folder),
                                           hint="run the campaign again into a new folder")])
    given = [o for o, v in (("--mission", mission), ("--baseline", baseline), ("--write-baseline", write_baseline)) if v]
    if given:
        raise InputError(problems=[Problem(f"{', '.join(given)} apply to the results of one run; {folder} is a campaign's, "
                                           f"checked against the requirements stored in {S.CAMPAIGN_FILE}",
                                           Location(folder), hint=f"sms check {folder}")])
    campaign = S.read_campaign(folder)
    try:
        specs = stored_specs(campaign)
    except ValidationError as exc:
        raise InputError(problems=[Problem(f"the stored campaign requirements are invalid ({exc.error_count()} problems)",
                                           Location(f), "requirements", "run the campaign again into a new folder")]) from None
    if not specs:
        raise InputError(problems=[Problem(f"nothing to check: {S.CAMPAIGN_FILE} has no campaign requirements", Location(f),
                                           hint="add a requirements: list (pass rates, correlations) to the campaign: "
                                                "section of the campaign file and run it again")])
    table = S.read_runs(folder)
    name = str(campaign.get("mission_name") or folder.resolve().name)
    outcome = CheckOutcome(name, results=str(folder), verdicts=evaluate_all(specs, table))
    n = S.counts(folder, table, campaign)
    if n["unfinished"]:
        outcome.incomplete = (f"{n['finished']} of {n['total']} runs of the campaign in {folder} finished: its statistics "
                              "are incomplete; resume the campaign (sms campaign --resume) to check it")
    if junit is not None:
        from sms_cli.check.junit import write_junit

        write_junit(junit, name, outcome.verdicts, None)
    return outcome
