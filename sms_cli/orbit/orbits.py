"""Keplerian orbits described by their apsides, and the vis-viva helpers.

An ``Orbit`` holds the perigee and apogee *radii* (m, from the centre of the body), the
inclination (rad) and, when known, the RAAN and argument of perigee (rad). Burns are
assumed at an apsis and, for plane changes, with the node on the apse line (Chevallard 2019 L305).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from sms_cli.orbit.constants import Constants

APSIDES = ("perigee", "apogee")


class OrbitError(ValueError):
    """An orbit or a manoeuvre that cannot exist (below the surface, perigee above apogee, ...)."""


def vis_viva(r: float, a: float, mu: float) -> float:
    """Speed (m/s) at radius ``r`` on an orbit of semi-major axis ``a``: v² = μ(2/r − 1/a)."""
    v2 = mu * (2.0 / r - 1.0 / a)
    if v2 < 0:
        raise OrbitError(f"radius {r:.0f} m is not reached by an orbit of semi-major axis {a:.0f} m")
    return math.sqrt(v2)


def circular_speed(r: float, mu: float) -> float:
    """Speed (m/s) of the circular orbit of radius ``r``."""
    return math.sqrt(mu / r)


def period(a: float, mu: float) -> float:
    """Orbital period (s) of semi-major axis ``a``."""
    return 2.0 * math.pi * math.sqrt(a**3 / mu)


def semi_major_axis_for_period(t: float, mu: float) -> float:
    """Semi-major axis (m) whose period is ``t`` seconds."""
    return (mu * (t / (2.0 * math.pi)) ** 2) ** (1.0 / 3.0)


@dataclass(frozen=True)
class Orbit:
    """A Keplerian orbit: perigee/apogee radii (m), inclination, RAAN, argument of perigee (rad)."""

    rp: float
    ra: float
    inc: float = 0.0
    raan: float | None = None
    argp: float | None = None

    def __post_init__(self) -> None:
        if not (self.rp > 0 and math.isfinite(self.ra)):
            raise OrbitError(f"perigee radius must be positive and apogee finite (rp={self.rp}, ra={self.ra})")
        if self.rp > self.ra * (1 + 1e-12):
            raise OrbitError(f"perigee radius {self.rp / 1e3:.3f} km is above apogee radius {self.ra / 1e3:.3f} km")

    @property
    def a(self) -> float:
        """Semi-major axis (m)."""
        return 0.5 * (self.rp + self.ra)

    @property
    def e(self) -> float:
        """Eccentricity."""
        return (self.ra - self.rp) / (self.ra + self.rp)

    @property
    def p(self) -> float:
        """Semi-latus rectum (m)."""
        return self.a * (1.0 - self.e**2)

    def is_circular(self, rtol: float = 1e-9) -> bool:
        return abs(self.ra - self.rp) <= rtol * self.ra

    def apsis(self, which: str) -> float:
        """Radius (m) of the named apsis, ``"perigee"`` or ``"apogee"``."""
        if which == "perigee":
            return self.rp
        if which == "apogee":
            return self.ra
        raise OrbitError(f"unknown apsis '{which}' (perigee or apogee)")

    def opposite(self, which: str) -> float:
        """Radius (m) of the apsis opposite the named one."""
        return self.ra if which == "perigee" else self.rp

    def speed(self, r: float, mu: float) -> float:
        """Speed (m/s) at radius ``r`` (must lie between the apsides)."""
        if r < self.rp * (1 - 1e-9) or r > self.ra * (1 + 1e-9):
            raise OrbitError(f"radius {r / 1e3:.3f} km is outside this orbit's range "
                             f"[{self.rp / 1e3:.3f}, {self.ra / 1e3:.3f}] km")
        return vis_viva(r, self.a, mu)

    def period(self, mu: float) -> float:
        return period(self.a, mu)

    def with_apsides(self, r1: float, r2: float, **kw) -> "Orbit":
        """Same plane, new apsides (in any order)."""
        return replace(self, rp=min(r1, r2), ra=max(r1, r2), **kw)

    def describe(self, constants: Constants) -> str:
        """``"488 x 35790 km @ 7.20 deg"`` (altitudes above the body radius)."""
        hp = (self.rp - constants.radius) / 1e3
        ha = (self.ra - constants.radius) / 1e3
        return f"{_fmt_km(hp)} x {_fmt_km(ha)} km @ {math.degrees(self.inc):.2f} deg"

    def as_dict(self, constants: Constants) -> dict:
        """Altitudes in km and angles in degrees, for results.json."""
        return {
            "perigee_altitude_km": (self.rp - constants.radius) / 1e3,
            "apogee_altitude_km": (self.ra - constants.radius) / 1e3,
            "inclination_deg": math.degrees(self.inc),
            "raan_deg": None if self.raan is None else math.degrees(self.raan),
            "arg_perigee_deg": None if self.argp is None else math.degrees(self.argp),
            "semi_major_axis_km": self.a / 1e3,
            "eccentricity": self.e,
        }


def _fmt_km(x: float) -> str:
    return f"{x:.0f}" if abs(x - round(x)) < 1e-6 else f"{x:.3f}".rstrip("0").rstrip(".")


def orbit_from_altitudes(perigee: float, apogee: float, inc: float, constants: Constants,
                         raan: float | None = None, argp: float | None = None) -> Orbit:
    """Orbit from perigee and apogee altitudes (m above the body radius)."""
    if perigee < 0:
        raise OrbitError(f"perigee altitude {perigee / 1e3:g} km is below the surface")
    if perigee > apogee:
        raise OrbitError(f"perigee altitude {perigee / 1e3:g} km is above apogee altitude {apogee / 1e3:g} km")
    return Orbit(constants.radius + perigee, constants.radius + apogee, inc, raan, argp)


def orbit_from_elements(a: float, e: float, inc: float, constants: Constants,
                        raan: float | None = None, argp: float | None = None) -> Orbit:
    """Orbit from semi-major axis (m) and eccentricity (0 ≤ e < 1)."""
    if not 0 <= e < 1:
        raise OrbitError(f"eccentricity {e} is not that of a closed orbit (0 <= e < 1)")
    rp, ra = a * (1 - e), a * (1 + e)
    if rp < constants.radius:
        raise OrbitError(f"perigee radius {rp / 1e3:.1f} km is below the surface "
                         f"(radius {constants.radius / 1e3:.1f} km)")
    return Orbit(rp, ra, inc, raan, argp)


def j2_raan_rate(orbit: Orbit, constants: Constants) -> float:
    """Secular RAAN drift (rad/s) from J2: Ω̇ = −3/2 n J2 (R/p)² cos i."""
    n = math.sqrt(constants.mu / orbit.a**3)
    return -1.5 * n * constants.j2 * (constants.radius / orbit.p) ** 2 * math.cos(orbit.inc)


def sun_synchronous_inclination(a: float, e: float, constants: Constants) -> float:
    """Inclination (rad) whose J2 node drift equals 2π per tropical year."""
    from sms_cli.orbit.constants import TROPICAL_YEAR

    n = math.sqrt(constants.mu / a**3)
    p = a * (1 - e**2)
    cos_i = -(2.0 * math.pi / TROPICAL_YEAR) / (1.5 * n * constants.j2 * (constants.radius / p) ** 2)
    if abs(cos_i) > 1:
        raise OrbitError(f"no sun-synchronous inclination exists for a = {a / 1e3:.0f} km")
    return math.acos(cos_i)
