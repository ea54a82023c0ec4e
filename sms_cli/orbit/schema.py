"""The ``budget:`` section of a mission file (pydantic; no numpy/scipy here so loading stays light).

A budget is an initial orbit, propulsion systems, a spacecraft (dry mass, optional wet mass)
and an ordered ``sequence`` of steps, each keyed by ``type:`` (manoeuvres, waits and mass
events). A trade-off of several scenarios side by side is written as ``scenarios:`` (a list of
named sequences sharing the constants, propulsion and margins) instead of ``sequence:``.
Altitudes are above the body's equatorial radius (``constants.earth_radius``).
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, model_validator

from sms_cli.mission.base import StrictModel
from sms_cli.mission.units import (
    Acceleration,
    Angle,
    Dimensionless,
    Force,
    GravitationalParameter,
    Length,
    Mass,
    Time,
    Velocity,
)

Apsis = Literal["perigee", "apogee"]


class ConstantsSpec(StrictModel):
    """Central-body constants (defaults: Earth, WGS-84/EGM-96). Chevallard 2019 used other values."""

    mu: GravitationalParameter = Field(3.986004418e14, gt=0, description="gravitational parameter, e.g. \"398600.4418 km^3/s^2\"")
    earth_radius: Length = Field(6378137.0, gt=0, description="equatorial radius; altitudes are measured from it")
    g0: Acceleration = Field(9.80665, gt=0, description="standard gravity that defines Isp (ve = g0 Isp)")
    j2: Dimensionless = Field(1.08262668e-3, description="J2 zonal coefficient (node drift of raan_drift steps)")


class OrbitSpec(StrictModel):
    """A Keplerian orbit: perigee × apogee altitudes (or semi_major_axis + eccentricity) @ inclination."""

    perigee: Length | None = Field(None, description="perigee altitude above earth_radius")
    apogee: Length | None = Field(None, description="apogee altitude above earth_radius")
    semi_major_axis: Length | None = Field(None, gt=0, description="instead of perigee/apogee: semi-major axis (from the centre)")
    eccentricity: Dimensionless | None = Field(None, ge=0, lt=1, description="with semi_major_axis")
    inclination: Angle = Field(0.0, description="inclination, e.g. \"98.5 deg\"")
    raan: Angle | None = Field(None, description="right ascension of the ascending node (optional)")
    arg_perigee: Angle | None = Field(None, description="argument of perigee (optional)")

    @model_validator(mode="after")
    def _one_form(self) -> "OrbitSpec":
        apsides = self.perigee is not None or self.apogee is not None
        elements = self.semi_major_axis is not None or self.eccentricity is not None
        if apsides and elements:
            raise ValueError("give either perigee + apogee altitudes or semi_major_axis + eccentricity, not both")
        if elements and (self.semi_major_axis is None or self.eccentricity is None):
            raise ValueError("semi_major_axis and eccentricity go together")
        if not elements:
            if self.perigee is None or self.apogee is None:
                raise ValueError("an orbit needs perigee and apogee altitudes (or semi_major_axis + eccentricity)")
            if self.perigee < 0:
                raise ValueError(f"perigee altitude {self.perigee / 1e3:g} km is below the surface")
            if self.perigee > self.apogee:
                raise ValueError(f"perigee altitude {self.perigee / 1e3:g} km is above apogee altitude "
                                 f"{self.apogee / 1e3:g} km: swap them")
        return self


class PropulsionSpec(StrictModel):
    """A propulsion system. ``dv_margins`` multiply the ΔV of the burns it performs."""

    kind: Literal["chemical", "electric"] = Field(description="chemical (impulsive) or electric (low thrust)")
    isp: Time = Field(gt=0, description="specific impulse, e.g. \"321 s\"")
    thrust: Force = Field(gt=0, description="total thrust of the firing thrusters, e.g. \"80 N\" or \"224 mN\"")
    propellant_model: Literal["tsiolkovsky", "linearized"] = Field(
        "tsiolkovsky", description="tsiolkovsky: m0(1-exp(-dV/ve)); linearized: m0 dV/ve (Chevallard 2019 electric, conservative)")
    duration_model: Literal["constant_thrust", "linearized"] = Field(
        "constant_thrust", description="constant_thrust: t = m_prop ve/F (exact); linearized: t = m0 dV/F (Chevallard 2019 IOS)")
    dv_margins: dict[str, Dimensionless] = Field(
        default_factory=dict,
        description="ΔV factor per step type for this system, plus 'default' (Chevallard 2019 electric: plane_change 1.3, default 1.2)")
    description: str = Field("", description="free text")


class SpacecraftSpec(StrictModel):
    """The chaser's masses. Without wet_mass, the budget sizes it (smallest launch mass that closes)."""

    dry_mass: Mass = Field(gt=0, description="dry mass of the chaser (no propellant, no captured target)")
    wet_mass: Mass | None = Field(None, gt=0, description="mass at the start of the sequence; omit to size it")


