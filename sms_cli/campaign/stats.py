"""Statistics of a campaign's results folder → results.json section ``campaign``.

Which runs count where:

- counts come from campaign.json (runs declared), the metric parts (finished runs by status) and
  manifest.jsonl (attempts, retried attempts);
- metric statistics and sensitivities use the runs that ran (status ``ok`` or ``diverged``; an
  ``invalid`` draw never ran), each pair or value with NaN dropped;
- pass rates count the same runs: ``invalid`` runs are excluded, a ``diverged`` run or a missing
  metric is a failure.

Pass rates carry the Wilson score interval (scipy's ``binomtest(...).proportion_ci``), rank
correlations Spearman's ρ (``scipy.stats.spearmanr``) with a Fisher-z interval whose standard error
is √(1.06 / (n − 3)) (Fieller, Hartley & Pearson 1957, for rank correlations).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from sms_cli.campaign.store import CAMPAIGN_FILE, METRICS_DIR, read_manifest
from sms_cli.campaign.tasks import FINISHED, RETRIED

PARAM, METRIC, REQ = "param.", "metric.", "req."
RAN = ("ok", "diverged")  # statuses of runs that executed their stages
PERCENTILES = (1, 5, 50, 95, 99)
CONFIDENCE = 0.95  # of the intervals of the mission requirements' pass rates and of the sensitivities


# ----------------------------------------------------------------- reading the folder


def _natural(p: Path) -> list:
    """Sort key: part-9 before part-10."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def part_files(folder: Path) -> list[Path]:
    """The metric parts of a results folder in the order they were written."""
    return sorted((Path(folder) / METRICS_DIR).glob("part-*.parquet"), key=_natural)


def _read_part(f: Path) -> pa.Table:
    """One metric part (InputError when it is not a readable Parquet file with a ``run`` column)."""
    from sms_cli.errors import InputError, Location, Problem

    try:
        table = pq.read_table(f)
    except (pa.ArrowException, OSError) as exc:
        raise InputError(problems=[Problem(f"not a readable Parquet file ({exc}): the metric part is damaged",
                                           Location(f))]) from None
    if "run" not in table.column_names or "status" not in table.column_names:
        raise InputError(problems=[Problem("has no 'run' and 'status' columns: not a metric part of a campaign", Location(f))])
    return table


def read_runs(folder: Path) -> pa.Table:
    """One row per finished run, sorted by run: the parts concatenated (columns missing from a part
    are null), a run present in several parts kept from the last part written."""
    tables = [_read_part(f) for f in part_files(folder)]
    if not tables:
        return pa.table({"run": pa.array([], pa.int64()), "status": pa.array([], pa.string()),
                         "exit_status": pa.array([], pa.int64())})
    table = pa.concat_tables(tables, promote_options="permissive")
    runs = table.column("run").to_numpy()
    last = len(runs) - 1 - np.unique(runs[::-1], return_index=True)[1]  # last row of each run, by run
    return table.take(pa.array(last))


def read_campaign(folder: Path) -> dict[str, Any]:
    """campaign.json of a results folder ({} when absent; InputError with the line when damaged)."""
    from sms_cli.errors import InputError, Location, Problem
    from sms_cli.outputs import kind_of, read_json_file

    f = Path(folder) / CAMPAIGN_FILE
    if not f.exists():
        return {}
    data, _ = read_json_file(f, "campaign file", "run the campaign again into a new folder")
    if not isinstance(data, dict):
        raise InputError(problems=[Problem(f"is {kind_of(data)}, not the resolved campaign (a mapping)", Location(f, 1))])
    return data


def column(table: pa.Table, name: str) -> np.ndarray:
    """A column as float64 (null → NaN; booleans → 0/1); all NaN when the table lacks it."""
    if name not in table.column_names:
        return np.full(table.num_rows, np.nan)
    col = table.column(name)
    if pa.types.is_boolean(col.type) or pa.types.is_integer(col.type) or pa.types.is_floating(col.type):
        return col.cast(pa.float64()).to_numpy(zero_copy_only=False).astype(float)
    return np.full(table.num_rows, np.nan)


def statuses(table: pa.Table) -> np.ndarray:
    return np.array(table.column("status").to_pylist(), dtype=object) if table.num_rows else np.array([], dtype=object)


def names(table: pa.Table, prefix: str) -> list[str]:
    """Names of the columns with ``prefix`` (prefix removed), in table order."""
    return [c[len(prefix):] for c in table.column_names if c.startswith(prefix)]


# ----------------------------------------------------------------- intervals and correlations


def _num(x: float | None) -> float | None:
    """A JSON-safe float (NaN/inf → None)."""
    return float(x) if x is not None and math.isfinite(float(x)) else None


def wilson(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float] | None:
    """Wilson score interval (low, high) of a proportion k/n at a two-sided ``confidence``; None when n = 0."""
    if n <= 0:
        return None
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def pass_rate(passed: np.ndarray, status: np.ndarray, confidence: float = CONFIDENCE) -> dict[str, Any]:
    """Pass rate of per-run outcomes (1 pass, 0 fail, NaN missing metric) over the runs that ran:
    ``invalid`` runs excluded, ``diverged`` and missing count as failures. Keys: passed, n, rate,
    low, high, confidence (rate and bounds None when no run counts)."""
    counted = np.isin(status, RAN)
    ok = counted & (status == "ok") & (passed == 1.0)
    k, n = int(ok.sum()), int(counted.sum())
    ci = wilson(k, n, confidence)
    return {"passed": k, "n": n, "rate": k / n if n else None, "low": ci[0] if ci else None,
            "high": ci[1] if ci else None, "confidence": confidence}


