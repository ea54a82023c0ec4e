"""Evaluate ``requirements:`` against results.json → one verdict per requirement.

Verdict statuses: ``pass``, ``fail`` (bound violated), ``missing`` (the metric is absent or not a
number: also a failure, with the reason), ``error`` (the requirement itself cannot be read, e.g.
a bound in a unit of another dimension). Values are shown in the requirement's ``unit`` when it
has one, else in the metric's own unit.
"""

from __future__ import annotations

import re
import shutil
import textwrap
from dataclasses import asdict, dataclass
from typing import Any

from sms_cli.check.metric_units import convert, metric_unit, parse_bound
from sms_cli.check.metrics import MetricMissing, as_number, resolve
from sms_cli.check.schema import RequirementSpec
from sms_cli.mission.units import UnitError


@dataclass
class Verdict:
    """The outcome of one requirement (``value``/``bound`` in ``unit``)."""

    name: str
    metric: str
    stage: str
    status: str  # pass | fail | missing | error
    value: float | bool | None
    bound: str
    unit: str
    message: str
    margin: float | None = None  # distance to the bound in `unit` (>= 0 when passing)

    @property
    def passed(self) -> bool:
        return self.status == "pass"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _fmt(x: float | bool) -> str:
    return str(x).lower() if isinstance(x, bool) else f"{x:.6g}"


def _bounds(req: RequirementSpec, m_unit: str | None, shown: str | None) -> dict[str, float]:
    """The numeric bounds in the display unit (raises UnitError)."""
    out: dict[str, float] = {}
    for kind, bound in (("min", req.min), ("max", req.max), ("equals", req.equals)):
        if bound is None or isinstance(bound, bool):
            continue
        b, b_unit = parse_bound(bound, req.unit or m_unit)
        out[kind] = convert(b, b_unit, shown) if b_unit != shown else b
    if "equals" in out:
        t, t_unit = parse_bound(req.tol, req.unit or m_unit)
        out["tol"] = abs(convert(t, t_unit, shown) if t_unit != shown else t)
    return out


def _bound_text(req: RequirementSpec, b: dict[str, float]) -> str:
    if isinstance(req.equals, bool):
        return f"== {_fmt(req.equals)}"
    parts = []
    if "min" in b:
        parts.append(f">= {_fmt(b['min'])}")
    if "max" in b:
        parts.append(f"<= {_fmt(b['max'])}")
    if "equals" in b:
        parts.append(f"== {_fmt(b['equals'])}" + (f" ± {_fmt(b['tol'])}" if b["tol"] else ""))
    return " and ".join(parts)


def evaluate(req: RequirementSpec, results: dict[str, Any]) -> Verdict:
    """One requirement against a results tree."""
    path = req.full_metric()
    m_unit = metric_unit(path)
    shown = req.unit or m_unit
    base = dict(name=req.name, metric=path, stage=req.section(), unit=shown or "")
    try:
        b = _bounds(req, m_unit, shown)
    except UnitError as exc:
        return Verdict(status="error", value=None, bound=str(req.max or req.min or req.equals),
                       message=f"requirement '{req.name}' ({path}, unit {shown or 'none'}): {exc}", **base)
    base["bound"] = _bound_text(req, b)
    try:
        value = as_number(resolve(results, path))
    except (MetricMissing, ValueError) as exc:
        return Verdict(status="missing", value=None, message=f"{path}: {exc}", **base)
    if isinstance(value, bool) or isinstance(req.equals, bool):
        if not (isinstance(req.equals, bool) and isinstance(value, bool)):
            return Verdict(status="error", value=value, message=(
                f"{path} is {'a flag' if isinstance(value, bool) else 'a number'}: compare it with "
                f"{'equals: true/false' if isinstance(value, bool) else 'max/min/equals and a number'}"), **base)
        ok = value == req.equals
        return Verdict(status="pass" if ok else "fail", value=value,
                       message="" if ok else f"{path} is {_fmt(value)}, required {_fmt(req.equals)}", **base)
    try:
        v = convert(value, m_unit, shown) if shown != m_unit else value
    except UnitError as exc:
        return Verdict(status="error", value=value, message=f"requirement '{req.name}': metric in {m_unit}: {exc}", **base)
    margins = []
    if "min" in b:
        margins.append(v - b["min"])
    if "max" in b:
        margins.append(b["max"] - v)
    if "equals" in b:
        margins.append(b["tol"] - abs(v - b["equals"]))
    margin = min(margins)
    ok = margin >= 0
    unit = f" {shown}" if shown else ""
    msg = "" if ok else f"{path} = {_fmt(v)}{unit} violates {base['bound']}{unit}"
    return Verdict(status="pass" if ok else "fail", value=v, margin=margin, message=msg, **base)


