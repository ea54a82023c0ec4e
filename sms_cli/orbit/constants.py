"""Physical constants of the central body (Earth by default), overridable per mission.

SI units: μ in m^3/s^2, radius in m, g0 in m/s^2 (the standard gravity that defines Isp),
J2 dimensionless. Chevallard 2019 used two other sets; see ``CHEVALLARD_PRELIMINARY`` and
``CHEVALLARD_IOS`` (found by reproducing its tables, Chevallard 2019 reading notes §2.4).
"""

from __future__ import annotations

from dataclasses import dataclass

#: Tropical year (s); a sun-synchronous node turns 2π per tropical year.
TROPICAL_YEAR = 365.24219 * 86400.0


@dataclass(frozen=True)
class Constants:
    """Gravitational parameter, equatorial radius, standard gravity and J2 of the central body."""

    mu: float = 3.986004418e14  # m^3/s^2 (EGM-96 / WGS-84)
    radius: float = 6378137.0  # m (WGS-84 equatorial radius)
    g0: float = 9.80665  # m/s^2 (standard gravity, defines Isp)
    j2: float = 1.08262668e-3  # EGM-96 unnormalised J2

    def __post_init__(self) -> None:
        for name in ("mu", "radius", "g0"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")


EARTH = Constants()
#: Chevallard 2019 preliminary trade-off (Tables 3.1-3.12): R_E 6378 km, μ 398600.44 km^3/s^2, g0 9.80665.
CHEVALLARD_PRELIMINARY = Constants(mu=3.9860044e14, radius=6378.0e3, g0=9.80665)
#: Chevallard 2019 IOS budgets (Tables 3.14-3.20): R_E 6371 km, μ 398600 km^3/s^2, g 9.81.
CHEVALLARD_IOS = Constants(mu=3.986e14, radius=6371.0e3, g0=9.81)
