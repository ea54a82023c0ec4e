"""Evaluate a budget: plan the orbits of a step sequence, run the mass chain, size the wet mass.

Two passes. ``plan_sequence`` walks the steps once, turning each into burns (ΔV, with margins)
or a mass event, and the orbit after it; orbital ΔV does not depend on mass. ``mass_chain``
then applies the rocket equation burn by burn from a launch mass m0, adding captured targets,
removing released ones and adding refuelled propellant. Masses in kg, ΔV in m/s, time in s.

Closing rule (Chevallard 2019 eq. 3.1/3.2): between two refuels (a "leg"), the propellant left at the
end of the leg must cover ``margin`` × the propellant consumed in it. The chain is affine in m0,
so the closing value is a concave function of m0 and the smallest closing launch mass is its
root (``size_wet_mass``, scipy brentq).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from typing import Callable

from sms_cli.errors import InputError, Location, Problem
from sms_cli.orbit import maneuvers as mv
from sms_cli.orbit.constants import Constants
from sms_cli.orbit.orbits import Orbit, OrbitError, orbit_from_altitudes, orbit_from_elements
from sms_cli.orbit.propulsion import Propulsion
from sms_cli.orbit.schema import BURN_TYPES, BudgetSpec, OrbitSpec, SpacecraftSpec

Locator = Callable[[tuple], "Location | None"]


def _no_location(path: tuple) -> None:
    return None


def _dotted(path: tuple) -> str:
    return ".".join(str(p) for p in path)


def input_error(msg: str, path: tuple, locate: Locator, hint: str = "") -> InputError:
    return InputError(problems=[Problem(msg, locate(path), _dotted(path), hint)])


def _suggest(bad: str, options: list[str]) -> str:
    close = difflib.get_close_matches(bad, options, n=1, cutoff=0.5)
    return f"did you mean '{close[0]}'?" if close else "known: " + ", ".join(sorted(options))


# ------------------------------------------------------------------ inputs → model objects


def constants_of(spec: BudgetSpec) -> Constants:
    c = spec.constants
    return Constants(mu=c.mu, radius=c.earth_radius, g0=c.g0, j2=c.j2)


def build_orbit(o: OrbitSpec, constants: Constants, path: tuple, locate: Locator) -> Orbit:
    """Orbit from its mission-file spec; surface and ordering errors located at ``path``."""
    try:
        if o.semi_major_axis is not None:
            return orbit_from_elements(o.semi_major_axis, o.eccentricity, o.inclination, constants, o.raan, o.arg_perigee)
        return orbit_from_altitudes(o.perigee, o.apogee, o.inclination, constants, o.raan, o.arg_perigee)
    except OrbitError as exc:
        raise input_error(str(exc), path, locate) from None


def build_propulsion(spec: BudgetSpec, constants: Constants, locate: Locator) -> dict[str, Propulsion]:
    out = {}
    allowed = list(BURN_TYPES) + ["default"]
    for name, p in spec.propulsion.items():
        for key in p.dv_margins:
            if key not in allowed:
                raise input_error(f"unknown step type '{key}' in dv_margins", ("budget", "propulsion", name, "dv_margins", key),
                                  locate, _suggest(key, allowed))
        out[name] = Propulsion(name, p.kind, p.isp, p.thrust, constants.g0, p.propellant_model, p.duration_model,
                               dict(p.dv_margins))
    for key in spec.margins.dv:
        if key not in allowed:
            raise input_error(f"unknown step type '{key}' in margins.dv", ("budget", "margins", "dv", key), locate,
                              _suggest(key, allowed))
    if spec.default_propulsion is not None and spec.default_propulsion not in out:
        raise input_error(f"unknown propulsion system '{spec.default_propulsion}'", ("budget", "default_propulsion"),
                          locate, _suggest(spec.default_propulsion, list(out)))
    return out


# ------------------------------------------------------------------ planning


@dataclass
class PlannedStep:
    """One step after orbit planning: burns (ΔV before margin), factor, event, orbit after."""

    index: int
    name: str
    type: str
    phase: str
    propulsion: Propulsion | None
    result: mv.ManeuverResult
    dv_factor: float = 1.0
    event: tuple | None = None  # ("capture", target, mass) | ("release", target) | ("refuel", mass)

    @property
    def dv_impulsive(self) -> float:
        return self.result.dv

    @property
    def dv(self) -> float:
        return self.result.dv * self.dv_factor


def plan_sequence(steps: list, orbit0: Orbit, constants: Constants, propulsion: dict[str, Propulsion],
                  default_propulsion: str | None, margins_dv: dict, path: tuple, locate: Locator = _no_location) -> list[PlannedStep]:
    """Turn the mission-file steps into planned steps (orbits and ΔV); raises located InputErrors."""
    mu, R = constants.mu, constants.radius
    orbit = orbit0
    phase = "mission"
    attached: list[str] = []
    planned: list[PlannedStep] = []
    for i, s in enumerate(steps):
        here = path + (i,)
        phase = s.phase or phase
        name = s.name or s.type.replace("_", " ")
        prop = None
        if hasattr(s, "propulsion"):
            pname = s.propulsion or default_propulsion or (next(iter(propulsion)) if len(propulsion) == 1 else None)
            if pname is None:
                raise input_error("which propulsion system performs this burn?", here, locate,
                                  f"add 'propulsion: <{' | '.join(propulsion)}>' here or budget.default_propulsion")
            if pname not in propulsion:
                raise input_error(f"unknown propulsion system '{pname}'", here + ("propulsion",), locate,
                                  _suggest(pname, list(propulsion)))
            prop = propulsion[pname]
        event = None
        try:
            t = s.type
            if t == "apsis_change":
                res = mv.apsis_change(orbit, s.at, R + s.altitude, mu)
            elif t == "circularize":
                res = mv.circularize(orbit, s.at, mu)
            elif t == "hohmann":
                res = mv.transfer_to_circular(orbit, R + s.altitude, mu)
            elif t == "bielliptic":
                res = mv.bielliptic(orbit, R + s.altitude, R + s.intermediate_altitude, mu)
            elif t == "plane_change":
                inc = s.inclination if s.inclination is not None else orbit.inc + s.delta_inclination
                res = mv.plane_change(orbit, s.at, inc, mu, s.raan)
            elif t == "combined":
                if s.perigee > s.apogee:
                    raise OrbitError("target perigee altitude is above the target apogee altitude")
                res = mv.combined_change(orbit, R + s.perigee, R + s.apogee, s.inclination, mu, s.first_burn_at,
                                         s.second_burn_at, s.split)
            elif t == "low_thrust":
                res = mv.low_thrust_transfer(orbit, R + s.altitude, orbit.inc if s.inclination is None else s.inclination, mu)
            elif t == "phasing":
                res = mv.phasing(orbit, s.phase_angle, s.revolutions, s.at, constants)
            elif t == "raan_drift":
                rel = build_orbit(s.relative_to, constants, here + ("relative_to",), locate) if s.relative_to else None
                res = mv.raan_drift(orbit, s.delta_raan, constants, rel)
            elif t in ("rendezvous", "allowance"):
                res = mv.allowance(orbit, s.dv, t)
            elif t == "deorbit":
                res = mv.deorbit(orbit, R + s.perigee, mu)
            elif t == "graveyard":
                alt = s.altitude if s.altitude is not None else (orbit.ra - R) + s.raise_by
                res = mv.transfer_to_circular(orbit, R + alt, mu)
            elif t == "aerobraking":
                res = mv.aerobraking(orbit, R + s.apogee, None if s.duration == "TBD" else s.duration, constants)
            elif t in ("capture", "dock"):
                if s.target in attached:
                    raise OrbitError(f"target '{s.target}' is already attached")
                attached.append(s.target)
                res, event = mv.ManeuverResult(orbit), ("capture", s.target, s.mass)
            elif t == "release":
                if not attached:
                    raise OrbitError("nothing to release: no target is attached")
                target = s.target or attached[-1]
                if target not in attached:
                    raise input_error(f"target '{target}' is not attached", here + ("target",), locate,
                                      _suggest(target, attached))
                attached.remove(target)
                res, event = mv.ManeuverResult(orbit), ("release", target)
            elif t == "refuel":
                res, event = mv.ManeuverResult(orbit), ("refuel", s.mass)
            else:  # pragma: no cover - the schema's discriminated union forbids it
                raise OrbitError(f"unknown step type {t}")
        except OrbitError as exc:
            raise input_error(f"{name}: {exc}", here, locate) from None
        if res.orbit.rp < R:
            raise input_error(f"{name}: the orbit after this step dips {(R - res.orbit.rp) / 1e3:.1f} km below the "
                              f"surface", here, locate, "check the altitudes (they are above earth_radius)")
        factor = 1.0
        if prop is not None:
            factor = float(margins_dv.get(s.type, margins_dv.get("default", 1.0))) * prop.margin_for(s.type)
        planned.append(PlannedStep(i, name, s.type, phase, prop, res, factor, event))
        orbit = res.orbit
    return planned


# ------------------------------------------------------------------ mass chain


@dataclass
class StepMass:
    mass_before: float
    propellant: float
    burn_duration: float
    mass_after: float
    attached_after: float


@dataclass
class Leg:
    """Propellant consumed between two refuels and what was left at the end."""

    consumed: float = 0.0
    residual: float = 0.0

    def closure(self, margin: float) -> float:
        return self.residual - margin * self.consumed


@dataclass
class Chain:
    steps: list[StepMass] = field(default_factory=list)
    legs: list[Leg] = field(default_factory=list)
    final_mass: float = 0.0
    final_attached: float = 0.0

    def closure(self, margin: float) -> float:
        return min(leg.closure(margin) for leg in self.legs)


def mass_chain(planned: list[PlannedStep], m0: float, dry_mass: float) -> Chain:
    """Apply mass events and the rocket equation to every burn, starting at launch mass ``m0``."""
    m = m0
    attached: dict[str, float] = {}
    chain = Chain()
    leg = Leg()
    for p in planned:
        before = m
        mp_total = t_total = 0.0
        if p.event is not None:
            kind = p.event[0]
            if kind == "capture":
                attached[p.event[1]] = p.event[2]
                m += p.event[2]
            elif kind == "release":
                m -= attached.pop(p.event[1])
            elif kind == "refuel":
                leg.residual = m - dry_mass - sum(attached.values())
                chain.legs.append(leg)
                leg = Leg()
                m += p.event[1]
        for b in p.result.burns:
            dv = b.dv * p.dv_factor
            if dv == 0.0:
                continue
            mp, t = p.propulsion.burn(m, dv)
            m -= mp
            mp_total += mp
            t_total += t
        leg.consumed += mp_total
        chain.steps.append(StepMass(before, mp_total, t_total, m, sum(attached.values())))
    leg.residual = m - dry_mass - sum(attached.values())
    chain.legs.append(leg)
    chain.final_mass = m
    chain.final_attached = sum(attached.values())
    return chain


class BudgetDiverges(Exception):
    """No launch mass up to the limit closes the budget."""


def size_wet_mass(planned: list[PlannedStep], dry_mass: float, margin: float, max_mass: float) -> float:
    """Smallest launch mass m0 ≥ dry mass whose chain closes (every leg keeps its reserve)."""
    from scipy.optimize import brentq

    def g(m0: float) -> float:
        return mass_chain(planned, m0, dry_mass).closure(margin)

    lo = dry_mass
    if g(lo) >= 0:
        return lo
    hi = 2.0 * lo
    while g(hi) < 0:
        if hi >= max_mass:
            raise BudgetDiverges()
        lo, hi = hi, min(2.0 * hi, max_mass)
    return brentq(g, lo, hi, xtol=1e-9, rtol=1e-14, maxiter=500)


def divergence_message(planned: list[PlannedStep], margin: float, max_mass: float) -> str:
    """Why no launch mass closes: the overall mass ratio against the reserve rule."""
    keep = 1.0  # fraction of the mass left after all burns (per unit launch mass, no targets)
    dv_total = 0.0
    for p in planned:
        for b in p.result.burns:
            dv = b.dv * p.dv_factor
            dv_total += dv
            if p.propulsion is not None and dv > 0:
                if p.propulsion.propellant_model == "linearized":
                    keep *= max(1.0 - dv / p.propulsion.ve, 0.0)
                else:
                    keep *= math.exp(-dv / p.propulsion.ve)
    need = (1.0 + margin) * (1.0 - keep)
    msg = (f"the budget cannot close at any launch mass up to {max_mass / 1e3:g} t: the total ΔV of "
           f"{dv_total:.1f} m/s leaves {keep:.4g} of the launch mass")
    if need >= 1.0:
        msg += (f", and (1 + propellant margin) × propellant fraction = {need:.3f} ≥ 1: the ΔV exceeds what the "
                f"Isp allows")
    return msg


# ------------------------------------------------------------------ one scenario


def scenario_inputs(spec: BudgetSpec, k: int | None) -> tuple[list, OrbitSpec, SpacecraftSpec, tuple, tuple, str, str]:
    """(steps, initial orbit, spacecraft, steps path, orbit path, name, description) of scenario k (None = sequence)."""
    if k is None:
        return (spec.sequence, spec.initial_orbit, spec.spacecraft, ("budget", "sequence"), ("budget", "initial_orbit"),
                "mission", "")
    sc = spec.scenarios[k]
    base = ("budget", "scenarios", k)
    orbit_path = base + ("initial_orbit",) if sc.initial_orbit is not None else ("budget", "initial_orbit")
    return (sc.sequence, sc.initial_orbit or spec.initial_orbit, sc.spacecraft or spec.spacecraft,
            base + ("sequence",), orbit_path, sc.name, sc.description)


@dataclass
class ScenarioResult:
    name: str
    description: str
    constants: Constants
    orbit0: Orbit
    planned: list[PlannedStep]
    chain: Chain
    dry_mass: float
    wet_mass: float
    wet_mass_source: str
    required_wet_mass: float | None
    required_wet_mass_grid: float | None
    margin: float
    warnings: list[str]


def evaluate_scenario(spec: BudgetSpec, k: int | None, locate: Locator = _no_location) -> ScenarioResult:
    """Plan, size and run the mass chain of one scenario (k = None for ``budget.sequence``)."""
    constants = constants_of(spec)
    props = build_propulsion(spec, constants, locate)
    steps, orbit_spec, craft, steps_path, orbit_path, name, description = scenario_inputs(spec, k)
    orbit0 = build_orbit(orbit_spec, constants, orbit_path, locate)
    planned = plan_sequence(steps, orbit0, constants, props, spec.default_propulsion, spec.margins.dv, steps_path, locate)
    margin = spec.margins.propellant
    warnings = [f"{p.name}: {n}" for p in planned for n in p.result.notes]
    try:
        required = size_wet_mass(planned, craft.dry_mass, margin, spec.sizing.max_mass)
    except BudgetDiverges:
        required = None
        if craft.wet_mass is None:
            raise input_error(divergence_message(planned, margin, spec.sizing.max_mass), steps_path, locate,
                              "lower the ΔV, use a higher-Isp system, add a refuel step or reduce the margins") from None
        warnings.append(divergence_message(planned, margin, spec.sizing.max_mass))
    grid = spec.sizing.grid
    required_grid = None
    if required is not None:
        required_grid = math.ceil(required / grid - 1e-9) * grid if grid > 0 else required
    if craft.wet_mass is not None:
        wet, source = craft.wet_mass, "given"
    else:
        wet, source = required_grid, "sized"
    chain = mass_chain(planned, wet, craft.dry_mass)
    for p, sm in zip(planned, chain.steps):
        if p.propulsion is not None and p.propulsion.propellant_model == "linearized" and sm.mass_after <= 0:
            raise input_error(f"{p.name}: the linearized propellant model asks for more propellant than the whole "
                              f"spacecraft mass", steps_path + (p.index,), locate,
                              "use propellant_model: tsiolkovsky for large ΔV")
        impulsive = p.type not in ("allowance", "rendezvous")  # allowances are spread over many burns
        if impulsive and p.propulsion is not None and p.propulsion.kind == "chemical" and sm.burn_duration > 0:
            t_orbit = p.result.orbit.period(constants.mu)
            if sm.burn_duration > 0.1 * t_orbit:
                warnings.append(f"{p.name}: a {sm.burn_duration:.0f} s chemical burn is over 10 % of the orbital "
                                f"period: finite-burn losses exceed the impulsive model")
    return ScenarioResult(name, description, constants, orbit0, planned, chain, craft.dry_mass, wet, source,
                          required, required_grid, margin, warnings)
