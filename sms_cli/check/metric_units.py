"""Units of results.json metrics and conversion of requirement bounds.

Stages name their numbers with a unit suffix (``dv_m_s``, ``attitude_error_deg``, ``total_mass_kg``,
``settling_time_s``); :func:`metric_unit` reads it back. Conversions go through
``sms_cli.mission.units`` (one source of truth for unit factors).
"""

from __future__ import annotations

import math
import re

from sms_cli.mission.units import UnitError, _compatible, _parse_unit_expression

# longest suffixes first: "_rad_s" before "_s", "_m_s" before "_s"
_SUFFIXES: list[tuple[str, str]] = [
    ("_m3_s2", "m^3/s^2"), ("_rad_s", "rad/s"), ("_deg_s", "deg/s"), ("_m_s", "m/s"), ("_km_s", "km/s"),
    ("_kgm2", "kg m^2"), ("_Nms", "N m s"), ("_Nm", "N m"), ("_deg", "deg"), ("_rad", "rad"),
    ("_rpm", "rpm"), ("_hz", "Hz"), ("_Hz", "Hz"), ("_kg", "kg"), ("_km", "km"), ("_m", "m"), ("_s", "s"),
    ("_n", "N"), ("_J", "J"), ("_W", "W"),
]
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def metric_unit(path: str) -> str | None:
    """The unit of a metric from the last path component carrying a unit suffix, or None.

    A single-letter stem is a symbol, not a quantity (``K_m`` is an index, not metres).
    """
    parts = [p.split("[")[0] for p in path.split(".")]
    for part in reversed(parts):
        for suffix, unit in _SUFFIXES:
            if part.endswith(suffix):
                stem = part[: -len(suffix)]
                if len(stem) >= 2 and not stem.endswith("_"):
                    return unit
    return None


def factor(unit: str) -> tuple[float, tuple[int, int, int, int]]:
    """(SI factor, dimension) of a unit expression; raises UnitError."""
    return _parse_unit_expression(unit)


def convert(value: float, from_unit: str | None, to_unit: str | None) -> float:
    """``value`` expressed in ``from_unit`` → in ``to_unit`` (None = SI of the other's dimension)."""
    if from_unit == to_unit or (from_unit is None and to_unit is None):
        return value
    f_from, d_from = factor(from_unit) if from_unit else (1.0, None)
    f_to, d_to = factor(to_unit) if to_unit else (1.0, None)
    if d_from is not None and d_to is not None:
        if not _compatible(d_from, d_to):
            raise UnitError(f"cannot convert {from_unit} to {to_unit}: different dimensions")
        if d_to[3] == 0 and d_from[3] != 0:
            f_from /= (2.0 * math.pi) ** d_from[3]
        elif d_from[3] == 0 and d_to[3] != 0:
            f_to /= (2.0 * math.pi) ** d_to[3]
    return value * f_from / f_to


def parse_bound(bound: float | str, unit: str | None) -> tuple[float, str | None]:
    """A requirement bound as (number, its unit): a bare number is in ``unit``; ``"1 deg"`` carries its own."""
    if isinstance(bound, (int, float)) and not isinstance(bound, bool):
        return float(bound), unit
    m = _QUANTITY.match(str(bound))
    if not m:
        raise UnitError(f"cannot read bound '{bound}': write a number, optionally with a unit ('1 deg', '2.4 km/s')")
    number, u = float(m.group(1)), m.group(2).strip()
    if u:
        factor(u)  # validate now: unknown units are an input error
    return number, (u or unit)
