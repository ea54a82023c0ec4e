"""The ``campaign:`` section of a mission file: what to disperse, how to sample it, how to run it.

    extends: pulsar_simple.yaml
    campaign:
      design: monte_carlo          # monte_carlo | lhs | sobol | grid
      runs: 64
      entropy: 20261201            # seed of every draw (default: drawn once and recorded)
      dispersions:
        - {name: base_mass, path: robot.links.base_link.mass, distribution: uniform, low: -3 %, high: 3 %}
        - {name: payload, path: payloads.tile.mass, distribution: choice, values: [0, 110, 220], mode: absolute}
        - {name: body, path: [robot.links.base_link.mass, robot.links.base_link.inertia], distribution: uniform,
           low: 0, high: 200 %}   # one draw scales the body's mass and inertia together

Each dispersion draws a number x and writes, at its dotted path, ``nominal × (1 + x)``
(``mode: relative``, the default), ``nominal + x`` (``offset``) or ``x`` (``absolute``). A path
to a vector or tensor (an inertia) scales or shifts every component by the one x. A draw the
mission refuses (a negative mass, an inertia off the triangle inequality) is never clipped: the
run is recorded ``invalid`` with the reason; ``truncated_normal`` truncates by declaration.
"""

from __future__ import annotations

from typing import Literal, Union

from pydantic import Field, field_validator, model_validator

from sms_cli.campaign.requirements import CampaignRequirementSpec
from sms_cli.mission.base import StrictModel
from sms_cli.mission.units import Time, any_to_si

#: a distribution parameter: a number (SI, or a fraction for ``relative``), "3 %", or "2 deg"
Number = Union[float, str]

STAGES = ("analyze", "synthesize", "simulate")


def _si(value: Number | None) -> float | None:
    return None if value is None else any_to_si(value)


class DispersionSpec(StrictModel):
    """One dispersed parameter."""

    name: str | None = Field(None, description="name of the parameter in tables and plots (default: the path); "
                                               "the seed of its draws is keyed by this name")
    path: str | list[str] = Field(description="dotted path into the mission, e.g. payloads.tile.mass, "
                                               "robot.links.base_link.inertia, simulation.phases.slew.duration, "
                                               "appendages.0.modes.0.frequency; a list item by index or by its name. "
                                               "A list of paths applies the one draw to each (a body's mass and "
                                               "inertia scaled together)")
    distribution: Literal["uniform", "normal", "truncated_normal", "choice"] = Field(
        description="uniform (low, high), normal (mean, std), truncated_normal (mean, std, low, high), choice (values)")
    mode: Literal["relative", "offset", "absolute"] = Field(
        "relative", description="relative: nominal × (1 + x); offset: nominal + x; absolute: x (the value itself)")
    low: Number | None = Field(None, description="lower bound of x (uniform, truncated_normal)")
    high: Number | None = Field(None, description="upper bound of x (uniform, truncated_normal)")
    mean: Number = Field(0.0, description="mean of x (normal, truncated_normal)")
    std: Number | None = Field(None, description="standard deviation of x (normal, truncated_normal), > 0")
    values: list[Number] | None = Field(None, description="the values x takes (choice), equally likely unless weights")
    weights: list[float] | None = Field(None, description="relative weights of the values (choice)")
    levels: int | None = Field(None, ge=2, le=1000,
                               description="grid design: number of levels (evenly spaced quantiles; choice: every value)")

    @field_validator("path")
    @classmethod
    def _path(cls, v: str | list[str]) -> str | list[str]:
        for one in [v] if isinstance(v, str) else v:
            if not one or any(not part for part in one.split(".")):
                raise ValueError(f"{one!r} has an empty part: write keys separated by single dots")
        if isinstance(v, list) and (not v or len(set(v)) != len(v)):
            raise ValueError("paths: give at least one, each once")
        return v

    @model_validator(mode="after")
    def _parameters(self):
        d = self.distribution
        need = {"uniform": ("low", "high"), "normal": ("std",), "truncated_normal": ("std", "low", "high"),
                "choice": ("values",)}[d]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {d} dispersion needs {' and '.join(missing)}")
        low, high, std = _si(self.low), _si(self.high), _si(self.std)
        if d in ("uniform", "truncated_normal") and not low < high:
            raise ValueError(f"low ({self.low}) must be below high ({self.high})")
        if std is not None and d != "choice" and not std > 0:
            raise ValueError(f"std must be positive, got {self.std}")
        if d == "truncated_normal" and not low <= _si(self.mean) <= high:
            raise ValueError(f"mean ({self.mean}) must lie within [low, high]")
        if d == "choice":
            if not self.values:
                raise ValueError("values must list at least one value")
            if self.weights is not None and (len(self.weights) != len(self.values) or min(self.weights) < 0
                                             or sum(self.weights) <= 0):
                raise ValueError("weights: one non-negative weight per value, not all zero")
            for x in self.values:
                any_to_si(x)
        return self

    @property
    def paths(self) -> list[str]:
        """Every path the draw is written to (the first names the parameter when it has no name)."""
        return [self.path] if isinstance(self.path, str) else list(self.path)

    @property
    def key(self) -> str:
        """The parameter's name (its first path when unnamed)."""
        return self.name or self.paths[0]