class MarginsSpec(StrictModel):
    """Margins: ΔV factors per step type (all systems) and a propellant reserve."""

    propellant: Dimensionless = Field(
        0.0, ge=0, description="reserve as a fraction of the propellant consumed: closes when "
                               "m_final >= m_dry + margin*m_prop (Chevallard 2019 eq. 3.2 uses 0.3)")
    dv: dict[str, Dimensionless] = Field(
        default_factory=dict, description="ΔV factor per step type for every propulsion system, plus 'default'")


class SizingSpec(StrictModel):
    """Wet-mass sizing: the smallest launch mass that closes the budget (Chevallard 2019 eq. 3.1)."""

    grid: Mass = Field(0.0, ge=0, description="round the sized mass up to a multiple of this (Chevallard 2019: 100 kg); 0 = exact")
    max_mass: Mass = Field(1.0e7, gt=0, description="give up above this launch mass (the budget diverges)")


# ------------------------------------------------------------------ steps


class _Step(StrictModel):
    name: str | None = Field(None, description="label in the tables (default: the type)")
    phase: str | None = Field(None, description="group for the ΔV-per-phase roll-up (default: the previous step's phase)")


class _Burn(_Step):
    propulsion: str | None = Field(None, description="propulsion system name (default: budget.default_propulsion)")


class ApsisChange(_Burn):
    """Tangential burn at an apsis that moves the opposite apsis (raise/lower perigee or apogee)."""

    type: Literal["apsis_change"]
    at: Apsis = Field(description="where the burn happens; the OTHER apsis moves")
    altitude: Length = Field(description="new altitude of the opposite apsis")


class Circularize(_Burn):
    """Tangential burn that makes the orbit circular at the given apsis."""

    type: Literal["circularize"]
    at: Apsis = Field(description="apsis whose radius the circular orbit keeps")


class Hohmann(_Burn):
    """Two-burn transfer to a circular orbit (Hohmann from a circular orbit)."""

    type: Literal["hohmann"]
    altitude: Length = Field(description="altitude of the final circular orbit")


class BiElliptic(_Burn):
    """Three-burn bi-elliptic transfer between circular orbits."""

    type: Literal["bielliptic"]
    altitude: Length = Field(description="altitude of the final circular orbit")
    intermediate_altitude: Length = Field(description="apoapsis altitude of the two transfer ellipses")


class PlaneChange(_Burn):
    """Pure plane change at an apsis: 2 v sin(Δθ/2) (node assumed on the apse line)."""

    type: Literal["plane_change"]
    at: Apsis = Field(description="apsis of the burn (apogee is cheaper)")
    inclination: Angle | None = Field(None, description="new inclination")
    delta_inclination: Angle | None = Field(None, description="instead of inclination: change (signed)")
    raan: Angle | None = Field(None, description="new RAAN (needs the current RAAN)")

    @model_validator(mode="after")
    def _one(self) -> "PlaneChange":
        if (self.inclination is None) == (self.delta_inclination is None):
            raise ValueError("give exactly one of inclination or delta_inclination")
        return self


class CombinedChange(_Burn):
    """Shape + plane change in two burns with the plane change split between them (law of cosines)."""

    type: Literal["combined"]
    perigee: Length = Field(description="target perigee altitude")
    apogee: Length = Field(description="target apogee altitude")
    inclination: Angle = Field(description="target inclination")
    first_burn_at: Apsis = Field("perigee", description="apsis of the current orbit where burn 1 happens")
    second_burn_at: Apsis | None = Field(None, description="apsis of the target orbit where burn 2 happens "
                                                           "(default: the one farther from burn 1)")
    split: Literal["optimal"] | Annotated[float, Field(ge=0, le=1)] = Field(
        "optimal", description="fraction of the plane change done in burn 1, or 'optimal' (minimum total ΔV)")


class LowThrust(_Burn):
    """Electric spiral between circular orbits with a plane change (Edelbaum ΔV)."""

    type: Literal["low_thrust"]
    altitude: Length = Field(description="altitude of the final circular orbit")
    inclination: Angle | None = Field(None, description="final inclination (default: unchanged)")


class Phasing(_Burn):
    """Two burns through a phasing orbit to catch a target on the same orbit."""

    type: Literal["phasing"]
    phase_angle: Angle = Field(description="how far the target leads the chaser (negative: trails)")
    revolutions: int = Field(1, ge=1, description="revolutions on the phasing orbit")
    at: Apsis = Field("perigee", description="apsis of both burns")


