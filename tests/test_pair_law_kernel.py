"""The compiled relative law (sms_cli/sim/compiled/pair_law.py, called by sms_cli/formation/laws.py:RelativeLaw) and
the decomposition's wrench maps against an independent numpy implementation written out here (the code the kernels
replaced, kept only as this oracle: numpy products and solves, Pinocchio's log3 and the decomposition oracle of
test_pair_decomposition_kernels), on random states for every law, actuation and controlled-subsystem combination,
with and without clipped wheel torques: every output to 1e-12 relative. The shipped missions' comparison (the oracle
law patched in) is in test_pair_decomposition_kernels."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from sms_cli.formation import laws
from sms_cli.formation.decomposition import decompose
from sms_cli.sim.compiled.momentum_laws import trace_potential
from test_pair_decomposition_kernels import _old_coriolis, _spacecraft_inertia

I6 = np.eye(6)


# ---------------------------------------------------------------------- the oracle
def _old_pose_potential(g, g_des, kp_linear, kp_angular):
    R_d, R = g_des.rotation, g.rotation
    r = R_d.T @ (g.translation - g_des.translation)
    R_e = R_d.T @ R
    gamma = np.empty(3)
    phi = trace_potential(np.ascontiguousarray(kp_angular, float), np.ascontiguousarray(R), np.ascontiguousarray(R_d),
                          gamma)
    grad = np.concatenate([R_e.T @ (kp_linear * r), gamma])
    angle = float(np.linalg.norm(pin.log3(R_e)))
    return laws.PoseError(0.5 * float(r @ (kp_linear * r)) + float(phi), grad, r, angle)


def _old_to_bodies(dec, F_L, F_E):
    F = dec.S.T @ np.concatenate([F_L, F_E])
    return F[:6], F[6:]


def _old_to_locked_shape(dec, F1, F2):
    F_L = F1 + dec.Ad12_inv.T @ F2
    return F_L, F2 - dec.A_star.T @ F_L


def _old_shape_effort(dec, F_E, actuated):
    z = np.zeros(6)
    if actuated == "both":
        return -dec.Ad12_inv.T @ F_E, F_E.copy()
    if actuated == "master":
        return np.linalg.solve(dec.A_star.T, -F_E), z
    P = I6 - dec.Ad12_inv @ dec.A_star
    return z, np.linalg.solve(P.T, F_E)


def _linear(grad):
    return np.concatenate([grad[:3], np.zeros(3)])


def old_law_call(self, dec, b1, b2):
    """RelativeLaw.__call__ as it was before the kernel (numpy)."""
    V = dec.S @ np.concatenate([b1.xi, b2.xi])
    V_L, V_E = V[:6], V[6:]
    zero = np.zeros(6)
    eL = _old_pose_potential(b1.pose, self.g1_des, self.locked.kp_linear, self.locked.kp_angular) if self.locked.controlled else None
    g12 = b1.pose.actInv(b2.pose)
    eE = _old_pose_potential(g12, self.g12_des, self.shape.kp_linear, self.shape.kp_angular) if self.shape.controlled else None
    gL = eL.grad if eL else zero
    gE = eE.grad if eE else zero
    if self.hierarchical:
        gL_f, gE_f = _linear(gL), _linear(gE)
    else:
        gL_f, gE_f = gL, gE
    if self.free_flying or self.hierarchical:
        C = _old_coriolis(dec, b1.xi, b2.xi, b2.twist - dec.Ad12_inv @ b1.twist)
        C_LE, C_EL = C[:6, 6:], C[6:, :6]
        F_L = -gL_f - self.locked.kd * V_L + C_LE @ V_E if eL else zero.copy()
        F_E = -gE_f + dec.A_star.T @ gL_f - (self.shape.kd * V_E if eE else 0.0) + (C_EL @ V_L if eE else 0.0)
        if eL or self.actuation == "both":
            F1, F2 = _old_to_bodies(dec, F_L, F_E)
        else:
            F1, F2 = _old_shape_effort(dec, F_E, self.actuation)
            F_L, F_E = _old_to_locked_shape(dec, F1, F2)
    else:
        F_L, F_E, F1, F2 = zero, zero, zero, zero
    Ad_inv_T_gE = dec.Ad12_inv.T @ gE
    t1 = b1.connection.T @ (F1 + gL - Ad_inv_T_gE) - self.wheel_damping * b1.wheel_rates
    t2 = b2.connection.T @ (F2 + gE) - self.wheel_damping * b2.wheel_rates
    c1, c2 = np.clip(t1, -b1.wheel_limits, b1.wheel_limits), np.clip(t2, -b2.wheel_limits, b2.wheel_limits)
    saturated = bool(np.any(c1 != t1) or np.any(c2 != t2))
    T_L, T_E = float(0.5 * V_L @ dec.M_tot @ V_L), float(0.5 * V_E @ dec.M_E @ V_E)
    T_w = 0.5 * sum(float(b.wheel_rates @ b.wheel_inertia @ b.wheel_rates) for b in (b1, b2))
    W = T_L + T_E + T_w + (eL.U if eL else 0.0) + (eE.U if eE else 0.0)
    return laws.Command(F1, F2, c1, c2, F_L, F_E, eL, eE, W, saturated)


# ---------------------------------------------------------------------- cases
def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def _gains(rng, controlled):
    offset = pin.SE3(pin.exp3(rng.normal(size=3) * 0.5), rng.normal(size=3))
    return SimpleNamespace(controlled=controlled, kp_linear=rng.uniform(0.1, 5, 3), kp_angular=rng.uniform(0.1, 5, 3),
                           kd_linear=rng.uniform(1, 50, 3), kd_angular=rng.uniform(1, 50, 3),
                           setpoint_offset=SimpleNamespace(se3=lambda: offset))


def _body(rng, pose, n):
    Lam = rng.normal(size=(6, n)) * 0.1
    B = rng.normal(size=(n, n))
    return laws.BodyState(pose, rng.normal(size=6) * 0.1, rng.normal(size=6) * 0.1, rng.normal(size=n) * 50.0, Lam,
                          np.full(n, 1e12), B @ B.T + 0.05 * np.eye(n))


def _case(seed, relative_law, actuation, locked_on, shape_on):
    rng = np.random.default_rng(seed)
    spec = SimpleNamespace(relative_law=relative_law, locked=_gains(rng, locked_on), shape=_gains(rng, shape_on),
                           wheel_damping=rng.uniform(0, 0.1), actuation=actuation)
    g1 = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3) * 10)
    g2 = g1 * pin.SE3(pin.exp3(rng.normal(size=3)), rng.uniform(-20, 20, 3))
    g1_0 = g1 * pin.SE3(pin.exp3(rng.normal(size=3) * 0.2), rng.normal(size=3))
    law = laws.RelativeLaw(spec, g1_0, g1_0.actInv(g2) * pin.SE3(pin.exp3(rng.normal(size=3) * 0.2), rng.normal(size=3)))
    b1, b2 = _body(rng, g1, 3), _body(rng, g2, 4)
    dec = decompose(_spacecraft_inertia(rng), _spacecraft_inertia(rng), g1.actInv(g2))
    return law, dec, b1, b2


def _same(got, want):
    for f in ("F1", "F2", "F_L", "F_E", "tau_w1", "tau_w2"):
        assert _rel(getattr(got, f), getattr(want, f)) < 1e-12 or np.linalg.norm(getattr(want, f)) == np.linalg.norm(
            getattr(got, f)) == 0.0, f
    assert abs(got.lyapunov - want.lyapunov) <= 1e-12 * abs(want.lyapunov)
    assert got.saturated == want.saturated
    for f in ("locked_error", "shape_error"):
        a, b = getattr(got, f), getattr(want, f)
        assert (a is None) == (b is None), f
        if b is not None:
            assert abs(a.U - b.U) <= 1e-12 * abs(b.U) and abs(a.angle - b.angle) <= 1e-12 * max(b.angle, 1e-3)
            assert _rel(a.grad, b.grad) < 1e-12 and _rel(a.position, b.position) < 1e-12, f


COMBOS = [(law, act, lo, so) for law in ("free_flying", "hierarchical", "free_floating")
          for act in ("both", "master", "other") for lo, so in ((True, True), (False, True), (True, False), (False, False))]


@pytest.mark.parametrize("relative_law, actuation, locked_on, shape_on", COMBOS)
@pytest.mark.parametrize("seed", range(3))
def test_relative_law_matches_the_numpy_law(seed, relative_law, actuation, locked_on, shape_on):
    """Every Command field (wrenches, clipped wheel torques, W, saturation, pose errors) to 1e-12, unclipped (limits
    1e12 N m) and with every wheel clipped (limits 1e-6 N m)."""
    law, dec, b1, b2 = _case(seed, relative_law, actuation, locked_on, shape_on)
    want = old_law_call(law, dec, b1, b2)
    got = law(dec, b1, b2)
    assert not want.saturated
    _same(got, want)
    for b in (b1, b2):
        b.wheel_limits = np.full(b.wheel_rates.size, 1e-6)
    want = old_law_call(law, dec, b1, b2)
    assert want.saturated
    _same(law(dec, b1, b2), want)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("actuated", ["both", "master", "other"])
def test_wrench_maps_match_the_numpy_formulas(seed, actuated):
    """PairDecomposition.to_bodies, to_locked_shape and shape_effort (now pair_law kernels) against numpy."""
    law, dec, _, _ = _case(seed, "free_flying", actuated, True, True)
    rng = np.random.default_rng(50 + seed)
    F_L, F_E = rng.normal(size=6), rng.normal(size=6)
    for got, want in zip(dec.to_bodies(F_L, F_E), _old_to_bodies(dec, F_L, F_E)):
        assert _rel(got, want) < 1e-12
    for got, want in zip(dec.to_locked_shape(F_L, F_E), _old_to_locked_shape(dec, F_L, F_E)):
        assert _rel(got, want) < 1e-12
    for got, want in zip(dec.shape_effort(F_E, actuated), _old_shape_effort(dec, F_E, actuated)):
        assert _rel(got, want) < 1e-12 or np.linalg.norm(want) == np.linalg.norm(got) == 0.0
    with pytest.raises(ValueError):
        dec.shape_effort(F_E, "neither")


def test_an_unknown_actuation_is_refused_where_it_matters():
    """A spacecraft name the law does not know is an error only when the shape wrench must be redistributed."""
    law, dec, b1, b2 = _case(0, "free_flying", "nobody", False, True)
    with pytest.raises(ValueError):
        law(dec, b1, b2)
    law, dec, b1, b2 = _case(0, "free_flying", "nobody", True, True)
    _same(law(dec, b1, b2), old_law_call(law, dec, b1, b2))
