"""Propulsion systems: propellant (rocket equation) and burn duration of one burn.

Models (masses in kg, ΔV in m/s, thrust in N, Isp in s, exhaust speed ve = g0·Isp):

- propellant ``tsiolkovsky`` (default): m_p = m0 (1 − e^{−ΔV/ve}).
- propellant ``linearized``: m_p = m0 ΔV / ve, the first-order expansion Chevallard 2019 used for its
  electric burns (eq. 2.8 with t = m0 ΔV/F); it over-estimates the propellant.
- duration ``constant_thrust`` (default): constant thrust F and mass flow F/ve, exact for the
  rocket equation: t = m_p ve / F = m0 (1 − e^{−ΔV/ve}) ve / F. The same law gives the thrusting
  time of an electric (low-thrust) transfer once its ΔV is known (impulsive ΔV × margin, or the
  Edelbaum ΔV of ``low_thrust`` steps).
- duration ``linearized``: t = m0 ΔV / F (momentum with the initial mass; Chevallard 2019 IOS tables).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Propulsion:
    """A propulsion system: kind (chemical/electric), Isp (s), thrust (N), models and ΔV margins."""

    name: str
    kind: str
    isp: float
    thrust: float
    g0: float = 9.80665
    propellant_model: str = "tsiolkovsky"
    duration_model: str = "constant_thrust"
    dv_margins: dict = field(default_factory=dict)

    @property
    def ve(self) -> float:
        """Effective exhaust speed (m/s)."""
        return self.isp * self.g0

    def margin_for(self, maneuver_type: str) -> float:
        """ΔV factor this system applies to a manoeuvre type (``default`` otherwise, else 1)."""
        return float(self.dv_margins.get(maneuver_type, self.dv_margins.get("default", 1.0)))

    def burn(self, m0: float, dv: float) -> tuple[float, float]:
        """(propellant kg, duration s) of a burn of ΔV ``dv`` starting at mass ``m0``."""
        mp = propellant_mass(m0, dv, self.ve, self.propellant_model)
        if self.duration_model == "linearized":
            t = m0 * dv / self.thrust
        else:
            t = mp * self.ve / self.thrust
        return mp, t


def propellant_mass(m0: float, dv: float, ve: float, model: str = "tsiolkovsky") -> float:
    """Propellant (kg) to give mass ``m0`` the velocity change ``dv`` with exhaust speed ``ve``."""
    if model == "linearized":
        return m0 * dv / ve
    return m0 * -math.expm1(-dv / ve)


def delta_v(m0: float, m1: float, ve: float) -> float:
    """Rocket equation: ΔV (m/s) from mass ``m0`` to ``m1`` (inverse of ``propellant_mass``)."""
    return ve * math.log(m0 / m1)


def burn_duration_constant_thrust(m0: float, dv: float, ve: float, thrust: float) -> float:
    """Thrusting time (s) to deliver ``dv`` at constant thrust and Isp: m0 (1 − e^{−ΔV/ve}) ve / F."""
    return propellant_mass(m0, dv, ve) * ve / thrust
