"""Orbital manoeuvres: each takes an ``Orbit`` and returns the burns (ΔV, m/s) and the new orbit.

Impulsive burns happen at an apsis; a plane change assumes the node lies on the apse line
(Chevallard 2019, L305). Elliptic-to-elliptic transfers are coaxial. The electric low-thrust
transfer uses Edelbaum's ΔV (circular to circular, constant thrust, plane change spread
over the spiral). Radii and speeds are SI (m, m/s); angles in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from sms_cli.orbit.constants import Constants
from sms_cli.orbit.orbits import (
    Orbit,
    OrbitError,
    circular_speed,
    j2_raan_rate,
    period,
    semi_major_axis_for_period,
    vis_viva,
)


@dataclass
class Burn:
    """One impulse: ΔV (m/s, ≥ 0), where (radius in m, NaN for an allowance) and what it does."""

    dv: float
    radius: float
    label: str


@dataclass
class ManeuverResult:
    """Burns of a manoeuvre, the orbit after it and the coast/wait time it implies (s, None = TBD)."""

    orbit: Orbit
    burns: list[Burn] = field(default_factory=list)
    coast: float | None = 0.0
    notes: list[str] = field(default_factory=list)
    info: dict = field(default_factory=dict)

    @property
    def dv(self) -> float:
        return sum(b.dv for b in self.burns)


# ---------------------------------------------------------------- closed forms


def plane_change_dv(v: float, angle: float) -> float:
    """Pure plane change at speed ``v`` through ``angle``: 2 v sin(Δi/2)."""
    return 2.0 * v * math.sin(abs(angle) / 2.0)


def combined_dv(v1: float, v2: float, angle: float) -> float:
    """One burn that changes speed v1 → v2 and turns the plane by ``angle`` (law of cosines)."""
    return math.sqrt(max(v1 * v1 + v2 * v2 - 2.0 * v1 * v2 * math.cos(angle), 0.0))


def hohmann_dv(r1: float, r2: float, mu: float) -> tuple[float, float, float]:
    """Hohmann transfer between circular radii: (ΔV1, ΔV2, time of flight) (Chevallard 2019 eq. 2.3)."""
    s = r1 + r2
    dv1 = math.sqrt(mu / r1) * (math.sqrt(2.0 * r2 / s) - 1.0)
    dv2 = math.sqrt(mu / r2) * (1.0 - math.sqrt(2.0 * r1 / s))
    tof = math.pi * math.sqrt((s / 2.0) ** 3 / mu)
    return abs(dv1), abs(dv2), tof


def edelbaum_dv(v0: float, v1: float, delta_i: float) -> float:
    """Edelbaum low-thrust ΔV between circular orbits of speeds v0, v1 with a plane change Δi."""
    return math.sqrt(max(v0 * v0 - 2.0 * v0 * v1 * math.cos(math.pi / 2.0 * abs(delta_i)) + v1 * v1, 0.0))


def plane_angle(i1: float, i2: float, raan1: float | None = None, raan2: float | None = None) -> float:
    """Angle between two orbit planes (rad) from inclinations and, if both given, RAANs."""
    if raan1 is None or raan2 is None:
        return abs(i2 - i1)
    c = math.cos(i1) * math.cos(i2) + math.sin(i1) * math.sin(i2) * math.cos(raan2 - raan1)
    return math.acos(max(-1.0, min(1.0, c)))


# ---------------------------------------------------------------- manoeuvres


def _flip_argp(orbit: Orbit, burn_at_r: float, new: Orbit, was_perigee: bool) -> Orbit:
    """Argument of perigee turns by π when the burn point changes from perigee to apogee."""
    if orbit.argp is None:
        return new
    now_perigee = math.isclose(new.rp, burn_at_r, rel_tol=1e-12)
    if now_perigee != was_perigee and not new.is_circular():
        return replace(new, argp=(orbit.argp + math.pi) % (2.0 * math.pi))
    return new


def apsis_change(orbit: Orbit, at: str, r_new: float, mu: float) -> ManeuverResult:
    """Tangential burn at apsis ``at`` that moves the opposite apsis to radius ``r_new``."""
    r_b = orbit.apsis(at)
    v1 = orbit.speed(r_b, mu)
    new = orbit.with_apsides(r_b, r_new)
    v2 = vis_viva(r_b, new.a, mu)
    new = _flip_argp(orbit, r_b, new, at == "perigee")
    other = "apogee" if at == "perigee" else "perigee"
    verb = "raise" if r_new > orbit.opposite(at) else "lower"
    return ManeuverResult(new, [Burn(abs(v2 - v1), r_b, f"{verb} {other} (burn at {at})")])


def circularize(orbit: Orbit, at: str, mu: float) -> ManeuverResult:
    """Tangential burn at apsis ``at`` that makes the orbit circular at that radius."""
    res = apsis_change(orbit, at, orbit.apsis(at), mu)
    res.burns[0].label = f"circularise at {at}"
    return res


def transfer_to_circular(orbit: Orbit, r2: float, mu: float) -> ManeuverResult:
    """Two-burn coaxial transfer to the circular orbit of radius ``r2``.

    From a circular orbit this is the Hohmann transfer (closed form, eq. 2.3); from an
    ellipse the first burn is at the apsis away from ``r2`` (perigee to go up, apogee to go down).
    """
    if orbit.is_circular():
        r1 = orbit.ra
        dv1, dv2, tof = hohmann_dv(r1, r2, mu)
        new = orbit.with_apsides(r2, r2)
        return ManeuverResult(new, [Burn(dv1, r1, "enter transfer ellipse"), Burn(dv2, r2, "circularise")],
                              coast=tof, info={"transfer_time_s": tof})
    if r2 >= orbit.ra:
        first = apsis_change(orbit, "perigee", r2, mu)
    elif r2 <= orbit.rp:
        first = apsis_change(orbit, "apogee", r2, mu)
    else:
        raise OrbitError(f"target radius {r2 / 1e3:.1f} km lies between the perigee and apogee of the current "
                         f"orbit; circularise first or use apsis_change")
    at_r2 = "apogee" if r2 >= first.orbit.ra * (1 - 1e-12) else "perigee"
    second = circularize(first.orbit, at_r2, mu)
    tof = 0.5 * period(first.orbit.a, mu)
    return ManeuverResult(second.orbit, first.burns + second.burns, coast=tof, info={"transfer_time_s": tof})


def bielliptic(orbit: Orbit, r2: float, rb: float, mu: float) -> ManeuverResult:
    """Bi-elliptic transfer from a circular orbit to circular radius ``r2`` via apoapsis ``rb``."""
    if not orbit.is_circular():
        raise OrbitError("a bi-elliptic transfer starts from a circular orbit: circularise first")
    r1 = orbit.ra
    if rb < max(r1, r2):
        raise OrbitError(f"intermediate radius {rb / 1e3:.1f} km must be at least the larger of the initial "
                         f"and final radii ({max(r1, r2) / 1e3:.1f} km)")
    a1, a2 = 0.5 * (r1 + rb), 0.5 * (r2 + rb)
    dv1 = abs(vis_viva(r1, a1, mu) - circular_speed(r1, mu))
    dv2 = abs(vis_viva(rb, a2, mu) - vis_viva(rb, a1, mu))
    dv3 = abs(vis_viva(r2, a2, mu) - circular_speed(r2, mu))
    tof = math.pi * (math.sqrt(a1**3 / mu) + math.sqrt(a2**3 / mu))
    burns = [Burn(dv1, r1, "raise apoapsis to intermediate"), Burn(dv2, rb, "raise periapsis to target"),
             Burn(dv3, r2, "circularise at target")]
    return ManeuverResult(orbit.with_apsides(r2, r2), burns, coast=tof, info={"transfer_time_s": tof})


def plane_change(orbit: Orbit, at: str, inc_new: float, mu: float, raan_new: float | None = None) -> ManeuverResult:
    """Pure plane change at apsis ``at`` to inclination ``inc_new`` (and RAAN ``raan_new`` if given)."""
    if raan_new is not None and orbit.raan is None:
        raise OrbitError("a RAAN change needs the current RAAN: give raan in initial_orbit")
    r = orbit.apsis(at)
    v = orbit.speed(r, mu)
    angle = plane_angle(orbit.inc, inc_new, orbit.raan if raan_new is not None else None, raan_new)
    new = replace(orbit, inc=inc_new, raan=raan_new if raan_new is not None else orbit.raan)
    return ManeuverResult(new, [Burn(plane_change_dv(v, angle), r, f"turn plane {math.degrees(angle):.3f} deg at {at}")],
                          info={"plane_angle_deg": math.degrees(angle)})


def combined_change(orbit: Orbit, rp2: float, ra2: float, inc2: float, mu: float, first_at: str = "perigee",
                    second_at: str | None = None, split: float | str = "optimal") -> ManeuverResult:
    """Two-burn coaxial shape change with the plane change shared between both burns.

    Burn 1 at apsis ``first_at`` (radius r1) moves the opposite apsis to the target apsis
    ``second_at`` (radius r2; default the target apsis farther from r1). Burn 2 at r2 sets
    the last apsis. A fraction ``split`` of Δi is done in burn 1 and the rest in burn 2, each
    burn priced by the law of cosines; ``"optimal"`` minimises the total (scipy bounded search).
    """
    r1 = orbit.apsis(first_at)
    if second_at is None:
        r2 = ra2 if abs(ra2 - r1) >= abs(rp2 - r1) else rp2
    else:
        r2 = rp2 if second_at == "perigee" else ra2
    r3 = ra2 if r2 == rp2 else rp2
    di = abs(inc2 - orbit.inc)
    at1 = 0.5 * (r1 + r2)
    v1a, v1b = orbit.speed(r1, mu), vis_viva(r1, at1, mu)
    v2a, v2b = vis_viva(r2, at1, mu), vis_viva(r2, 0.5 * (r2 + r3), mu)

    def total(s: float) -> float:
        return combined_dv(v1a, v1b, s * di) + combined_dv(v2a, v2b, (1.0 - s) * di)

    if split == "optimal":
        from scipy.optimize import minimize_scalar

        res = minimize_scalar(total, bounds=(0.0, 1.0), method="bounded", options={"xatol": 1e-12})
        candidates = [(total(0.0), 0.0), (total(1.0), 1.0), (float(res.fun), float(res.x))]
        s = min(candidates)[1]
    else:
        s = float(split)
        if not 0.0 <= s <= 1.0:
            raise OrbitError(f"split {s} must be between 0 and 1 (fraction of the plane change in the first burn)")
    dv1, dv2 = combined_dv(v1a, v1b, s * di), combined_dv(v2a, v2b, (1.0 - s) * di)
    new = Orbit(min(r2, r3), max(r2, r3), inc2, orbit.raan, orbit.argp)
    burns = [Burn(dv1, r1, f"shape + {math.degrees(s * di):.3f} deg plane (burn at {first_at})"),
             Burn(dv2, r2, f"shape + {math.degrees((1 - s) * di):.3f} deg plane")]
    info = {"split": s, "delta_i_first_deg": math.degrees(s * di), "delta_i_second_deg": math.degrees((1 - s) * di),
            "dv_all_plane_first": total(1.0), "dv_all_plane_second": total(0.0)}
    return ManeuverResult(new, burns, coast=0.5 * period(at1, mu), info=info)


def low_thrust_transfer(orbit: Orbit, r2: float, inc2: float, mu: float) -> ManeuverResult:
    """Edelbaum low-thrust transfer between circular orbits (ΔV only; duration from the thruster)."""
    if not orbit.is_circular(1e-3):
        raise OrbitError("Edelbaum's low-thrust transfer is between circular orbits: circularise first")
    v0, v1 = circular_speed(orbit.a, mu), circular_speed(r2, mu)
    di = abs(inc2 - orbit.inc)
    notes = []
    if math.degrees(di) > 114.6:
        notes.append("Edelbaum's formula is derived for plane changes below 114.6 deg")
    dv = edelbaum_dv(v0, v1, di)
    return ManeuverResult(replace(orbit.with_apsides(r2, r2), inc=inc2),
                          [Burn(dv, float("nan"), f"Edelbaum spiral, {math.degrees(di):.3f} deg plane change")],
                          notes=notes)


def phasing(orbit: Orbit, phase_angle: float, revolutions: int, at: str, constants: Constants) -> ManeuverResult:
    """Two burns at apsis ``at`` through a phasing orbit flown ``revolutions`` times.

    ``phase_angle`` > 0: the target leads the chaser by that angle (measured as mean anomaly,
    i.e. a fraction of the period); the chaser takes a shorter phasing orbit.
    """
    mu = constants.mu
    if revolutions < 1:
        raise OrbitError("revolutions must be at least 1")
    t = orbit.period(mu)
    t_ph = t * (1.0 - phase_angle / (2.0 * math.pi * revolutions))
    if t_ph <= 0:
        raise OrbitError("phase angle too large for this number of revolutions: add revolutions")
    a_ph = semi_major_axis_for_period(t_ph, mu)
    r_b = orbit.apsis(at)
    r_other = 2.0 * a_ph - r_b
    if r_other < constants.radius:
        raise OrbitError(f"the phasing orbit would dip {(constants.radius - r_other) / 1e3:.0f} km below the surface: "
                         f"add revolutions")
    dv = abs(vis_viva(r_b, a_ph, mu) - orbit.speed(r_b, mu))
    notes = []
    if r_other < constants.radius + 150e3:
        notes.append(f"phasing orbit apsis at {(r_other - constants.radius) / 1e3:.0f} km altitude: drag")
    return ManeuverResult(orbit, [Burn(dv, r_b, "enter phasing orbit"), Burn(dv, r_b, "leave phasing orbit")],
                          coast=revolutions * t_ph, notes=notes,
                          info={"phasing_period_s": t_ph, "phasing_other_apsis_km": (r_other - constants.radius) / 1e3})


def raan_drift(orbit: Orbit, delta_raan: float, constants: Constants, relative_to: Orbit | None = None) -> ManeuverResult:
    """Wait until J2 turns the node by ``delta_raan`` (relative to ``relative_to``'s node if given)."""
    rate = j2_raan_rate(orbit, constants)
    rel = rate - (j2_raan_rate(relative_to, constants) if relative_to is not None else 0.0)
    if abs(rel) < 1e-15:
        raise OrbitError("no relative node drift between these orbits (same a, e, i): change altitude or inclination")
    two_pi = 2.0 * math.pi
    angle = (delta_raan % two_pi) if rel > 0 else ((-delta_raan) % two_pi)
    wait = angle / abs(rel)
    new = orbit if orbit.raan is None else replace(orbit, raan=(orbit.raan + rate * wait) % two_pi)
    info = {"raan_rate_deg_per_day": math.degrees(rate) * 86400.0,
            "relative_rate_deg_per_day": math.degrees(rel) * 86400.0, "wait_days": wait / 86400.0}
    return ManeuverResult(new, [], coast=wait, info=info)


def allowance(orbit: Orbit, dv: float, label: str) -> ManeuverResult:
    """A fixed ΔV allowance (rendezvous, station keeping): no orbit change."""
    if dv < 0:
        raise OrbitError("a ΔV allowance cannot be negative")
    return ManeuverResult(orbit, [Burn(dv, float("nan"), label)])


def deorbit(orbit: Orbit, r_perigee: float, mu: float) -> ManeuverResult:
    """Lower the perigee to ``r_perigee`` with one burn at apogee."""
    res = apsis_change(orbit, "apogee", r_perigee, mu)
    res.burns[0].label = "lower perigee (burn at apogee)"
    if r_perigee > orbit.rp:
        res.notes.append("deorbit raises the perigee: check the target perigee altitude")
    return res


def aerobraking(orbit: Orbit, ra_new: float, duration: float | None, constants: Constants) -> ManeuverResult:
    """Drag lowers the apogee to ``ra_new`` at constant perigee: no ΔV, duration given or TBD."""
    if not orbit.rp <= ra_new <= orbit.ra * (1 + 1e-12):
        raise OrbitError(f"aerobraking lowers the apogee: the new apogee must lie between the current perigee "
                         f"({(orbit.rp - constants.radius) / 1e3:.0f} km) and apogee "
                         f"({(orbit.ra - constants.radius) / 1e3:.0f} km) altitudes")
    hp = (orbit.rp - constants.radius) / 1e3
    notes = []
    if not 80.0 <= hp <= 200.0:
        notes.append(f"aerobraking with a perigee at {hp:.0f} km altitude: Chevallard 2019 assumes 100-150 km")
    return ManeuverResult(replace(orbit, ra=ra_new), [], coast=duration, notes=notes)
