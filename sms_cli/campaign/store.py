"""The results folder of a campaign, written by the client process only.

- ``campaign.json``: what the campaign is (mission and its SHA-256, entropy, parameters); a
  ``--resume`` must find the same campaign there.
- ``manifest.jsonl``: append-only, one line per attempt, flushed and fsync'ed line by line, so a
  killed client loses at most the attempt it was writing (a torn last line is ignored on reading).
- ``metrics/part-NNNNN.parquet``: finished runs in blocks (each part written whole, atomically).

Nothing here deletes: ``--restart`` moves an earlier campaign into ``previous/<time>/``.
"""

from __future__ import annotations

import json
import os
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from sms_cli.campaign.tasks import FINISHED, RunOutcome
from sms_cli.errors import InputError, Location, Problem
from sms_cli.results import _jsonable, atomic_path, write_json_atomic

CAMPAIGN_FILE, MANIFEST_FILE, METRICS_DIR = "campaign.json", "manifest.jsonl", "metrics"
#: finished runs per Parquet part, and the longest a finished run waits in memory (s)
BLOCK_ROWS, BLOCK_SECONDS = 64, 30.0
#: what identifies a campaign: a resume must find these equal
IDENTITY = ("mission_sha256", "entropy", "design", "runs", "parameters", "stages")


def read_manifest(folder: Path) -> list[dict[str, Any]]:
    """Every whole line of the manifest (a torn last line, from a killed client, is skipped)."""
    f = Path(folder) / MANIFEST_FILE
    if not f.exists():
        return []
    out = []
    for line in f.read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(line)
        except ValueError:
            continue
        if isinstance(rec, dict) and "run" in rec:
            out.append(rec)
    return out


def finished_runs(folder: Path) -> set[int]:
    """Runs with a finished attempt (ok, invalid, diverged) in the manifest and their metrics stored."""
    stored = stored_runs(folder)
    return {int(r["run"]) for r in read_manifest(folder) if r.get("status") in FINISHED} & stored


def stored_runs(folder: Path) -> set[int]:
    import pyarrow.parquet as pq

    runs: set[int] = set()
    for part in sorted((Path(folder) / METRICS_DIR).glob("part-*.parquet")):
        runs.update(int(x) for x in pq.read_table(part, columns=["run"]).column("run").to_pylist())
    return runs


def attempts_so_far(folder: Path) -> dict[int, int]:
    """Highest attempt number of each run in the manifest."""
    out: dict[int, int] = {}
    for r in read_manifest(folder):
        out[int(r["run"])] = max(out.get(int(r["run"]), 0), int(r.get("attempt", 1)))
    return out


