"""Closed-form identities of the orbit/budget code: independent formulas must agree."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sms_cli.orbit import maneuvers as mv
from sms_cli.orbit.budget import PlannedStep, mass_chain, size_wet_mass
from sms_cli.orbit.constants import EARTH, TROPICAL_YEAR
from sms_cli.orbit.orbits import Orbit, OrbitError, j2_raan_rate, sun_synchronous_inclination, vis_viva
from sms_cli.orbit.propulsion import Propulsion, burn_duration_constant_thrust, delta_v, propellant_mass

MU = EARTH.mu
R = EARTH.radius
RADII = [R + 300e3, R + 1000e3, R + 20200e3, R + 35786e3, R + 384000e3]


@pytest.mark.parametrize("r1", RADII)
@pytest.mark.parametrize("r2", RADII)
def test_hohmann_equals_two_apsis_changes(r1, r2):
    """Eq. 2.3 closed form == apsis burn to r2 + circularisation at r2 (vis-viva)."""
    if r1 == r2:
        return
    dv1, dv2, tof = mv.hohmann_dv(r1, r2, MU)
    circ = Orbit(r1, r1)
    at1 = "perigee" if r2 > r1 else "apogee"
    b1 = mv.apsis_change(circ, at1, r2, MU)
    b2 = mv.circularize(b1.orbit, "apogee" if r2 > r1 else "perigee", MU)
    assert dv1 == pytest.approx(b1.dv, rel=1e-12)
    assert dv2 == pytest.approx(b2.dv, rel=1e-12)
    assert b2.orbit.rp == pytest.approx(r2) and b2.orbit.ra == pytest.approx(r2)
    assert tof == pytest.approx(0.5 * b1.orbit.period(MU), rel=1e-12)
    seq = mv.transfer_to_circular(circ, r2, MU)
    assert seq.dv == pytest.approx(dv1 + dv2, rel=1e-12)


def test_transfer_from_ellipse_equals_apsis_burns():
    o = Orbit(R + 250e3, R + 35786e3)
    res = mv.transfer_to_circular(o, R + 40000e3, MU)
    b1 = mv.apsis_change(o, "perigee", R + 40000e3, MU)
    b2 = mv.circularize(b1.orbit, "apogee", MU)
    assert res.dv == pytest.approx(b1.dv + b2.dv, rel=1e-12)
    with pytest.raises(OrbitError):
        mv.transfer_to_circular(o, R + 20000e3, MU)


def test_bielliptic_equals_three_apsis_changes():
    r1, r2, rb = 7000e3, 105000e3, 210000e3
    res = mv.bielliptic(Orbit(r1, r1), r2, rb, MU)
    a = mv.apsis_change(Orbit(r1, r1), "perigee", rb, MU)
    b = mv.apsis_change(a.orbit, "apogee", r2, MU)
    c = mv.circularize(b.orbit, "perigee", MU)
    assert res.dv == pytest.approx(a.dv + b.dv + c.dv, rel=1e-12)
    assert [x.dv for x in res.burns] == pytest.approx([a.dv, b.dv, c.dv], rel=1e-12)


def _rot_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues rotation matrix (independent of the code under test)."""
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


@pytest.mark.parametrize("di_deg", [0.0, 1.2, 28.5, 60.0, 91.3])
def test_combined_single_burn_is_law_of_cosines(di_deg):
    """GTO apogee → GEO in one burn (split = 1) == |v_after − v_before| of rotated velocity vectors."""
    gto = Orbit(R + 250e3, R + 35786e3, math.radians(28.5))
    r = gto.ra
    va, vc = gto.speed(r, MU), math.sqrt(MU / r)
    di = math.radians(di_deg)
    res = mv.combined_change(gto, r, r, gto.inc - di, MU, first_at="apogee", split=1.0)
    radial = np.array([1.0, 0.0, 0.0])  # burn point on the node line: the plane turns about the radius
    v_before = np.array([0.0, va, 0.0])
    v_after = _rot_about(radial, di) @ np.array([0.0, vc, 0.0])
    assert res.dv == pytest.approx(float(np.linalg.norm(v_after - v_before)), rel=1e-12, abs=1e-9)
    assert res.dv == pytest.approx(mv.combined_dv(va, vc, di), rel=1e-12, abs=1e-9)
    # pure plane change: same speed, 2 v sin(Δi/2) == vector difference
    pc = mv.plane_change(gto, "apogee", gto.inc - di, MU)
    assert pc.dv == pytest.approx(float(np.linalg.norm(_rot_about(radial, di) @ v_before - v_before)), abs=1e-9)


