"""``sms campaign rerun RESULTS --run ID``: one run of a campaign again, recorded, compared.

The run is drawn again from campaign.json (the entropy and the run id give its samples), run
through the CLI's stages into ``RESULTS/runs/<id>/`` with its MCAP, and its metrics compared with
the ones the campaign stored: equal to the last bit, or the differences are listed.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

from sms_cli.errors import InputError, Location, Problem


def _campaign_meta(results: Path) -> dict[str, Any]:
    f = Path(results) / "campaign.json"
    if not f.exists():
        raise InputError(problems=[Problem(f"no campaign.json in {results}: not the results of a campaign",
                                           Location(results), hint="run one first: sms campaign CAMPAIGN.yaml -o DIR")])
    from sms_cli.outputs import read_json_file

    meta, _ = read_json_file(f, "campaign file", f"run the campaign again into {results} with --restart")
    return meta


def rerun(results: Path, run_id: int, out: Path | None = None) -> dict[str, Any]:
    """Replay run ``run_id``; returns {run, out, identical, compared, differences: [...]}."""
    from sms_cli.campaign.runner import record_run
    from sms_cli.campaign.stage import define
    from sms_cli.campaign.stats import read_runs
    from sms_cli.mission.load import load_mission

    results = Path(results)
    meta = _campaign_meta(results)
    loaded = load_mission(meta["mission"])
    if hashlib.sha256(loaded.text.encode("utf-8")).hexdigest() != meta.get("mission_sha256"):
        raise InputError(problems=[Problem(f"{meta['mission']} changed since the campaign ran: its runs cannot be "
                                           "replayed exactly", Location(Path(meta["mission"])),
                                           hint="restore the campaign file as it was (campaign.json has its SHA-256)")])
    campaign = define(loaded, int(meta["entropy"]))
    if not 0 <= run_id < campaign.runs:
        raise InputError(problems=[Problem(f"run {run_id} is not in this campaign (runs 0 to {campaign.runs - 1})",
                                           Location(results / "campaign.json"), hint="pick a run from manifest.jsonl")])
    stored = _stored_metrics(read_runs(results), run_id)
    target = out if out is not None else results / "runs" / str(run_id)
    metrics = record_run(campaign.tasks([run_id])[0], target)
    diffs = []
    for key, want in sorted(stored.items()):
        got = metrics.get(key, math.nan)
        if not (got == want or (math.isnan(got) and math.isnan(want))):
            diffs.append({"metric": key, "campaign": want, "rerun": got})
    return {"run": run_id, "out": str(target), "identical": not diffs and stored != {}, "compared": len(stored),
            "differences": diffs, "stored": bool(stored)}


def _stored_metrics(table, run_id: int) -> dict[str, float]:
    if table.num_rows == 0:
        return {}
    runs = table.column("run").to_pylist()
    if run_id not in runs:
        return {}
    i = len(runs) - 1 - runs[::-1].index(run_id)  # the last part written wins
    return {c[len("metric."):]: (math.nan if table.column(c)[i].as_py() is None else float(table.column(c)[i].as_py()))
            for c in table.column_names if c.startswith("metric.")}


def format_rerun(o: dict[str, Any]) -> str:
    if not o["stored"]:
        return f"run {o['run']} replayed into {o['out']}/; the campaign has no stored metrics for it to compare\n"
    if o["identical"]:
        return f"run {o['run']} replayed into {o['out']}/: its {o['compared']} metrics equal the campaign's to the last bit\n"
    lines = [f"run {o['run']} replayed into {o['out']}/: {len(o['differences'])} of {o['compared']} metrics differ:"]
    lines += [f"  {d['metric']}: campaign {d['campaign']!r}, rerun {d['rerun']!r}" for d in o["differences"][:20]]
    return "\n".join(lines) + "\n"