class CampaignSpec(StrictModel):
    """A Monte-Carlo campaign or parameter sweep of the mission (``sms campaign``)."""

    design: Literal["monte_carlo", "lhs", "sobol", "grid"] = Field(
        "monte_carlo", description="monte_carlo: independent draws (adding a dispersion leaves the others' draws "
                                   "unchanged); lhs: Latin hypercube (per parameter, also independent); sobol: "
                                   "scrambled Sobol points (columns in declaration order); grid: cartesian product of "
                                   "each dispersion's levels")
    runs: int | None = Field(None, ge=1, le=10_000_000, description="number of runs (not for grid: the product of the "
                                                                    "levels)")
    entropy: int | None = Field(None, ge=0, description="seed entropy of every draw (default: drawn from the OS and "
                                                        "recorded in campaign.json)")
    stages: list[Literal["analyze", "synthesize", "simulate"]] = Field(
        default_factory=lambda: ["simulate"], min_length=1,
        description="stages each run executes, in the order analyze, synthesize, simulate")
    dispersions: list[DispersionSpec] = Field(min_length=1, description="the dispersed parameters")
    variants: dict[str, dict] = Field(
        default_factory=dict,
        description="named designs each run executes on the same draws (a paired comparison, e.g. two control "
                    "laws): each is a mission overlay merged as extends merges; metrics are then keyed "
                    "'<variant>.<metric>' and requirement verdicts '<variant>: <name>'")
    timeout: Time = Field(600.0, gt=0, description="per-run timeout (s); a run past it costs one attempt")
    retries: int = Field(2, ge=0, le=20, description="further attempts of a run that failed, timed out or lost its "
                                                     "worker")
    requirements: list[CampaignRequirementSpec] = Field(
        default_factory=list, description="requirements on campaign figures (pass rates, sensitivities), judged by "
                                          "sms check on the confidence interval's bound")

    @model_validator(mode="after")
    def _design(self):
        names = [d.key for d in self.dispersions]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"dispersion names must be unique: {', '.join(dup)} appear twice (name them)")
        if self.design == "grid":
            if self.runs is not None:
                raise ValueError("a grid design has no 'runs': it runs the product of the dispersions' levels")
            bad = [d.key for d in self.dispersions if d.distribution != "choice" and d.levels is None]
            if bad:
                raise ValueError(f"grid design: give levels to {', '.join(bad)}")
        elif self.runs is None:
            raise ValueError(f"a {self.design} design needs runs: the number of runs")
        bad = [v for v in self.variants if not v or "." in v or ":" in v]
        if bad:
            raise ValueError(f"variant names are plain words (no '.' or ':'): {', '.join(map(repr, bad))}")
        for r in self.requirements:
            w = getattr(r, "correlation_with", None)
            if w is not None and w not in names:
                raise ValueError(f"requirement {r.name!r}: correlation_with {w!r} is not a dispersion "
                                 f"(dispersions: {', '.join(names)})")
        return self

    @property
    def ordered_stages(self) -> tuple[str, ...]:
        return tuple(s for s in STAGES if s in self.stages)
