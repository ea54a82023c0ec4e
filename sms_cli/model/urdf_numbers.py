"""Every number a URDF writes, checked before urdfdom sees it.

urdfdom reports a malformed number as "… at line 243 in model.cpp" (its own source line) or
not at all; Python's ``float`` raises with no location. Here each numeric attribute of the URDF
elements urdfdom parses is read once, with its element's line: a value that is not a decimal
number, is NaN, is infinite (outside ``<limit>``, where ±inf means "unbounded") or is larger in
magnitude than ``MAX_MAGNITUDE`` (SI units: no robot has 1e10 kg, m or kg m²) is a problem with
file:line and a fix. Missing required attributes of ``<inertia>`` are filled with 0 (warned).
"""

from __future__ import annotations

import math
import re

from sms_cli.errors import Location, Problem, Warnings

#: Largest magnitude accepted for a URDF number (SI units); larger is a typo or a unit error.
MAX_MAGNITUDE = 1e10

#: (element tag, attribute) → number of values it holds (URDF 1.0 specification).
NUMERIC_ATTRIBUTES: dict[tuple[str, str], int] = {
    ("origin", "xyz"): 3, ("origin", "rpy"): 3,
    ("mass", "value"): 1,
    **{("inertia", k): 1 for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")},
    ("axis", "xyz"): 3,
    **{("limit", k): 1 for k in ("lower", "upper", "effort", "velocity")},
    ("dynamics", "damping"): 1, ("dynamics", "friction"): 1,
    **{("safety_controller", k): 1 for k in ("soft_lower_limit", "soft_upper_limit", "k_position", "k_velocity")},
    **{("calibration", k): 1 for k in ("rising", "falling", "reference_position")},
    ("mimic", "multiplier"): 1, ("mimic", "offset"): 1,
    ("box", "size"): 3, ("cylinder", "radius"): 1, ("cylinder", "length"): 1, ("sphere", "radius"): 1,
    ("capsule", "radius"): 1, ("capsule", "length"): 1, ("mesh", "scale"): 3,
    ("color", "rgba"): 4,
}
INERTIA_KEYS = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
#: A decimal number as urdfdom reads it (no hex, no digit separators), or ±inf.
_DECIMAL = re.compile(r"[+-]?((\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|inf|infinity)", re.IGNORECASE)


def _owner(el) -> str:
    """'link 'x'' / 'joint 'y'' / 'material 'z'' that an element belongs to, for messages."""
    node = el
    while node is not None:
        if node.tag in ("link", "joint", "material") and node.get("name"):
            return f"{node.tag} '{node.get('name')}'"
        node = node.getparent()
    return "the robot"


def _shown(text: str) -> str:
    return text if len(text) <= 40 else text[:37] + "…"


def parse_numbers(text: str, count: int) -> tuple[list[float] | None, str]:
    """Values of an attribute holding ``count`` decimal numbers, or (None, why not)."""
    parts = text.split()
    if len(parts) != count:
        return None, f"holds {len(parts)} value(s), expected {count}"
    out = []
    for p in parts:
        if not _DECIMAL.fullmatch(p):
            return None, "is NaN" if p.lower().lstrip("+-") == "nan" else f"'{_shown(p)}' is not a decimal number"
        out.append(float(p))
    return out, ""


def check_numbers(root, path, problems: list[Problem], warnings: Warnings) -> None:
    """Check every numeric attribute below ``root``; append problems (with lines) in document order."""
    for el in root.iter():
        tag = el.tag if isinstance(el.tag, str) else ""
        for attr, text in el.attrib.items():
            count = NUMERIC_ATTRIBUTES.get((tag, attr))
            if count is None:
                continue
            where = Location(path, el.sourceline or 0)
            values, why = parse_numbers(text, count)
            if values is None:
                problems.append(Problem(f"{_owner(el)}: <{tag} {attr}=\"{_shown(text)}\"> {why}", where,
                                        hint=f"write {count} decimal number(s) in SI units" + (", separated by spaces" if count > 1 else "")))
                continue
            big = [x for x in values if abs(x) > MAX_MAGNITUDE]
            if big and tag == "limit":
                el.set(attr, repr(math.copysign(MAX_MAGNITUDE, big[0])))  # ±inf / huge: unbounded
            elif big:
                what = "is infinite" if math.isinf(big[0]) else f"is out of range (|value| > {MAX_MAGNITUDE:g} in SI units)"
                problems.append(Problem(f"{_owner(el)}: <{tag} {attr}=\"{_shown(text)}\"> {what}", where,
                                        hint="check the units (kg, m, kg m^2, rad) and the exponent"))
        if tag == "inertia":
            missing = [k for k in INERTIA_KEYS if el.get(k) is None]
            if missing:
                warnings.add(f"{_owner(el)}: <inertia> lacks {', '.join(missing)}; read as 0",
                             Location(path, el.sourceline or 0), "inertia", "write all six of ixx iyy izz ixy ixz iyz")
                for k in missing:
                    el.set(k, "0")


def number(el, attr: str, default: float) -> float:
    """One number of an element, or the default when absent or malformed (``check_numbers`` reports those)."""
    values = vector(el, attr, (default,))
    return values[0]


def vector(el, attr: str, default: tuple[float, ...]) -> list[float]:
    """A vector attribute, or the default when absent, malformed or out of range (``check_numbers``
    reports those; it already made an out-of-range ``<limit>`` "unbounded")."""
    if el is None or el.get(attr) is None:
        return list(default)
    values, _ = parse_numbers(el.get(attr), len(default))
    if values is None or any(abs(x) > MAX_MAGNITUDE for x in values):
        return list(default)
    return values