def spearman(x: np.ndarray, y: np.ndarray, confidence: float = CONFIDENCE) -> dict[str, Any] | None:
    """Spearman's ρ of the finite (x, y) pairs with its Fisher-z interval; None when fewer than 4
    pairs or either side is constant. Keys: rho, low, high, n, p_value, confidence.

    Perfectly ordered ranks (|ρ| = 1) would give atanh(±1) = ±∞ and an interval of one point
    whatever n is; the interval is then taken about the largest |ρ| short of 1 that n ranks can
    give less half a step, 1 − 6/(n³ − n) (so 4 perfectly ordered runs, which chance orders so one
    time in 12, do not make a sign significant; 6 do)."""
    from scipy.stats import norm, spearmanr

    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    n = len(x)
    if n < 4 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return None
    res = spearmanr(x, y)
    rho = float(np.clip(res.statistic, -1.0, 1.0))
    half = norm.ppf(0.5 + confidence / 2) * math.sqrt(1.06 / (n - 3))
    centre = rho if abs(rho) < 1.0 else math.copysign(1.0 - 6.0 / (n**3 - n), rho)
    z = np.arctanh(centre)
    return {"rho": rho, "low": float(np.tanh(z - half)), "high": float(np.tanh(z + half)), "n": n,
            "p_value": _num(res.pvalue), "confidence": confidence}


# ----------------------------------------------------------------- the section


def counts(folder: Path, table: pa.Table, campaign: dict[str, Any]) -> dict[str, int | None]:
    """Runs declared, finished (by status), unfinished; attempts and retried attempts of the manifest."""
    st = statuses(table)
    attempts = read_manifest(folder)
    total = campaign.get("runs")
    out: dict[str, int | None] = {"total": int(total) if isinstance(total, int) else None,
                                  "finished": int(np.isin(st, FINISHED).sum())}
    out.update({s: int((st == s).sum()) for s in FINISHED})
    out["unfinished"] = None if out["total"] is None else max(out["total"] - out["finished"], 0)
    out["attempts"] = len(attempts)
    out["retried"] = sum(a.get("status") in RETRIED for a in attempts)
    return out


def metric_stats(values: np.ndarray, runs: np.ndarray) -> dict[str, Any]:
    """n, mean, std (sample), percentiles p01…p99, min and max with the run that gave them."""
    keep = np.isfinite(values)
    v, r = values[keep], runs[keep]
    if not len(v):
        return {"n": 0}
    out: dict[str, Any] = {"n": len(v), "mean": float(v.mean()),
                           "std": float(v.std(ddof=1)) if len(v) > 1 else None}
    for p, q in zip(PERCENTILES, np.percentile(v, PERCENTILES)):
        out[f"p{p:02d}"] = float(q)
    lo, hi = int(np.argmin(v)), int(np.argmax(v))
    out["min"] = {"value": float(v[lo]), "run": int(r[lo])}
    out["max"] = {"value": float(v[hi]), "run": int(r[hi])}
    return out


def sensitivities(table: pa.Table, confidence: float = CONFIDENCE) -> list[dict[str, Any]]:
    """Spearman ρ of every metric against every parameter that varies, over the runs that ran,
    strongest |ρ| first. Keys: metric, parameter, rho, low, high, n, p_value, confidence."""
    ran = np.isin(statuses(table), RAN)
    params = {p: column(table, PARAM + p)[ran] for p in names(table, PARAM)}
    out = []
    for m in names(table, METRIC):
        y = column(table, METRIC + m)[ran]
        for p, x in params.items():
            r = spearman(x, y, confidence)
            if r is not None:
                out.append({"metric": m, "parameter": p, **r})
    out.sort(key=lambda s: (-abs(s["rho"]), s["metric"], s["parameter"]))
    return out


def mission_pass_rates(table: pa.Table, confidence: float = CONFIDENCE) -> list[dict[str, Any]]:
    """Pass rate of each mission requirement (``req.*`` columns) with its Wilson interval."""
    st = statuses(table)
    return [{"name": n, **pass_rate(column(table, REQ + n), st, confidence)} for n in names(table, REQ)]


def campaign_section(folder: Path) -> dict[str, Any]:
    """The results.json ``campaign`` section of a results folder. Keys: ``runs`` (counts: total,
    finished, ok, invalid, diverged, unfinished, attempts, retried), ``metrics`` (key → n, mean, std,
    p01 p05 p50 p95 p99, min/max {value, run}, unit), ``pass_rates`` (mission requirements: name,
    passed, n, rate, low, high, confidence), ``sensitivities`` (see :func:`sensitivities`) and
    ``requirements`` (verdicts of the campaign requirements stored in campaign.json)."""
    from sms_cli.campaign.requirements import evaluate_all, stored_specs
    from sms_cli.check.metric_units import metric_unit

    folder = Path(folder)
    campaign = read_campaign(folder)
    table = read_runs(folder)
    ran = np.isin(statuses(table), RAN)
    runs = column(table, "run")[ran].astype(np.int64) if table.num_rows else np.array([], np.int64)
    metrics = {}
    for m in names(table, METRIC):
        metrics[m] = {**metric_stats(column(table, METRIC + m)[ran], runs), "unit": metric_unit(m) or ""}
    return {
        "runs": counts(folder, table, campaign),
        "metrics": metrics,
        "pass_rates": mission_pass_rates(table),
        "sensitivities": sensitivities(table),
        "requirements": [v.as_dict() for v in evaluate_all(stored_specs(campaign), table)],
    }