class RaanDrift(_Step):
    """Wait for J2 to turn the node by delta_raan (absolute, or relative to a target orbit)."""

    type: Literal["raan_drift"]
    delta_raan: Angle = Field(description="node change to wait for (signed)")
    relative_to: OrbitSpec | None = Field(None, description="target orbit whose own node drift is subtracted")


class Allowance(_Burn):
    """A fixed ΔV: rendezvous (Chevallard 2019: 50 m/s each), station keeping, contingency."""

    type: Literal["rendezvous", "allowance"]
    dv: Velocity = Field(ge=0, description="ΔV allowance, e.g. \"50 m/s\"")


class Deorbit(_Burn):
    """Lower the perigee to a re-entry altitude with one burn at apogee."""

    type: Literal["deorbit"]
    perigee: Length = Field(description="target perigee altitude (Chevallard 2019: 50 km preliminary, 100 km IOS)")


class Graveyard(_Burn):
    """Two-burn raise to a circular disposal orbit."""

    type: Literal["graveyard"]
    altitude: Length | None = Field(None, description="altitude of the disposal orbit")
    raise_by: Length | None = Field(None, gt=0, description="instead: height above the current apogee (GEO: 235 km + 1000 Cr A/m)")

    @model_validator(mode="after")
    def _one(self) -> "Graveyard":
        if (self.altitude is None) == (self.raise_by is None):
            raise ValueError("give exactly one of altitude or raise_by")
        return self


class Aerobraking(_Step):
    """Drag lowers the apogee at constant perigee: no ΔV; duration given or TBD."""

    type: Literal["aerobraking"]
    apogee: Length = Field(description="apogee altitude at the end of aerobraking")
    duration: Time | Literal["TBD"] = Field("TBD", description="how long it takes, or TBD")


class Capture(_Step):
    """Dock with / capture a target: its mass joins the stack."""

    type: Literal["capture", "dock"]
    target: str = Field(description="target name (release it by this name)")
    mass: Mass = Field(gt=0, description="target mass")


class Release(_Step):
    """Release a captured target (default: the last one captured)."""

    type: Literal["release"]
    target: str | None = Field(None, description="target name")


class Refuel(_Step):
    """Take on propellant (e.g. from the launcher upper stage)."""

    type: Literal["refuel"]
    mass: Mass = Field(gt=0, description="propellant added")


Step = Annotated[
    Union[ApsisChange, Circularize, Hohmann, BiElliptic, PlaneChange, CombinedChange, LowThrust, Phasing,
          RaanDrift, Allowance, Deorbit, Graveyard, Aerobraking, Capture, Release, Refuel],
    Field(discriminator="type"),
]

#: Step types that carry ΔV (valid keys of dv margins, besides 'default').
BURN_TYPES = ("apsis_change", "circularize", "hohmann", "bielliptic", "plane_change", "combined", "low_thrust",
              "phasing", "rendezvous", "allowance", "deorbit", "graveyard")


class ScenarioSpec(StrictModel):
    """One named sequence of a trade-off (shares constants, propulsion and margins)."""

    name: str = Field(description="scenario name")
    description: str = Field("", description="free text")
    initial_orbit: OrbitSpec | None = Field(None, description="overrides budget.initial_orbit")
    spacecraft: SpacecraftSpec | None = Field(None, description="overrides budget.spacecraft")
    sequence: list[Step] = Field(min_length=1, description="the steps, in execution order")


class BudgetSpec(StrictModel):
    """ΔV, propellant and burn-time budget (``sms budget``): a sequence, or several scenarios."""

    constants: ConstantsSpec = Field(default_factory=ConstantsSpec)
    propulsion: dict[str, PropulsionSpec] = Field(min_length=1, description="propulsion systems by name")
    default_propulsion: str | None = Field(None, description="system of burns without 'propulsion' "
                                                             "(default: the only system)")
    spacecraft: SpacecraftSpec
    initial_orbit: OrbitSpec = Field(description="orbit at the start of the sequence (e.g. the launcher drop-off)")
    margins: MarginsSpec = Field(default_factory=MarginsSpec)
    sizing: SizingSpec = Field(default_factory=SizingSpec)
    sequence: list[Step] | None = Field(None, description="the steps, in execution order")
    scenarios: list[ScenarioSpec] | None = Field(
        None, description="instead of sequence: named sequences evaluated side by side (a trade-off)")

    @model_validator(mode="after")
    def _sequence_or_scenarios(self) -> "BudgetSpec":
        if (self.sequence is None) == (self.scenarios is None):
            raise ValueError("give either sequence (one scenario) or scenarios (a trade-off), not both or neither")
        return self
