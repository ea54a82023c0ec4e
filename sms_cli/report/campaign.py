"""The campaign section of the HTML report: counts, pass rates, statistics, figures, sensitivities.

Built from results.json's ``campaign`` section when the campaign stage wrote it, else from the
folder's runs (:func:`sms_cli.campaign.stats.campaign_section`); the figures are the files of
``plots/`` the stage wrote, or drawn the same way when absent (:mod:`sms_cli.campaign.plots`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sms_cli.report.model import Figure, Section, Table, figure_from_file, fmt

TOP_SENSITIVITIES = 12


def statistics(folder: Path, results: dict[str, Any]) -> dict[str, Any]:
    """The campaign statistics: results.json's section, else computed from the runs."""
    stored = results.get("campaign")
    if isinstance(stored, dict) and isinstance(stored.get("runs"), dict):
        return stored
    from sms_cli.campaign.stats import campaign_section

    return campaign_section(folder)


def _counts_table(n: dict[str, Any]) -> Table:
    rows = [[label, fmt(n.get(key))] for key, label in (
        ("total", "runs declared"), ("finished", "runs finished"), ("ok", "ok (stages ran)"),
        ("diverged", "diverged (a failure of every pass rate)"), ("invalid", "invalid draws (left out of the rates)"),
        ("unfinished", "not finished yet"), ("attempts", "attempts"), ("retried", "attempts retried (failed, timeout, "
                                                                                 "crashed, lost)"))]
    return Table("Runs of the campaign", ["runs", "count"], rows, [False, True])


def _rates_table(rates: list[dict[str, Any]]) -> Table:
    h = ["mission requirement", "passed", "runs counted", "pass rate [–]", "Wilson low [–]", "Wilson high [–]"]
    rows = [[r["name"], fmt(r["passed"]), fmt(r["n"]), fmt(r["rate"]), fmt(r["low"]), fmt(r["high"])] for r in rates]
    conf = rates[0]["confidence"] if rates else 0.95
    return Table(f"Mission requirements over the runs that ran (invalid draws left out, diverged runs failed; "
                 f"Wilson score interval at {conf:.0%})", h, rows, [False] + [True] * 5)


def _extreme(x: dict[str, Any] | None) -> str:
    return "—" if not x else f"{fmt(x['value'])} (run {x['run']})"


def _stats_table(metrics: dict[str, dict[str, Any]]) -> Table:
    h = ["metric", "unit", "n", "mean", "std", "p01", "p50", "p99", "min (run)", "max (run)"]
    rows = [[m, s.get("unit") or "–", fmt(s["n"]), fmt(s.get("mean")), fmt(s.get("std")), fmt(s.get("p01")),
             fmt(s.get("p50")), fmt(s.get("p99")), _extreme(s.get("min")), _extreme(s.get("max"))]
            for m, s in metrics.items() if s.get("n")]
    return Table("Metrics over the runs that ran (percentiles p05 and p95 are in results.json)", h, rows,
                 [False, False] + [True] * 8)


def _sensitivity_table(sens: list[dict[str, Any]]) -> Table:
    h = ["metric", "parameter", "Spearman ρ [–]", "low [–]", "high [–]", "runs"]
    rows = [[s["metric"], s["parameter"], fmt(s["rho"], 3), fmt(s["low"], 3), fmt(s["high"], 3), fmt(s["n"])]
            for s in sens[:TOP_SENSITIVITIES]]
    conf = sens[0]["confidence"] if sens else 0.95
    return Table(f"Strongest sensitivities: rank correlation of a metric with a dispersed parameter (Fisher-z "
                 f"interval at {conf:.0%}; {len(sens)} pairs in results.json)", h, rows, [False, False] + [True] * 4)


def _figures(folder: Path, section: dict[str, Any]) -> list[Figure]:
    from sms_cli.campaign import plots

    out, table = [], None
    for p in plots.plan(folder, section):
        fig = figure_from_file(folder, p.file, p.caption)
        if fig is None:
            from sms_cli.campaign.stats import read_runs

            table = read_runs(folder) if table is None else table
            fig = Figure.of_png(p.caption, plots.png(folder, p, section, table))
        out.append(fig)
    return out


def campaign_report_section(folder: Path, section: dict[str, Any]) -> Section:
    """The report section of a campaign's statistics (``section``: results.json ``campaign``)."""
    n = section["runs"]
    s = Section("campaign", "Campaign: dispersions over the runs")
    s.intro = (f"{fmt(n.get('finished'))} of {fmt(n.get('total'))} runs finished: {fmt(n.get('ok'))} ok, "
               f"{fmt(n.get('diverged'))} diverged, {fmt(n.get('invalid'))} invalid draws; "
               f"{fmt(n.get('attempts'))} attempts. The campaign requirements are in the verdicts at the top.")
    s.add(_counts_table(n))
    if section.get("pass_rates"):
        s.add(_rates_table(section["pass_rates"]))
    if section.get("metrics"):
        s.add(_stats_table(section["metrics"]))
    for f in _figures(folder, section):
        s.add(f)
    if section.get("sensitivities"):
        s.add(_sensitivity_table(section["sensitivities"]))
    if n.get("unfinished"):
        s.notes.append(f"{n['unfinished']} runs have not finished: resume the campaign (sms campaign --resume) "
                       "for the statistics of all of them")
    return s