class CampaignStore:
    """Writes one campaign's folder (see the module docstring). Use as a context manager: leaving
    it writes the finished runs still in memory."""

    def __init__(self, folder: Path, meta: dict[str, Any], seed_of):
        self.folder = Path(folder)
        self.meta = meta
        self.seed_of = seed_of  # run → its seed record, e.g. {"entropy": E, "spawn_key": [run]}
        self._rows: list[RunOutcome] = []
        self._since = time.monotonic()
        self._manifest = None

    # ------------------------------------------------------------------ opening
    @staticmethod
    def state(folder: Path) -> str:
        """'empty' (absent or empty folder), 'campaign' (holds a campaign) or 'other' (holds other files)."""
        folder = Path(folder)
        if not folder.exists() or not any(p for p in folder.iterdir() if p.name != ".sms.lock"):
            return "empty"
        return "campaign" if (folder / CAMPAIGN_FILE).exists() else "other"

    def check_resumable(self) -> None:
        """InputError unless the folder holds this same campaign (same mission text, entropy, parameters)."""
        f = self.folder / CAMPAIGN_FILE
        try:
            old = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(problems=[Problem(f"cannot read the campaign to resume: {exc}", Location(f),
                                               hint="start it over with --restart (the old one is kept)")]) from None
        new = _jsonable(self.meta)
        changed = [k for k in IDENTITY if old.get(k) != new.get(k)]
        if changed:
            raise InputError(problems=[Problem(
                f"this folder holds another campaign (its {', '.join(changed)} differ{'s' if len(changed) == 1 else ''})",
                Location(f), hint="resume with the campaign file that started it, or --restart (the old one is kept)")])

    def archive_previous(self) -> Path:
        """Move what the folder holds into previous/<UTC time>/ (``--restart``): nothing is deleted."""
        dest = self.folder / "previous" / datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S")
        dest.mkdir(parents=True)
        for p in list(self.folder.iterdir()):
            if p.name not in ("previous", ".sms.lock"):
                p.rename(dest / p.name)
        return dest

    def __enter__(self) -> CampaignStore:
        self.folder.mkdir(parents=True, exist_ok=True)
        (self.folder / METRICS_DIR).mkdir(exist_ok=True)
        write_json_atomic(self.folder / CAMPAIGN_FILE, self.meta)
        self._manifest = open(self.folder / MANIFEST_FILE, "a", encoding="utf-8")
        return self

    def __exit__(self, *exc) -> None:
        self.flush()
        if self._manifest is not None:
            self._manifest.close()

    # ------------------------------------------------------------------ writing
    def record(self, o: RunOutcome) -> None:
        """One attempt: its manifest line now; its metrics with the next block when it finished the run."""
        line = {"run": o.run, "attempt": o.attempt, "status": o.status, "seed": self.seed_of(o.run),
                "wall_s": round(o.wall_s, 6), "exit_status": o.exit_status, "message": o.message,
                "worker": o.worker, "time": datetime.now(timezone.utc).isoformat(timespec="seconds")}
        if o.status in FINISHED:
            self._rows.append(o)
        if len(self._rows) >= BLOCK_ROWS or (self._rows and time.monotonic() - self._since > BLOCK_SECONDS):
            self.flush()  # the metrics first: a manifest line never names a finished run whose row is lost
        self._manifest.write(json.dumps(_jsonable(line)) + "\n")
        self._manifest.flush()
        os.fsync(self._manifest.fileno())

    def flush(self) -> None:
        """Write the finished runs held in memory as one Parquet part (atomically)."""
        if not self._rows:
            return
        import pyarrow.parquet as pq

        table = outcomes_table(self._rows, self.meta)
        n = len(list((self.folder / METRICS_DIR).glob("part-*.parquet")))
        target = self.folder / METRICS_DIR / f"part-{n:05d}.parquet"
        while target.exists():
            n += 1
            target = self.folder / METRICS_DIR / f"part-{n:05d}.parquet"
        with atomic_path(target) as tmp:
            pq.write_table(table, tmp)
        self._rows.clear()
        self._since = time.monotonic()


def outcomes_table(rows: list[RunOutcome], meta: dict[str, Any]):
    """The Parquet table of finished runs: run, status, exit_status, param.*, metric.*, req.*."""
    import pyarrow as pa

    names = [p["name"] for p in meta["parameters"]]
    metric_keys = sorted({k for o in rows for k in o.metrics})
    req_keys = sorted({k for o in rows for k in o.requirements})
    cols: dict[str, Any] = {
        "run": pa.array([o.run for o in rows], pa.int64()),
        "status": pa.array([o.status for o in rows], pa.string()),
        "exit_status": pa.array([o.exit_status for o in rows], pa.int8()),
        "message": pa.array([o.message for o in rows], pa.string()),
    }
    for n in names:
        cols[f"param.{n}"] = pa.array([_scalar_param(o.params.get(n), n, meta) for o in rows], pa.float64())
    for k in metric_keys:
        cols[f"metric.{k}"] = pa.array([o.metrics.get(k, float("nan")) for o in rows], pa.float64())
    for k in req_keys:
        cols[f"req.{k}"] = pa.array([o.requirements.get(k) for o in rows], pa.bool_())
    return pa.table(cols)


def _scalar_param(value, name: str, meta: dict[str, Any]) -> float | None:
    """A parameter's table number: the value, or for a vector the one number ``Parameter.scalar`` keeps."""
    if value is None:
        return None
    if not isinstance(value, list):
        return float(value)
    from sms_cli.campaign.dispersions import scalar_of

    p = next(p for p in meta["parameters"] if p["name"] == name)
    return scalar_of(p["mode"], p["nominal"], value)
