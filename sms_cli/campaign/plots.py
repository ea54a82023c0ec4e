"""Figures of a campaign: histograms of metrics, metric against a dispersed parameter.

:func:`plan` chooses the figures from the statistics (``campaign_section``) and the campaign
requirements: a histogram of each metric a requirement names, and of the settling time and the
attitude error when the runs recorded them; a scatter for each correlation requirement and for
the strongest |ρ| pairs. :func:`write_plots` draws them into ``plots/``; the report shows those
files (or draws a missing one the same way, :func:`png`). Figures use the report's set-up
(:mod:`sms_cli.report.figstyle`), half the content column wide; scatter points are rasterised.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sms_cli.report import figstyle

PLOTS_DIR = "plots"
#: metrics shown whenever the runs recorded them (besides those the requirements name)
ALWAYS = ("simulate.overall.settling_time_s", "simulate.overall.attitude_error_deg.final",
          "simulate.overall.attitude_error_deg.max")
MAX_HISTOGRAMS, TOP_PAIRS, MAX_SCATTERS = 8, 4, 8
WIDTH_PX, HEIGHT_PX = figstyle.HALF_PX, 300
OK_COLOUR, DIVERGED_COLOUR, BOUND_COLOUR = "#3b6ea8", "#c0392b", "#b3261e"


@dataclass(frozen=True)
class Plot:
    """One figure: ``file`` relative to the results folder, ``kind`` hist or scatter."""

    file: str
    kind: str
    metric: str
    parameter: str = ""
    caption: str = ""


def _file(*parts: str) -> str:
    return f"{PLOTS_DIR}/" + "--".join(re.sub(r"[^A-Za-z0-9_.-]+", "_", p) for p in parts) + ".png"


def _specs(folder: Path) -> list:
    from sms_cli.campaign.requirements import stored_specs
    from sms_cli.campaign.stats import read_campaign

    return stored_specs(read_campaign(folder))


def plan(folder: Path, section: dict[str, Any]) -> list[Plot]:
    """The figures of a campaign, in the order the report shows them."""
    specs = _specs(folder)
    metrics = section.get("metrics", {})
    named = [s.metric for s in specs if s.kind == "pass_rate"] + list(ALWAYS)
    hists = [m for m in dict.fromkeys(named) if metrics.get(m, {}).get("n")][:MAX_HISTOGRAMS]
    out = [Plot(_file("hist", m), "hist", m, caption=_hist_caption(m, metrics[m], specs)) for m in hists]
    sens = {(s["metric"], s["parameter"]): s for s in section.get("sensitivities", [])}
    pairs = [(s.metric, s.correlation_with) for s in specs if s.kind == "correlation"]
    pairs += [k for k in sens if abs(sens[k]["rho"]) > 0][:TOP_PAIRS]
    for m, p in [k for k in dict.fromkeys(pairs) if k in sens][:MAX_SCATTERS]:
        out.append(Plot(_file("scatter", m, p), "scatter", m, p, _scatter_caption(sens[(m, p)])))
    return out


def _hist_caption(metric: str, st: dict[str, Any], specs: list) -> str:
    bound = any(s.metric == metric and s.kind == "pass_rate" for s in specs)
    return (f"{metric}: distribution over the {st['n']} runs that ran (diverged runs stacked in red)"
            + (", with the per-run bound of its campaign requirement (dotted)" if bound else "")
            + f"; extremes in runs {st['min']['run']} and {st['max']['run']}"
            + (": how far the spread stays from the bound." if bound else ": the spread the dispersions cause."))


def _scatter_caption(s: dict[str, Any]) -> str:
    return (f"{s['metric']} against the dispersed {s['parameter']} ({s['n']} runs; Spearman ρ = {s['rho']:.2f}, "
            f"{s['confidence']:.0%} interval [{s['low']:.2f}, {s['high']:.2f}]): the sign and strength of the sensitivity.")


def _label(key: str) -> str:
    """An axis label short enough for a half-column figure: the variant (if any), then the metric
    without its section and 'overall' ("twisting: attitude_error_deg.max (deg)")."""
    from sms_cli.check.metric_units import metric_unit
    from sms_cli.check.schema import STAGE_SECTIONS

    parts = key.split(".")
    variant = parts.pop(0) if parts[0] not in STAGE_SECTIONS.values() else ""
    parts = parts[1:] if len(parts) > 1 else parts
    if parts and parts[0] == "overall" and len(parts) > 1:
        parts = parts[1:]
    unit = metric_unit(key)
    return (f"{variant}: " if variant else "") + ".".join(parts) + (f" ({unit})" if unit else "")


def _bounds(metric: str, specs: list) -> list[float]:
    """Per-run bounds of the pass-rate requirements on ``metric``, in the metric's own unit."""
    from sms_cli.check.metric_units import metric_unit
    from sms_cli.check.requirements import _bounds as bounds_of

    unit = metric_unit(metric)
    return [v for s in specs if s.kind == "pass_rate" and s.metric == metric
            for k, v in bounds_of(s.run_requirement(), unit, unit).items() if k in ("min", "max")]


