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

from pydantic import Field, model_validator

from sms_cli.check.schema import Bound, RequirementSpec
from sms_cli.mission.base import StrictModel


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
