"""Physical quantities in mission files: ``"2800 rpm"``, ``"57.6 deg"``, ``"35786 km"``.

One source of truth for unit conversion. Inside sms every number is SI and every angle
is in radians; a bare number in a mission file is already SI. Strings carry a value and a
unit expression (``"0.2 N m"``, ``"4e-4 kg m^2"``, ``"3 deg/s"``, ``"50 N*m*s"``).

Dimensions are vectors over (length, mass, time, angle). Angle is kept as its own
dimension so that ``"0.16 Hz"`` can mean 2π·0.16 rad/s for an angular frequency, and
``"2800 rpm"`` converts to rad/s. A quantity with no angle where an angle is expected
(``"1/s"`` for a rate) is taken as radians.

Use the ``Annotated`` types below as pydantic field types: ``Length``, ``Mass``, ...
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass
from functools import cache
from typing import Annotated, Any

from pydantic import BeforeValidator

# (length, mass, time, angle)
Dim = tuple[int, int, int, int]

_BASE_UNITS: dict[str, tuple[float, Dim]] = {
    # length
    "m": (1.0, (1, 0, 0, 0)),
    "km": (1e3, (1, 0, 0, 0)),
    "cm": (1e-2, (1, 0, 0, 0)),
    "mm": (1e-3, (1, 0, 0, 0)),
    # mass
    "kg": (1.0, (0, 1, 0, 0)),
    "g": (1e-3, (0, 1, 0, 0)),
    "t": (1e3, (0, 1, 0, 0)),
    # time
    "s": (1.0, (0, 0, 1, 0)),
    "ms": (1e-3, (0, 0, 1, 0)),
    "min": (60.0, (0, 0, 1, 0)),
    "h": (3600.0, (0, 0, 1, 0)),
    "day": (86400.0, (0, 0, 1, 0)),
    "days": (86400.0, (0, 0, 1, 0)),
    "d": (86400.0, (0, 0, 1, 0)),
    "yr": (365.25 * 86400.0, (0, 0, 1, 0)),
    # angle
    "rad": (1.0, (0, 0, 0, 1)),
    "deg": (math.pi / 180.0, (0, 0, 0, 1)),
    "°": (math.pi / 180.0, (0, 0, 0, 1)),
    "arcmin": (math.pi / 180.0 / 60.0, (0, 0, 0, 1)),
    "arcsec": (math.pi / 180.0 / 3600.0, (0, 0, 0, 1)),
    "rev": (2.0 * math.pi, (0, 0, 0, 1)),
    # derived
    "rpm": (2.0 * math.pi / 60.0, (0, 0, -1, 1)),
    "Hz": (2.0 * math.pi, (0, 0, -1, 1)),  # cycles per second; 1 cycle = 2π rad
    "N": (1.0, (1, 1, -2, 0)),
    "mN": (1e-3, (1, 1, -2, 0)),
    "kN": (1e3, (1, 1, -2, 0)),
    "mNm": (1e-3, (2, 1, -2, 0)),
    "Nm": (1.0, (2, 1, -2, 0)),
    "Nms": (1.0, (2, 1, -1, 0)),
    "J": (1.0, (2, 1, -2, 0)),
    "W": (1.0, (2, 1, -3, 0)),
}

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_QUANTITY_RE = re.compile(rf"^\s*({_NUMBER})\s*(.*?)\s*$")
_TOKEN_RE = re.compile(r"([A-Za-z°]+)(?:\^?([-+]?\d{1,2}))?")
_SEP = r"[\s*·.]+"  # between the factors of a product ("N m", "N*m", "N·m", "N.m")
#: Longest quantity string read (characters); longer ones are refused before parsing.
MAX_QUANTITY_CHARS = 200
#: Characters of a user's value echoed in a message.
ECHO_CHARS = 60

#: Named dimensions of the quantity types (used in messages and the JSON Schema).
DIMENSIONS: dict[str, Dim] = {
    "dimensionless": (0, 0, 0, 0),
    "length": (1, 0, 0, 0),
    "mass": (0, 1, 0, 0),
    "time": (0, 0, 1, 0),
    "angle": (0, 0, 0, 1),
    "angular rate": (0, 0, -1, 1),
    "angular acceleration": (0, 0, -2, 1),
    "frequency": (0, 0, -1, 0),
    "velocity": (1, 0, -1, 0),
    "acceleration": (1, 0, -2, 0),
    "force": (1, 1, -2, 0),
    "torque": (2, 1, -2, 0),
    "angular momentum": (2, 1, -1, 0),
    "inertia": (2, 1, 0, 0),
    "rotational stiffness": (2, 1, -2, -1),
    "rotational damping": (2, 1, -1, -1),
    "linear stiffness": (0, 1, -2, 0),
    "linear damping": (0, 1, -1, 0),
    "gravitational parameter": (3, 0, -2, 0),
    "power": (2, 1, -3, 0),
}

_EXAMPLES = {
    "length": '"35786 km"',
    "mass": '"150 kg"',
    "time": '"10 min"',
    "angle": '"57.6 deg"',
    "angular rate": '"2800 rpm" or "0.5 deg/s"',
    "frequency": '"0.16 Hz"',
    "velocity": '"7.8 km/s"',
    "force": '"0.5 N"',
    "torque": '"0.2 N m"',
    "angular momentum": '"50 N m s"',
    "inertia": '"4e-4 kg m^2"',
    "rotational stiffness": '"120 N m/rad"',
    "rotational damping": '"2 N m s/rad"',
    "gravitational parameter": '"398600.4418 km^3/s^2"',
}


class SpecError(ValueError):
    """A mission-schema check that failed: the message, where below the validated value
    (a key path such as ``("joints", 2)``) and how to fix it (shown as ``fix:``)."""

    def __init__(self, message: str, at: tuple = (), hint: str = ""):
        super().__init__(message)
        self.at = tuple(at)
        self.hint = hint


class UnitError(SpecError):
    """A quantity string that cannot be read or has the wrong dimension."""


def clip(value: Any, n: int = ECHO_CHARS) -> str:
    """``repr(value)`` cut to about ``n`` characters with "…" (for echoing user input in messages)."""
    text = repr(value)
    return text if len(text) <= n else text[: n - 1] + "…"


def _a(noun: str) -> str:
    """``noun`` with its indefinite article ("an angle", "a mass")."""
    return f"{'an' if noun[0] in 'aeiou' else 'a'} {noun}"


def _units_of(wanted: Dim) -> str:
    """The single-token units of a dimension (for messages), e.g. "deg, rad, rev" for an angle."""
    return ", ".join(sorted(u for u, (_, d) in _BASE_UNITS.items() if d != (0, 0, 0, 0) and _compatible(d, wanted)))


def _parse_unit_expression(expr: str) -> tuple[float, Dim]:
    """Return (SI factor, dimension) of a unit expression such as ``"N m s/rad"``."""
    expr = expr.strip()
    if not expr:
        return 1.0, (0, 0, 0, 0)
    factor = 1.0
    dim = [0, 0, 0, 0]
    parts = expr.split("/")
    for i, part in enumerate(parts):
        sign = 1 if i == 0 else -1
        for raw in re.split(_SEP, part.strip()):
            if not raw or raw == "1":
                continue
            m = _TOKEN_RE.fullmatch(raw)
            if not m or m.group(1) not in _BASE_UNITS:
                known = ", ".join(sorted(_BASE_UNITS))
                raise UnitError(f"unknown unit {clip(raw)}", hint=f"known units: {known}")
            f, d = _BASE_UNITS[m.group(1)]
            p = sign * int(m.group(2) or 1)
            try:
                factor *= f**p
            except OverflowError:
                raise UnitError(f"unit {clip(expr)} is out of range") from None
            for k in range(4):
                dim[k] += d[k] * p
    return factor, (dim[0], dim[1], dim[2], dim[3])


def _compatible(given: Dim, wanted: Dim) -> bool:
    """Same dimension, allowing a missing angle (implicit radians) on the given side, or
    an angle where none is wanted (read as cycles: "0.16 Hz" as a frequency is 0.16 1/s)."""
    if given[:3] != wanted[:3]:
        return False
    return given[3] == wanted[3] or given[3] == 0 or wanted[3] == 0


def to_si(value: Any, dimension: str) -> float:
    """Convert a bare number (already SI) or a ``"<number> <unit>"`` string to SI.

    A string without a unit (``"1e2"``) is SI, like a bare number. Raises UnitError (with the
    expected dimension and an example) when the value cannot be read or its unit has another
    dimension. NaN and infinity pass through: the mission schema refuses them (``StrictModel``).
    """
    wanted = DIMENSIONS[dimension]
    ex = _EXAMPLES.get(dimension, "1.0")
    fix = f"write a number (SI) or a number and a unit of {dimension}, e.g. {ex}"
    if isinstance(value, bool):
        raise UnitError(f"expected {_a(dimension)}, got a boolean", hint=fix)
    if isinstance(value, (int, float)):
        return float(value)
    if not isinstance(value, str):
        raise UnitError(f"expected {_a(dimension)} (number or string with unit), got {type(value).__name__}", hint=fix)
    if len(value) > MAX_QUANTITY_CHARS:
        raise UnitError(f"expected {_a(dimension)}, got a string of {len(value)} characters {clip(value)}", hint=fix)
    m = _QUANTITY_RE.match(value)
    if not m:
        raise UnitError(f"cannot read {clip(value)} as {_a(dimension)}", hint=fix)
    number = float(m.group(1))
    if not m.group(2):
        return number
    try:
        factor, dim = _parse_unit_expression(m.group(2))
    except UnitError as exc:
        units = _units_of(wanted)
        raise UnitError(f"{exc} in {clip(value)}: expected {_a(dimension)}",
                        hint=f"{fix}" + (f" (units of {dimension}: {units})" if units else "")) from None
    if not _compatible(dim, wanted):
        raise UnitError(f"{clip(value)} is not {_a(dimension)}", hint=fix)
    if wanted[3] == 0 and dim[3] != 0:
        factor /= (2.0 * math.pi) ** dim[3]  # angle where none is wanted: count cycles
    return number * factor


# ------------------------------------------------------------------ the JSON Schema's unit patterns
# The schema lists, for each kind, the unit expressions people write, built from _BASE_UNITS and
# spelled with the separators, powers and "/" that _parse_unit_expression reads. The loader reads
# more (any order of the factors, "m m/m" for a length); the schema is a subset of it (tested).

#: Dimensions of the base units, in the order the schema writes them in a product ("kg m^2 s^-2").
_BASE_DIMS: tuple[Dim, ...] = ((0, 1, 0, 0), (1, 0, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1))
_PER = r"\s*/\s*"  # every factor after a "/" is in the denominator ("m/s/s" = m/s^2)

Factor = tuple[Dim, int]  # a unit class (the tokens of one dimension) and its power
Product = tuple[tuple[Factor, ...], tuple[Factor, ...]]  # numerator, denominator


@cache
def _unit_classes() -> dict[Dim, tuple[str, ...]]:
    """The unit tokens of _BASE_UNITS by dimension, the SI one first: {(1, 0, 0, 0): ("m", "km", "cm", "mm"), ...}."""
    classes: dict[Dim, list[str]] = {}
    for token, (_, dim) in _BASE_UNITS.items():
        classes.setdefault(dim, []).append(token)
    return {dim: tuple(sorted(tokens, key=lambda t: _BASE_UNITS[t][0] != 1.0)) for dim, tokens in classes.items()}


def _subsets(classes: tuple[Dim, ...], powers: tuple[int, ...], most: int):
    """Products of at most ``most`` distinct classes (in the given order), each at one of ``powers``."""
    for n in range(most + 1):
        for chosen in itertools.combinations(classes, n):
            for ps in itertools.product(powers, repeat=n):
                yield tuple(zip(chosen, ps))


def _products() -> list[Product]:
    """The unit products the schema can list, before the dimension filter:

    - base units (mass, length, time, angle), powers 1-3: up to 3 factors over up to 2
      (``kg m^2/s^2``), or up to 3 factors with negative powers last (``kg m^2 s^-2``);
    - one derived unit (N, Nm, Nms, W and their multiples) with length, time and angle to the
      power 1 on either side (``N m s/rad``, ``N/m``);
    - a per-time angle unit (rpm, Hz) alone or per time (``rpm/s``).
    """
    classes = _unit_classes()
    out: list[Product] = []
    for num in _subsets(_BASE_DIMS, (1, 2, 3), 3):
        rest = tuple(c for c in _BASE_DIMS if c not in dict(num))
        out.extend((num, den) for den in _subsets(rest, (1, 2, 3), 2) if num or den)
        for signs in itertools.product((1, -1), repeat=len(num)):
            if -1 in signs:
                signed = tuple((c, p * s) for (c, p), s in zip(num, signs))
                out.append((tuple(f for f in signed if f[1] > 0) + tuple(f for f in signed if f[1] < 0), ()))
    lta = _BASE_DIMS[1:]
    for derived in (d for d in classes if d not in _BASE_DIMS):
        if derived[1] == 0:  # no mass: rpm, Hz
            out += [(((derived, 1),), ()), (((derived, 1),), ((_BASE_DIMS[2], 1),))]
            continue
        for num in _subsets(lta, (1,), 3):
            rest = tuple(c for c in lta if c not in dict(num))
            out.extend((((derived, 1),) + num, den) for den in _subsets(rest, (1,), 3))
    return out


def _dimension_of(product: Product) -> Dim:
    num, den = product
    return tuple(sum(c[k] * p for c, p in num) - sum(c[k] * p for c, p in den) for k in range(4))  # type: ignore[return-value]


@cache
def unit_products(dimension: str) -> tuple[Product, ...]:
    """The unit products the JSON Schema accepts for a quantity kind: those the loader reads as this
    kind (``_compatible``) whose angle is the kind's or absent (implicit radians); a per-time angle
    unit alone also counts as a frequency (``"0.16 Hz"``: the loader counts cycles)."""
    wanted = DIMENSIONS[dimension]
    out = []
    for product in _products():
        given = _dimension_of(product)
        if not _compatible(given, wanted):
            continue
        cycles = not product[1] and len(product[0]) == 1 and product[0][0][0] not in _BASE_DIMS and given[:3] == wanted[:3]
        if given[3] in (0, wanted[3]) or cycles:
            out.append(product)
    return tuple(out)


def spell(product: Product, pick: int = 0) -> str:
    """A product written with the ``pick``-th token of each class (clamped): ``"kg m^2/s^2"``."""
    classes = _unit_classes()

    def factor(c: Dim, p: int) -> str:
        tokens = classes[c]
        return tokens[min(pick, len(tokens) - 1)] + ("" if p == 1 else f"^{p}")

    num, den = product
    text = " ".join(factor(c, p) for c, p in num) or "1"
    return text + ("/" + " ".join(factor(c, p) for c, p in den) if den else "")


def _factor_pattern(c: Dim, p: int) -> str:
    tokens = "|".join(sorted(_unit_classes()[c], key=len, reverse=True))
    power = r"(?:\^?\+?1)?" if p == 1 else (rf"\^?\+?{p}" if p > 0 else rf"\^?-{-p}")
    return f"(?:{tokens}){power}"


@cache
def quantity_pattern(dimension: str) -> str:
    """The JSON Schema pattern (ECMA-262 and Python ``re``) of a quantity string of this kind: a
    number as ``to_si`` reads it, then nothing (SI) or one of ``unit_products(dimension)``."""
    alternatives = []
    for num, den in unit_products(dimension):
        text = _SEP.join(_factor_pattern(c, p) for c, p in num) or "1?"
        if den:
            text += _PER + f"(?:{_SEP}|{_PER})".join(_factor_pattern(c, p) for c, p in den)
        alternatives.append(text)
    units = rf"\s*(?:{'|'.join(alternatives)})?" if alternatives else ""
    return rf"^\s*{_NUMBER}{units}\s*$"


def quantity_text_schema(dimension: str) -> dict[str, Any]:
    """JSON Schema of the string form of a quantity (``"150 kg"``), its description listing the units."""
    products = unit_products(dimension)
    if products:
        classes = _unit_classes()
        used = {c for num, den in products for c, _ in num + den}
        others = "; ".join(f"{', '.join(classes[c][1:])} for {classes[c][0]}" for c in classes if c in used and len(classes[c]) > 1)
        units = (f"a number, then nothing (SI) or one of: {', '.join(spell(p) for p in products)}"
                 + (f" (or {others})" if others else ""))
    else:
        units = "a number, without a unit"
    return {"type": "string", "pattern": quantity_pattern(dimension), "maxLength": MAX_QUANTITY_CHARS,
            "description": f"{dimension} as text: {units}"}


def quantity_description(dimension: str) -> str:
    """What a quantity field's hover says: ``mass (bare number = SI; or a string with a unit, e.g. "150 kg")``."""
    return f"{dimension} (bare number = SI; or a string with a unit, e.g. {_EXAMPLES.get(dimension, '1.0')})"


