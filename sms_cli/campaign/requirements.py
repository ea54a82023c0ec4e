"""Campaign-level requirements: pass rates over the runs and signs of sensitivities.

The ``campaign.requirements:`` list of a campaign file holds two kinds::

    requirements:
      # per-run bound + pass rate, judged on the Wilson interval's lower bound
      - name: settles in 160 s
        metric: simulate.overall.settling_time_s
        max: 160 s
        pass_rate_min: 0.99
      # sign of a sensitivity, judged on the Fisher-z interval of Spearman's rank correlation
      - name: heavier body settles sooner
        metric: simulate.overall.settling_time_s
        correlation_with: body_mass
        rho_max: 0

A pass rate counts the runs that finished and were not refused (``invalid`` runs are excluded);
a ``diverged`` run or a run without the metric counts as a failure. Bounds and units are read as
a mission requirement's (:class:`sms_cli.check.schema.RequirementSpec`).
"""

from __future__ import annotations

import difflib
from typing import TYPE_CHECKING, Any

from pydantic import Field, model_validator

from sms_cli.check.metric_units import convert, metric_unit
from sms_cli.check.requirements import Verdict
from sms_cli.check.schema import Bound, RequirementSpec
from sms_cli.mission.base import StrictModel

if TYPE_CHECKING:  # numpy and pyarrow load with the verdicts, not with the mission schema (sms --help stays light)
    import numpy as np
    import pyarrow as pa


class CampaignRequirementSpec(StrictModel):
    """One campaign requirement: a per-run bound with a pass rate, or the sign of a rank correlation."""

    name: str = Field(description="short requirement name (shown in tables and JUnit test names)")
    metric: str = Field(
        min_length=1,
        description="dotted metric key as in results.json, e.g. 'simulate.overall.settling_time_s'")
    min: Bound | None = Field(
        None, description="per-run lower bound: number (in 'unit', else the metric's unit) or '5 s'")
    max: Bound | None = Field(
        None, description="per-run upper bound: number (in 'unit', else the metric's unit) or '160 s'")
    unit: str | None = Field(
        None, description="display unit of the per-run bound, e.g. 's', 'deg'; bare-number bounds use it")
    pass_rate_min: float | None = Field(
        None, gt=0.0, le=1.0,
        description="least fraction of valid runs meeting min/max, in (0, 1]; judged on the lower "
                    "bound of the Wilson score interval at 'confidence'")
    minus: str | None = Field(
        None, min_length=1,
        description="another metric subtracted from 'metric' run by run (a paired comparison: the same metric "
                    "under another variant, e.g. 'backstepping.simulate.overall.attitude_error_deg.max')")
    correlation_with: str | None = Field(
        None, min_length=1,
        description="name of a dispersion: the requirement bounds Spearman's rank correlation of "
                    "'metric' with that parameter over the finished runs")
    rho_max: float | None = Field(
        None, ge=-1.0, le=1.0,
        description="upper bound of the rank correlation (0: the metric decreases with the "
                    "parameter); judged on the interval's upper bound at 'confidence'")
    rho_min: float | None = Field(
        None, ge=-1.0, le=1.0,
        description="lower bound of the rank correlation (0: the metric increases with the "
                    "parameter); judged on the interval's lower bound at 'confidence'")
    confidence: float = Field(
        0.95, gt=0.0, lt=1.0,
        description="two-sided confidence level of the interval the verdict is judged on, in (0, 1)")
    description: str = Field("", description="why this requirement exists (source, rationale)")

    @model_validator(mode="after")
    def _one_kind(self):
        rate = self.pass_rate_min is not None or self.min is not None or self.max is not None
        corr = self.correlation_with is not None or self.rho_max is not None or self.rho_min is not None
        if rate == corr:
            raise ValueError(
                f"campaign requirement '{self.name}' needs either 'pass_rate_min' with 'min'/'max' "
                "(a pass rate) or 'correlation_with' with 'rho_max'/'rho_min' (a sensitivity sign)"
                + (", not both" if rate else ""))
        if rate:
            if self.pass_rate_min is None:
                raise ValueError(f"campaign requirement '{self.name}': 'min'/'max' need 'pass_rate_min' "
                                 "(the least fraction of runs meeting them, e.g. 0.99)")
            if self.min is None and self.max is None:
                raise ValueError(f"campaign requirement '{self.name}': 'pass_rate_min' needs a per-run "
                                 "bound 'min' and/or 'max'")
            self.run_requirement()  # bounds and units read as a mission requirement's
        else:
            if self.correlation_with is None or (self.rho_max is None and self.rho_min is None):
                raise ValueError(f"campaign requirement '{self.name}' needs 'correlation_with' and "
                                 "'rho_max' and/or 'rho_min'")
            if self.unit is not None:
                raise ValueError(f"campaign requirement '{self.name}': 'unit' applies to min/max only")
            if self.rho_min is not None and self.rho_max is not None and self.rho_min > self.rho_max:
                raise ValueError(f"campaign requirement '{self.name}': rho_min ({self.rho_min}) is above "
                                 f"rho_max ({self.rho_max}); no correlation can meet it")
        return self

    @property
    def kind(self) -> str:
        """``pass_rate`` or ``correlation``."""
        return "pass_rate" if self.pass_rate_min is not None else "correlation"

    def run_requirement(self) -> RequirementSpec:
        """The per-run bound as a mission requirement (raises on unreadable bounds or units)."""
        try:
            return RequirementSpec(name=self.name, metric=self.metric, min=self.min, max=self.max, unit=self.unit)
        except ValueError as exc:  # pydantic's ValidationError: keep only the message
            errors = getattr(exc, "errors", None)
            raise ValueError("; ".join(e["msg"].removeprefix("Value error, ") for e in errors())
                             if errors else str(exc)) from None


