"""Quantities with units in mission files (closed-form conversions)."""

import math

import pytest

from sms_cli.mission.units import UnitError, to_si


@pytest.mark.parametrize(
    "text, dim, expected",
    [
        ("2800 rpm", "angular rate", 2800 * 2 * math.pi / 60),
        ("57.6 deg", "angle", math.radians(57.6)),
        ("0.16 Hz", "angular rate", 0.16 * 2 * math.pi),
        ("0.16 Hz", "frequency", 0.16),
        ("35786 km", "length", 35_786_000.0),
        ("4e-4 kg m^2", "inertia", 4e-4),
        ("0.2 N m", "torque", 0.2),
        ("50 N*m*s", "angular momentum", 50.0),
        ("398600.4418 km^3/s^2", "gravitational parameter", 3.986004418e14),
        ("3 deg/s", "angular rate", math.radians(3)),
        ("10 min", "time", 600.0),
        ("1 1/s", "angular rate", 1.0),
    ],
)
def test_conversions(text, dim, expected):
    if expected is None:
        with pytest.raises(UnitError):
            to_si(text, dim)
    else:
        assert to_si(text, dim) == pytest.approx(expected, rel=1e-12)


def test_bare_numbers_are_si():
    assert to_si(1.5, "angle") == 1.5
    assert to_si(7, "mass") == 7.0


@pytest.mark.parametrize("text, dim", [("3 kg", "length"), ("5 parsecs", "length"), ("fast", "angular rate"), ("2 N", "torque")])
def test_wrong_dimension_or_unit(text, dim):
    with pytest.raises(UnitError):
        to_si(text, dim)