def test_optimal_split_beats_both_extremes_and_a_grid():
    """LEO 28.5° → GEO: the optimum splits the plane change (a few degrees at perigee)."""
    leo = Orbit(R + 300e3, R + 300e3, math.radians(28.5))
    geo = R + 35786e3
    opt = mv.combined_change(leo, geo, geo, 0.0, MU, first_at="perigee", split="optimal")
    all_first = mv.combined_change(leo, geo, geo, 0.0, MU, first_at="perigee", split=1.0)
    all_second = mv.combined_change(leo, geo, geo, 0.0, MU, first_at="perigee", split=0.0)
    assert opt.dv < all_first.dv and opt.dv < all_second.dv
    assert 0.0 < opt.info["split"] < 1.0
    assert 1.0 < opt.info["delta_i_first_deg"] < 4.0  # classic result: ~2 deg at perigee
    grid = min(mv.combined_change(leo, geo, geo, 0.0, MU, split=s).dv for s in np.linspace(0, 1, 2001))
    assert opt.dv <= grid + 1e-9
    assert opt.info["dv_all_plane_second"] == pytest.approx(all_second.dv)


@pytest.mark.parametrize("dv", [1.0, 50.0, 1500.0, 6000.0])
@pytest.mark.parametrize("ve", [225 * 9.81, 321 * 9.80665, 1938 * 9.81])
def test_tsiolkovsky_inverse(dv, ve):
    m0 = 1234.5
    mp = propellant_mass(m0, dv, ve)
    assert delta_v(m0, m0 - mp, ve) == pytest.approx(dv, rel=1e-10)  # m0 − mp cancels digits
    # linearized model is the first-order expansion: agrees to O((ΔV/ve)^2)
    x = dv / ve
    assert propellant_mass(m0, dv, ve, "linearized") - mp == pytest.approx(m0 * x * x / 2, rel=x + 1e-9)


def test_constant_thrust_duration_matches_integration():
    """t = m0(1−e^{−ΔV/ve})ve/F == time at which ∫F/m dt reaches ΔV with dm/dt = −F/ve."""
    from scipy.integrate import solve_ivp

    m0, F, ve, dv = 1000.0, 0.224, 1938 * 9.81, 1500.0

    def rhs(t, y):
        return [F / y[1], -F / ve]

    def reached(t, y):
        return y[0] - dv

    reached.terminal = True
    sol = solve_ivp(rhs, (0, 1e9), [0.0, m0], events=reached, rtol=1e-12, atol=1e-9)
    assert burn_duration_constant_thrust(m0, dv, ve, F) == pytest.approx(sol.t_events[0][0], rel=1e-8)
    p = Propulsion("x", "electric", 1938, F, 9.81)
    assert p.burn(m0, dv)[1] == pytest.approx(sol.t_events[0][0], rel=1e-8)


def _planned(items, prop):
    """Planned steps from (ΔV, event) pairs (allowance burns: no orbit needed)."""
    o = Orbit(R + 500e3, R + 500e3)
    out = []
    for i, (dv, event) in enumerate(items):
        res = mv.allowance(o, dv, "burn") if dv else mv.ManeuverResult(o)
        out.append(PlannedStep(i, f"s{i}", "allowance" if dv else "event", "p", prop if dv else None, res, 1.0, event))
    return out