def evaluate_all(reqs: list[RequirementSpec], results: dict[str, Any]) -> list[Verdict]:
    return [evaluate(r, results) for r in reqs]


#: break points of a table cell: after the spaces of a text, after the dots of a metric path
_WORDS = re.compile(r"\S+\s*")
_PATH = re.compile(r"[^.]*\.|[^.]+")


def terminal_width(default: int = 100) -> int:
    """Columns to print in: ``COLUMNS``, else the terminal's width, else ``default`` (not a terminal)."""
    return max(40, shutil.get_terminal_size((default, 24)).columns)


def _wrap(text: str, width: int, breaks: re.Pattern) -> list[str]:
    """``text`` in lines of at most ``width`` characters, cut only at ``breaks`` (a longer piece stays whole)."""
    lines, cur = [], ""
    for piece in breaks.findall(text):
        if cur and len((cur + piece).rstrip()) > width:
            lines.append(cur.rstrip())
            cur = piece
        else:
            cur += piece
    return lines + [cur.rstrip()]


def text_table(head: list[str], rows: list[list[str]], width: int = 10**6, breaks: list[re.Pattern] | None = None,
               shrink: tuple[int, ...] = (), indent: str = "") -> tuple[list[str], list[list[str]]]:
    """(header lines, lines of each row) of a table at most ``width`` characters wide: the columns
    ``shrink`` lists give up width in that order, down to their longest unbreakable piece, and their
    cells wrap at ``breaks`` (words, or a metric path's dots): a number is never cut. The first
    column is indented by ``indent``. Without ``breaks``, every cell breaks at its spaces."""
    cols = range(len(head))
    breaks = breaks or [_WORDS] * len(head)
    shown = [[indent + r[0]] + r[1:] for r in [head] + rows]
    widths = [max(len(r[i]) for r in shown) for i in cols]
    least = [max([len(head[i]) + (len(indent) if i == 0 else 0)]
                 + [max(len(p.rstrip()) for p in breaks[i].findall(r[i]) or [""]) + (len(indent) if i == 0 else 0)
                    for r in rows]) for i in cols]
    for i in shrink:
        excess = sum(widths) + 2 * (len(head) - 1) - width
        if excess <= 0:
            break
        widths[i] -= min(excess, widths[i] - least[i])

    def block(row: list[str]) -> list[str]:
        cells = [[indent + c for c in _wrap(row[0], widths[0] - len(indent), breaks[0])]]
        cells += [_wrap(row[i], widths[i], breaks[i]) for i in cols if i]
        return ["  ".join((c[k] if k < len(c) else "").ljust(w) for c, w in zip(cells, widths)).rstrip()
                for k in range(max(map(len, cells)))]

    return block(head) + ["  ".join("-" * w for w in widths)], [block(r) for r in rows]


def format_verdicts(verdicts: list[Verdict], width: int | None = None) -> str:
    """A plain-text table: requirement, metric, value, bound, status, at most ``width`` columns wide
    (default: the terminal's, 100 when not a terminal). When the five columns do not fit, each
    requirement's name gets a line of its own above its metric, value, bound and status, and the
    metric paths wrap at their dots; numbers are never cut."""
    if not verdicts:
        return "no requirements\n"
    width = width or terminal_width()
    cells = []
    for v in verdicts:
        val = "—" if v.value is None else _fmt(v.value) + (f" {v.unit}" if v.unit else "")
        cells.append([v.name, v.metric, val, v.bound + (f" {v.unit}" if v.unit and v.bound else ""), v.status.upper()])
    head, rows = text_table(["requirement", "metric", "value", "bound", "status"], cells)
    if max(len(x) for x in head + sum(rows, [])) <= width:
        out = head + sum(rows, [])
    else:
        head, rows = text_table(["metric", "value", "bound", "status"], [c[1:] for c in cells], width,
                                [_PATH, _WORDS, _WORDS, _WORDS], (0, 2, 1), indent="  ")
        out = ["requirement"] + head
        for c, lines in zip(cells, rows):
            out += _wrap(c[0], width, _WORDS) + lines
    for v in verdicts:
        if v.message and not v.passed:
            out += textwrap.wrap(f"  {v.status}: {v.name}: {v.message}", width, subsequent_indent="      ",
                                 break_long_words=False, break_on_hyphens=False)
    n_fail = sum(not v.passed for v in verdicts)
    out.append(f"{len(verdicts) - n_fail}/{len(verdicts)} requirements met")
    return "\n".join(out) + "\n"
