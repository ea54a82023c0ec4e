"""The mission file's ``requirements:`` list (read by ``sms run`` and ``sms check``).

A requirement names a metric of ``results.json`` by a dotted path and bounds it::

    requirements:
      - name: slew settles
        metric: simulate.overall.attitude_error_deg.final   # dotted path; [i] or [name] picks a list item
        max: 0.01 deg            # a bare number is in `unit` (if given) or in the metric's own unit
        unit: deg                # optional: display unit (and unit of bare-number bounds)
      - {name: closes, metric: budget.mass.closes, equals: true}
      - {name: ΔV, stage: budget, metric: totals.dv_m_s, max: 2.4 km/s}   # path relative to the stage

A metric's own unit is read from its key suffix (``_deg``, ``_m_s``, ``_kg``, ``_s``, ``_Nm``…,
see ``sms_cli.check.metric_units``); a metric without a suffix is SI in the dimension of ``unit``.
"""

from __future__ import annotations

import math
from typing import Literal, Union

from pydantic import Field, field_validator, model_validator

from sms_cli.mission.base import StrictModel

#: results.json section of each stage (CLI stage name → section name)
STAGE_SECTIONS: dict[str, str] = {
    "compile": "compile", "budget": "budget", "analyze": "analysis", "analysis": "analysis",
    "synthesize": "synthesis", "synthesis": "synthesis", "simulate": "simulate", "simulation": "simulate",
}

Bound = Union[float, str]


class RequirementSpec(StrictModel):
    """One pass/fail requirement on a metric of results.json."""

    name: str = Field(description="short requirement name (shown in tables and JUnit test names)")
    metric: str = Field(
        min_length=1,
        description="dotted path into results.json, e.g. 'simulate.overall.attitude_error_deg.max'; "
                    "list items by index 'phases[0]' or by name 'phases[slew]'; relative to the stage's "
                    "section when 'stage' is given and the path does not start with a section name")
    max: Bound | None = Field(None, description="upper bound: number (in 'unit', else the metric's unit) or '1 deg'")
    min: Bound | None = Field(None, description="lower bound: number (in 'unit', else the metric's unit) or '5 s'")
    equals: Bound | bool | None = Field(None, description="expected value (true/false for flags); see 'tol'")
    tol: Bound = Field(0.0, description="absolute tolerance of 'equals' (same units as the bound)")
    unit: str | None = Field(None, description="display unit, e.g. 'deg', 'm/s', 'kg'; bare-number bounds use it")
    stage: Literal["compile", "budget", "analyze", "analysis", "synthesize", "synthesis", "simulate", "simulation"] | None = Field(
        None, description="stage that produces the metric (default: the first part of the metric path)")
    description: str = Field("", description="why this requirement exists (source, rationale)")

    @field_validator("metric")
    @classmethod
    def _metric_text(cls, v: str) -> str:
        v = v.strip()
        if not v or v.startswith(".") or v.endswith(".") or ".." in v:
            raise ValueError("metric is a dotted path such as 'simulate.overall.attitude_error_deg.max'")
        return v

    @model_validator(mode="after")
    def _one_bound(self):
        if self.max is None and self.min is None and self.equals is None:
            raise ValueError(f"requirement '{self.name}' needs a bound: 'max', 'min' or 'equals'")
        if self.equals is not None and (self.max is not None or self.min is not None):
            raise ValueError(f"requirement '{self.name}': use either 'equals' (with 'tol') or 'max'/'min', not both")
        self._check_units()
        return self

    def _check_units(self) -> None:
        """Bounds and display unit must be readable and of the metric's dimension."""
        from sms_cli.check.metric_units import convert, metric_unit, parse_bound
        from sms_cli.mission.units import SpecError, UnitError

        m_unit = metric_unit(self.full_metric())
        try:
            if self.unit:
                convert(1.0, self.unit, m_unit) if m_unit else parse_bound(f"1 {self.unit}", None)
            for b in (self.max, self.min, self.equals, self.tol if self.equals is not None else None):
                if b is None or isinstance(b, bool):
                    continue
                value, unit = parse_bound(b, self.unit or m_unit)
                if unit and (self.unit or m_unit):
                    convert(value, unit, self.unit or m_unit)
                if not math.isfinite(value):
                    raise UnitError(f"bound {b!r} is not a finite number")
            if self.min is not None and self.max is not None:
                shown = self.unit or m_unit
                lo, hi = (convert(*parse_bound(b, shown), shown) for b in (self.min, self.max))
                if lo > hi:
                    raise SpecError(f"requirement '{self.name}': min ({self.min}) is above max ({self.max}); "
                                    "no value can meet it", ("min",), "swap min and max")
        except UnitError as exc:
            where = f"the metric is in {m_unit}" if m_unit else "the metric's unit is not known from its name"
            raise ValueError(f"requirement '{self.name}': {exc} ({where}; 'unit' is {self.unit or 'not set'})") from None

    def section(self) -> str:
        """The results.json section the metric lives in."""
        return STAGE_SECTIONS.get(self.stage or "", "") or self.metric.split(".")[0].split("[")[0]

    def full_metric(self) -> str:
        """The metric path from the top of results.json."""
        head = self.metric.split(".")[0].split("[")[0]
        if self.stage and head not in set(STAGE_SECTIONS.values()):
            return f"{STAGE_SECTIONS[self.stage]}.{self.metric}"
        return self.metric