# ----------------------------------------------------------------- verdicts


def stored_specs(campaign: dict[str, Any]) -> list[CampaignRequirementSpec]:
    """The campaign requirements campaign.json stores (key ``requirements``; raises ValidationError)."""
    return [CampaignRequirementSpec.model_validate(s) for s in campaign.get("requirements") or []]


def _absent(table: pa.Table, column: str, what: str) -> str:
    """Why ``column`` is not in the table, with the nearest recorded one ("" when it is there)."""
    if column in table.column_names:
        return ""
    prefix = column.split(".")[0] + "."
    have = [c[len(prefix):] for c in table.column_names if c.startswith(prefix)]
    close = difflib.get_close_matches(column[len(prefix):], have, n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'?" if close else f"{len(have)} {what}s recorded"
    return f"no run recorded the {what} '{column[len(prefix):]}'; {hint}"


def _values(spec: CampaignRequirementSpec, table: pa.Table, metric: str) -> tuple[np.ndarray | None, str]:
    """The per-run values a requirement judges: the metric, less ``minus`` run by run when given;
    or why they are missing."""
    from sms_cli.campaign import stats as S

    why = _absent(table, S.METRIC + metric, "metric") or (spec.minus and _absent(table, S.METRIC + spec.minus, "metric"))
    if why:
        return None, why
    v = S.column(table, S.METRIC + metric)
    return (v - S.column(table, S.METRIC + spec.minus) if spec.minus else v), ""


def evaluate_pass_rate(spec: CampaignRequirementSpec, table: pa.Table) -> Verdict:
    """Fraction of runs meeting the per-run bound, judged on its Wilson lower bound."""
    import numpy as np

    from sms_cli.campaign import stats as S
    from sms_cli.check.requirements import _bound_text, _bounds

    req = spec.run_requirement()
    path = req.full_metric()
    m_unit = metric_unit(path)
    shown = req.unit or m_unit
    b = _bounds(req, m_unit, shown)
    each = f"each run {_bound_text(req, b)}" + (f" {shown}" if shown else "")
    shown_path = f"{path} − {spec.minus}" if spec.minus else path
    base = {"name": spec.name, "metric": f"{shown_path} pass rate, Wilson low", "stage": req.section(),
            "bound": f">= {spec.pass_rate_min:g} ({each})", "unit": ""}
    v, why = _values(spec, table, path)
    if why:
        return Verdict(status="missing", value=None, message=why, **base)
    v = v * convert(1.0, m_unit, shown)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(v) & (v >= b.get("min", -np.inf)) & (v <= b.get("max", np.inf))
    r = S.pass_rate(ok.astype(float), S.statuses(table), spec.confidence)
    if r["low"] is None:
        return Verdict(status="missing", value=None, message="no run that ran (all invalid or none finished)", **base)
    margin = r["low"] - spec.pass_rate_min
    msg = (f"{r['passed']}/{r['n']} runs that ran meet it ({r['rate']:.1%}); Wilson {spec.confidence:.0%} "
           f"interval [{r['low']:.4g}, {r['high']:.4g}]; judged on the lower bound")
    return Verdict(status="pass" if margin >= 0 else "fail", value=r["low"], margin=margin, message=msg, **base)


def evaluate_correlation(spec: CampaignRequirementSpec, table: pa.Table) -> Verdict:
    """Sign of Spearman's ρ(metric, parameter), judged on the bound of its Fisher-z interval."""
    import numpy as np

    from sms_cli.campaign import stats as S

    bounds = [f"ρ {op} {b:g}" for op, b in ((">=", spec.rho_min), ("<=", spec.rho_max)) if b is not None]
    shown = f"{spec.metric} − {spec.minus}" if spec.minus else spec.metric
    base = {"name": spec.name, "metric": f"ρ({shown}, {spec.correlation_with}), Fisher-z bound",
            "stage": spec.metric.split(".")[0], "bound": " and ".join(bounds), "unit": ""}
    y, why = _values(spec, table, spec.metric)
    why = why or _absent(table, S.PARAM + spec.correlation_with, "parameter")
    if why:
        return Verdict(status="missing", value=None, message=why, **base)
    ran = np.isin(S.statuses(table), S.RAN)
    r = S.spearman(S.column(table, S.PARAM + spec.correlation_with)[ran], y[ran], spec.confidence)
    if r is None:
        return Verdict(status="missing", value=None, message="fewer than 4 runs with both values, or one of them "
                                                             "constant: no rank correlation", **base)
    judged = []  # (margin, judged interval bound)
    if spec.rho_max is not None:
        judged.append((spec.rho_max - r["high"], r["high"]))
    if spec.rho_min is not None:
        judged.append((r["low"] - spec.rho_min, r["low"]))
    margin, value = min(judged)
    msg = (f"Spearman ρ = {r['rho']:.3f} over {r['n']} runs; Fisher-z {spec.confidence:.0%} interval "
           f"[{r['low']:.3f}, {r['high']:.3f}]; judged on its bound")
    return Verdict(status="pass" if margin >= 0 else "fail", value=value, margin=margin, message=msg, **base)


def evaluate(spec: CampaignRequirementSpec, table: pa.Table) -> Verdict:
    """One campaign requirement against the runs of :func:`sms_cli.campaign.stats.read_runs`."""
    return evaluate_pass_rate(spec, table) if spec.kind == "pass_rate" else evaluate_correlation(spec, table)


def evaluate_all(specs: list[CampaignRequirementSpec], table: pa.Table) -> list[Verdict]:
    return [evaluate(s, table) for s in specs]