def test_wet_mass_sizing_closes_analytic():
    """One burn, no target: m0 = m_dry / (R − margin (1 − R)), R = e^{−ΔV/ve}."""
    prop = Propulsion("c", "chemical", 321, 400, 9.80665)
    dv, dry, margin = 2500.0, 600.0, 0.3
    planned = _planned([(dv, None)], prop)
    m0 = size_wet_mass(planned, dry, margin, 1e7)
    ratio = math.exp(-dv / prop.ve)
    assert m0 == pytest.approx(dry / (ratio - margin * (1 - ratio)), rel=1e-10)
    chain = mass_chain(planned, m0, dry)
    mp = m0 - chain.final_mass
    assert chain.final_mass == pytest.approx(dry + margin * mp, rel=1e-10)  # eq. 3.2 holds with equality
    assert mass_chain(planned, m0 - 1.0, dry).closure(margin) < 0


def test_wet_mass_sizing_with_targets_and_refuel():
    prop = Propulsion("c", "chemical", 225, 80, 9.81)
    planned = _planned([(300.0, None), (0, ("capture", "T", 1000.0)), (200.0, None), (0, ("release", "T")),
                        (0, ("refuel", 150.0)), (900.0, None)], prop)
    dry, margin = 500.0, 0.1
    m0 = size_wet_mass(planned, dry, margin, 1e7)
    chain = mass_chain(planned, m0, dry)
    assert chain.closure(margin) == pytest.approx(0.0, abs=1e-6)
    assert all(leg.closure(margin) >= -1e-6 for leg in chain.legs)
    assert mass_chain(planned, m0 * (1 - 1e-6), dry).closure(margin) < 0
    # the mass bookkeeping: m0 + target + refuel − target − propellant = final
    consumed = sum(s.propellant for s in chain.steps)
    assert chain.final_mass == pytest.approx(m0 + 150.0 - consumed, rel=1e-12)


def test_phasing_identity():
    """After N phasing revolutions the target has moved 2πN − θ: both meet at the burn point."""
    o = Orbit(R + 6800e3 - 6378e3, R + 13600e3 - 6378e3)
    theta = math.radians(90)
    for n in (1, 3):
        res = mv.phasing(o, theta, n, "perigee", EARTH)
        t_total = res.coast
        target_travel = 2 * math.pi * t_total / o.period(MU)
        assert target_travel == pytest.approx(2 * math.pi * n - theta, rel=1e-12)
        assert res.burns[0].dv == res.burns[1].dv
    res1, res3 = mv.phasing(o, theta, 1, "perigee", EARTH), mv.phasing(o, theta, 3, "perigee", EARTH)
    assert res3.dv < res1.dv  # more revolutions, gentler phasing orbit


def test_sun_synchronous_rate_and_raan_wait():
    a = R + 800e3
    i = sun_synchronous_inclination(a, 0.0, EARTH)
    o = Orbit(a, a, i, raan=0.0)
    assert j2_raan_rate(o, EARTH) == pytest.approx(2 * math.pi / TROPICAL_YEAR, rel=1e-12)
    res = mv.raan_drift(o, math.radians(10), EARTH)
    assert res.coast == pytest.approx(math.radians(10) / (2 * math.pi / TROPICAL_YEAR), rel=1e-12)
    assert res.orbit.raan == pytest.approx(math.radians(10), rel=1e-9)


def test_edelbaum_limits():
    v0, v1 = 7.7e3, 3.07e3
    assert mv.edelbaum_dv(v0, v1, 0.0) == pytest.approx(v0 - v1)
    # same radius: ΔV = v sqrt(2 − 2 cos(π Δi/2)) = 2 v sin(π Δi/4)
    assert mv.edelbaum_dv(v0, v0, 0.3) == pytest.approx(2 * v0 * math.sin(math.pi * 0.3 / 4))


def test_apsis_change_keeps_burn_radius_and_energy():
    o = Orbit(R + 250e3, R + 35786e3)
    res = mv.apsis_change(o, "apogee", R + 488e3, MU)
    assert res.orbit.ra == o.ra and res.orbit.rp == pytest.approx(R + 488e3)
    assert res.dv == pytest.approx(vis_viva(o.ra, res.orbit.a, MU) - vis_viva(o.ra, o.a, MU))
    # lowering the opposite apsis below the burn point swaps the apsides
    res2 = mv.apsis_change(Orbit(R + 1000e3, R + 2000e3), "perigee", R + 500e3, MU)
    assert res2.orbit.ra == pytest.approx(R + 1000e3) and res2.orbit.rp == pytest.approx(R + 500e3)