@figstyle.styled
def draw_hist(values: np.ndarray, diverged: np.ndarray, metric: str, bounds: list[float]):
    """Histogram of a metric's finite values (diverged runs stacked on top) with bounds as lines."""
    fig, ax = figstyle.new(WIDTH_PX, HEIGHT_PX)
    fin = np.isfinite(values)
    edges = np.histogram_bin_edges(values[fin], bins=min(40, max(5, int(np.sqrt(fin.sum())))))
    ax.hist([values[fin & ~diverged], values[fin & diverged]], bins=edges, stacked=True,
            color=[OK_COLOUR, DIVERGED_COLOUR], label=["ok", "diverged"])
    for b in bounds:
        ax.axvline(b, color=BOUND_COLOUR, ls=":", lw=1.4)
    ax.set_xlabel(_label(metric))
    ax.set_ylabel("runs")
    ax.set_title(metric.split(".")[0])
    if np.any(fin & diverged):
        ax.legend(loc="upper right")
    return fig


@figstyle.styled
def draw_scatter(x: np.ndarray, y: np.ndarray, diverged: np.ndarray, metric: str, parameter: str, rho: float):
    """A metric against a parameter, one point per run (rasterised), diverged runs as red crosses."""
    fig, ax = figstyle.new(WIDTH_PX, HEIGHT_PX)
    ax.scatter(x[~diverged], y[~diverged], s=9, color=OK_COLOUR, alpha=0.6, lw=0, rasterized=True, label="ok")
    if diverged.any():
        ax.scatter(x[diverged], y[diverged], s=16, color=DIVERGED_COLOUR, marker="x", lw=1, rasterized=True,
                   label="diverged")
        ax.legend(loc="best")
    ax.set_xlabel(parameter)
    ax.set_ylabel(_label(metric))
    ax.set_title(f"ρ = {rho:.2f}")
    return fig


def figure(p: Plot, table, specs: list, section: dict[str, Any]):
    """The matplotlib figure of one planned plot, from the runs that ran."""
    from sms_cli.campaign import stats as S

    st = S.statuses(table)
    ran = np.isin(st, S.RAN)
    diverged = st[ran] == "diverged"
    y = S.column(table, S.METRIC + p.metric)[ran]
    if p.kind == "hist":
        return draw_hist(y, diverged, p.metric, _bounds(p.metric, specs))
    x = S.column(table, S.PARAM + p.parameter)[ran]
    keep = np.isfinite(x) & np.isfinite(y)
    rho = next(s["rho"] for s in section["sensitivities"] if (s["metric"], s["parameter"]) == (p.metric, p.parameter))
    return draw_scatter(x[keep], y[keep], diverged[keep], p.metric, p.parameter, rho)


def png(folder: Path, p: Plot, section: dict[str, Any], table=None) -> bytes:
    """The PNG bytes of one planned plot (the runs read from ``folder`` unless ``table`` is given)."""
    from sms_cli.campaign.stats import read_runs

    table = read_runs(folder) if table is None else table
    return figstyle.render(figure(p, table, _specs(folder), section))


def write_plots(folder: Path, section: dict[str, Any]) -> list[str]:
    """Draw the planned figures into ``<folder>/plots/``; the file names written, relative to ``folder``."""
    from sms_cli.campaign.stats import read_runs
    from sms_cli.results import write_bytes_atomic

    folder = Path(folder)
    table, specs = read_runs(folder), _specs(folder)
    (folder / PLOTS_DIR).mkdir(exist_ok=True)
    out = []
    for p in plan(folder, section):
        write_bytes_atomic(folder / p.file, figstyle.render(figure(p, table, specs, section)))
        out.append(p.file)
    return out