@dataclass(frozen=True)
class _QuantitySchema:
    """JSON Schema of a quantity field: the number (with the field's bounds, ``gt=0`` → exclusiveMinimum)
    or the string of this kind. ``sms_cli.mission.json_schema`` moves the string form into ``$defs``
    and carries the bounds over to it."""

    dimension: str

    def __get_pydantic_json_schema__(self, core_schema: Any, handler: Any) -> dict[str, Any]:
        number = handler(core_schema)
        return {"anyOf": [number, quantity_text_schema(self.dimension)], "description": quantity_description(self.dimension)}


def _quantity(dimension: str) -> Any:
    def validate(v: Any) -> float:
        return to_si(v, dimension)  # UnitError is a ValueError: pydantic reports it with its hint

    return Annotated[float, BeforeValidator(validate), _QuantitySchema(dimension)]


Length = _quantity("length")
Mass = _quantity("mass")
Time = _quantity("time")
Angle = _quantity("angle")
AngularRate = _quantity("angular rate")
Frequency = _quantity("frequency")
Velocity = _quantity("velocity")
Acceleration = _quantity("acceleration")
Force = _quantity("force")
Torque = _quantity("torque")
AngularMomentum = _quantity("angular momentum")
Inertia = _quantity("inertia")
RotationalStiffness = _quantity("rotational stiffness")
RotationalDamping = _quantity("rotational damping")
LinearStiffness = _quantity("linear stiffness")
LinearDamping = _quantity("linear damping")
GravitationalParameter = _quantity("gravitational parameter")
Dimensionless = _quantity("dimensionless")


def any_to_si(value: Any) -> float:
    """A bare number (SI), a percentage (``"3 %"`` → 0.03) or ``"<number> <unit>"`` in SI, whatever
    the unit's dimension (for values whose dimension is the target field's, checked there)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise UnitError(f"expected a number or a number and a unit, got {clip(value)}",
                        hint="write e.g. 0.03, \"3 %\" or \"2 deg\"")
    if not isinstance(value, str):
        return float(value)
    text = value.strip()
    if text.endswith("%"):
        try:
            return float(text[:-1]) / 100.0
        except ValueError:
            raise UnitError(f"cannot read {clip(value)} as a percentage", hint="write e.g. \"3 %\"") from None
    m = _QUANTITY_RE.match(text)
    if not m:
        raise UnitError(f"cannot read {clip(value)} as a number and a unit", hint="write e.g. 0.03 or \"2 deg\"")
    factor, _ = _parse_unit_expression(m.group(2)) if m.group(2) else (1.0, None)
    return float(m.group(1)) * factor
