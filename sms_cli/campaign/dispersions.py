"""Per-run samples of a campaign: seeding, designs, distributions and the value each run writes.

Seeding (``SeedSequence(entropy, spawn_key=…)``, numpy's documented way to derive independent
streams): a Monte-Carlo draw of parameter P in run r uses the key (r, crc32(P's name)), so
adding, removing or reordering a dispersion leaves every other parameter's draws unchanged, and
any run can be drawn again on its own (``--resume``, ``sms campaign rerun``). A Latin hypercube
permutes the strata of each parameter with its own key (also independent of the others). A
Sobol design draws all columns together (scipy.stats.qmc), in declaration order.

Every design gives a quantile u ∈ (0, 1) per run and parameter; the distribution maps it to x
(its inverse CDF), and the mode maps x to the value written into the mission.
"""

from __future__ import annotations

import itertools
import zlib
from dataclasses import dataclass

import numpy as np
from scipy import stats
from scipy.stats import qmc

from sms_cli.campaign.schema import CampaignSpec, DispersionSpec
from sms_cli.mission.units import any_to_si

_LHS_TAG, _SOBOL_TAG = 0x4C4853, 0x534F42  # keys of the design-level streams ("LHS", "SOB")


def name_key(name: str) -> int:
    """The stream key of a parameter name (stable across Python versions and machines)."""
    return zlib.crc32(name.encode("utf-8"))


def new_entropy() -> int:
    """Fresh entropy from the OS (recorded in campaign.json, so the campaign can be drawn again)."""
    return int(np.random.SeedSequence().entropy)


@dataclass(frozen=True)
class Parameter:
    """A dispersion resolved against the mission: the nominal SI value (a number or a vector) at each
    of its paths; ``nominal`` is the first path's, the one the campaign tables show."""

    spec: DispersionSpec
    nominals: tuple[float | np.ndarray, ...]

    @property
    def name(self) -> str:
        return self.spec.key

    @property
    def nominal(self) -> float | np.ndarray:
        return self.nominals[0]

    def values(self, x: float) -> list[tuple[str, float | np.ndarray]]:
        """(path, SI value) written for the draw x at each path."""
        return [(path, self._value(x, n)) for path, n in zip(self.spec.paths, self.nominals)]

    def _value(self, x: float, nominal: float | np.ndarray) -> float | np.ndarray:
        """relative: nominal·(1+x); offset: nominal+x; absolute: x."""
        mode = self.spec.mode
        if mode == "relative":
            return nominal * (1.0 + x)
        if mode == "offset":
            return nominal + x
        return np.full_like(nominal, x) if isinstance(nominal, np.ndarray) else float(x)

    def scalar(self, value: float | np.ndarray) -> float:
        return scalar_of(self.spec.mode, self.nominal, value)


def scalar_of(mode: str, nominal, value) -> float:
    """The number the campaign tables keep for a value: the value itself, or for a vector the factor
    − 1 (relative) or the shift (offset) of its largest nominal component (absolute: that component)."""
    if not isinstance(nominal, (list, np.ndarray)):
        return float(value)
    nominal = np.asarray(nominal, float)
    k = int(np.argmax(np.abs(nominal)))
    v = float(np.asarray(value, float)[k])
    if mode == "relative":
        return v / nominal[k] - 1.0 if nominal[k] != 0 else float("nan")
    if mode == "offset":
        return v - nominal[k]
    return v


def quantile_to_x(d: DispersionSpec, u: np.ndarray) -> np.ndarray:
    """x for quantiles u ∈ (0, 1) by the distribution's inverse CDF."""
    u = np.asarray(u, float)
    if d.distribution == "uniform":
        lo, hi = any_to_si(d.low), any_to_si(d.high)
        return lo + u * (hi - lo)
    mean = any_to_si(d.mean)
    if d.distribution == "normal":
        return stats.norm.ppf(u, loc=mean, scale=any_to_si(d.std))
    if d.distribution == "truncated_normal":
        std = any_to_si(d.std)
        a, b = (any_to_si(d.low) - mean) / std, (any_to_si(d.high) - mean) / std
        return stats.truncnorm.ppf(u, a, b, loc=mean, scale=std)
    values = np.array([any_to_si(v) for v in d.values], float)
    w = np.ones(len(values)) if d.weights is None else np.asarray(d.weights, float)
    edges = np.cumsum(w) / w.sum()
    return values[np.minimum(np.searchsorted(edges, u, side="right"), len(values) - 1)]


def grid_levels(d: DispersionSpec) -> np.ndarray:
    """The x levels of a grid: every value of a choice; evenly spaced from low to high (uniform,
    truncated normal); quantiles (j + ½)/levels of a normal."""
    if d.distribution == "choice":
        return np.array([any_to_si(v) for v in d.values], float)
    n = int(d.levels)
    if d.distribution == "uniform":
        return np.linspace(any_to_si(d.low), any_to_si(d.high), n)
    if d.distribution == "truncated_normal":
        return np.linspace(any_to_si(d.low), any_to_si(d.high), n)
    return quantile_to_x(d, (np.arange(n) + 0.5) / n)


def run_count(c: CampaignSpec) -> int:
    if c.design == "grid":
        return int(np.prod([len(grid_levels(d)) for d in c.dispersions]))
    return int(c.runs)


def draws(c: CampaignSpec, entropy: int, runs: list[int] | None = None) -> dict[int, dict[str, float]]:
    """x of every parameter for the given runs (default: all): {run: {name: x}}."""
    n = run_count(c)
    runs = list(range(n)) if runs is None else runs
    ds = c.dispersions
    if c.design == "grid":
        grid = list(itertools.product(*[grid_levels(d) for d in ds]))
        return {r: {d.key: float(grid[r][j]) for j, d in enumerate(ds)} for r in runs}
    if c.design == "monte_carlo":
        u = {r: {d.key: _uniform(entropy, (r, name_key(d.key))) for d in ds} for r in runs}
    elif c.design == "lhs":
        cols = {d.key: _lhs_column(entropy, d.key, n) for d in ds}
        u = {r: {k: float(col[r]) for k, col in cols.items()} for r in runs}
    else:
        pts = qmc.Sobol(len(ds), scramble=True, seed=np.random.default_rng(
            np.random.SeedSequence(entropy, spawn_key=(_SOBOL_TAG,)))).random(n)
        u = {r: {d.key: float(pts[r, j]) for j, d in enumerate(ds)} for r in runs}
    return {r: {d.key: float(quantile_to_x(d, np.array([u[r][d.key]]))[0]) for d in ds} for r in runs}


def _uniform(entropy: int, key: tuple[int, ...]) -> float:
    """One quantile in (0, 1) from the stream of ``key`` (0 is excluded: the inverse CDF is finite)."""
    u = np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=key)).random()
    return float(u) if u > 0 else float(np.nextafter(0.0, 1.0))


def _lhs_column(entropy: int, name: str, n: int) -> np.ndarray:
    """A Latin-hypercube column: one quantile in each of the n strata, in an order of its own stream."""
    rng = np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(_LHS_TAG, name_key(name))))
    return (rng.permutation(n) + rng.uniform(1e-12, 1.0, n)) / n
