"""Regression baselines: stored metric values with per-metric tolerances.

File format (JSON, ``format: sms-baseline/1``)::

    {"format": "sms-baseline/1", "mission": "hipparcos_geo", "mission_sha256": "…",
     "metrics": {"budget.totals.dv_m_s": {"value": 2307.51, "rel_tol": 1e-09, "abs_tol": 1e-09}, …}}

A metric passes when ``|value − stored| <= max(abs_tol, rel_tol·|stored|)`` (flags: equal).
Which metrics a new baseline holds, and their default tolerances, is the rule table
:data:`RULES` (first matching regular expression wins); edit the file to tighten or loosen one.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sms_cli.check.metrics import MetricMissing, as_number, numeric_leaves, resolve, section
from sms_cli.errors import InputError, Location, Problem
from sms_cli.outputs import key_line, kind_of, read_json_file

FORMAT = "sms-baseline/1"

#: (regex on the metric path, (rel_tol, abs_tol) or None = not stored). First match wins.
RULES: list[tuple[str, tuple[float, float] | None]] = [
    (r"^(run|requirements)\b", None),                       # provenance and verdicts, not results
    (r"\.(timing|files|artifacts)\b", None),                 # wall-clock and file names
    (r"(^|\.)(total|wall|solve|solver|build|verify|compile|setup|elapsed)_time(_s)?$", None),  # wall-clock durations
    (r"^analysis\.variants\.[^.]+\.best\b", None),           # arg-max sample lists (ties reorder)
    (r"^analysis\.(samples|n)$", (0.0, 0.0)),
    (r"\.(dof|nq|nv)\b|\.steps$", (0.0, 0.0)),              # counts are exact
    (r"^simulate\.conservation\..*drift", (0.0, 1e-6)),       # momentum drifts: round-off level, bound absolutely
    (r"settling_time_s$", (0.0, 0.25)),                      # quantised to the record period
    (r"^simulate\.", (1e-4, 1e-9)),
    (r"^synthesis\.", (1e-4, 1e-8)),                         # interior-point solver tolerance
    (r"^analysis\.", (1e-6, 1e-9)),
    (r"^budget\.", (1e-9, 1e-9)),                            # closed-form orbital mechanics
    (r"^compile\.", (1e-9, 1e-12)),
    (r".", (1e-6, 1e-9)),
]


def tolerance_for(path: str) -> tuple[float, float] | None:
    for pattern, tol in RULES:
        if re.search(pattern, path):
            return tol
    return None


def make_baseline(results: dict[str, Any]) -> dict[str, Any]:
    """A baseline of every numeric result the rules keep."""
    metrics: dict[str, dict[str, Any]] = {}
    for path, value in numeric_leaves(results):
        tol = tolerance_for(path)
        if tol is None:
            continue
        metrics[path] = {"value": value, "rel_tol": tol[0], "abs_tol": tol[1]}
    run = section(results, "run")
    return {"format": FORMAT, "mission": run.get("mission") or section(results, "compile").get("name"),
            "mission_sha256": run.get("mission_sha256"), "metrics": metrics}


REGENERATE = "regenerate it from good results: sms check RESULTS --write-baseline FILE"


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _metric_problem(m: Any) -> str:
    """What is wrong with one stored metric ('' when nothing)."""
    if not isinstance(m, dict):
        return f"is {kind_of(m)}, not {{\"value\": v, \"rel_tol\": r, \"abs_tol\": a}}"
    if "value" not in m:
        return "has no \"value\""
    if not (_number(m["value"]) or isinstance(m["value"], bool)):
        return f"value is {kind_of(m['value'])} ({m['value']!r}), not a finite number or a flag"
    for k in ("rel_tol", "abs_tol"):
        if k in m and not (_number(m[k]) and m[k] >= 0):
            return f"{k} is {m[k]!r}: a tolerance is a number >= 0"
    return ""


def read_baseline(path: Path) -> dict[str, Any]:
    """Load and validate a baseline file (InputError naming the file, the line and the fix)."""
    if not path.exists():
        raise InputError(problems=[Problem(f"no such baseline file {path}", Location(path),
                                           hint="write one with: sms check RESULTS --write-baseline FILE")])
    data, raw = read_json_file(path, "baseline", REGENERATE)
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("metrics"), dict):
        what = f"is {kind_of(data)}" if not isinstance(data, dict) else "has no \"metrics\" mapping" if data.get(
            "format") == FORMAT else f"has \"format\": {data.get('format')!r}"
        raise InputError(problems=[Problem(f"not an sms baseline: it {what} (expected \"format\": \"{FORMAT}\" "
                                           "and a \"metrics\" mapping)", Location(path, 1), hint=REGENERATE)])
    for name, m in data["metrics"].items():
        wrong = _metric_problem(m)
        if wrong:
            raise InputError(problems=[Problem(wrong, Location(path, key_line(raw, name)), f"metrics.{name}",
                                               hint="correct it, or " + REGENERATE)])
    return data


@dataclass
class Drift:
    """One baseline metric compared with the current results."""

    metric: str
    status: str  # pass | fail | missing
    value: float | bool | None
    expected: float | bool
    allowed: float
    message: str

    @property
    def passed(self) -> bool:
        return self.status == "pass"


def compare(results: dict[str, Any], baseline: dict[str, Any]) -> list[Drift]:
    """Every stored metric against the results (missing metrics fail)."""
    out = []
    for path, m in baseline["metrics"].items():
        expected = m["value"]
        rel, abs_ = float(m.get("rel_tol", 0.0)), float(m.get("abs_tol", 0.0))
        allowed = 0.0 if isinstance(expected, bool) else max(abs_, rel * abs(float(expected)))
        try:
            value = as_number(resolve(results, path))
        except (MetricMissing, ValueError) as exc:
            out.append(Drift(path, "missing", None, expected, allowed, str(exc)))
            continue
        if isinstance(expected, bool) or isinstance(value, bool):
            ok = value == expected
            msg = "" if ok else f"{value} (baseline {expected})"
        else:
            diff = abs(value - float(expected))
            ok = diff <= allowed
            rel_txt = f", {diff / abs(expected):.3g} relative" if expected else ""
            msg = "" if ok else f"{value:.10g} vs baseline {float(expected):.10g}: off by {diff:.3g}{rel_txt} (allowed {allowed:.3g})"
        out.append(Drift(path, "pass" if ok else "fail", value, expected, allowed, msg))
    return out


def format_drifts(drifts: list[Drift], limit: int = 40) -> str:
    bad = [d for d in drifts if not d.passed]
    lines = [f"baseline: {len(drifts) - len(bad)}/{len(drifts)} metrics within tolerance"]
    for d in bad[:limit]:
        lines.append(f"  {d.status.upper()} {d.metric}: {d.message}")
    if len(bad) > limit:
        lines.append(f"  … and {len(bad) - limit} more (see the JUnit report)")
    return "\n".join(lines) + "\n"
