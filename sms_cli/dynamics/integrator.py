"""Fixed-step, Lie-group aware Runge–Kutta 4 (Runge–Kutta–Munthe-Kaas) for the SystemModel.

The configuration moves on the Pinocchio configuration manifold: ``q(t) = q0 ⊕ θ(t)``
(``pin.integrate``, right composition with body-frame velocities). RKMK integrates θ in the
tangent space with ``θ̇ = dexp⁻¹_{−θ}(v) = v + ½[θ, v] + 1/12 [θ, [θ, v]]`` (truncation
enough for order 4); only the free-flyer's se(3) part has a non-zero bracket (joints are
abelian). Velocities ``v`` (body frame) and modal states are plain vectors. A plain RK4
through ``pin.integrate`` drops the bracket terms and lets world-frame momentum drift at O(dt²).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import pinocchio as pin


@dataclass
class State:
    """Plant state: q (nq), v (nv), eta (n_modes), etadot (n_modes)."""

    q: np.ndarray
    v: np.ndarray
    eta: np.ndarray
    etadot: np.ndarray

    def copy(self) -> "State":
        return State(self.q.copy(), self.v.copy(), self.eta.copy(), self.etadot.copy())


# accel(q, v, eta, etadot) -> (vdot, etaddot)
Accel = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _dexpinv_neg(theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """dexp⁻¹_{−θ}(v) truncated after the second bracket, on the free-flyer block (first 6).

    The se(3) bracket of [ρ; φ] and [u; w] (linear first, Pinocchio order) is
    [φ×u + ρ×w ; φ×w]; written out in floats (this runs 3× per plant step)."""
    r0, r1, r2, p0, p1, p2 = theta[:6].tolist()  # Python floats: arithmetic on numpy scalars is ~5× slower
    u0, u1, u2, w0, w1, w2 = v[:6].tolist()
    # c1 = [θ, v]
    a0 = p1 * u2 - p2 * u1 + r1 * w2 - r2 * w1
    a1 = p2 * u0 - p0 * u2 + r2 * w0 - r0 * w2
    a2 = p0 * u1 - p1 * u0 + r0 * w1 - r1 * w0
    b0 = p1 * w2 - p2 * w1
    b1 = p2 * w0 - p0 * w2
    b2 = p0 * w1 - p1 * w0
    # c2 = [θ, c1]
    out = v.copy()
    out[0] = u0 + 0.5 * a0 + (p1 * a2 - p2 * a1 + r1 * b2 - r2 * b1) / 12.0
    out[1] = u1 + 0.5 * a1 + (p2 * a0 - p0 * a2 + r2 * b0 - r0 * b2) / 12.0
    out[2] = u2 + 0.5 * a2 + (p0 * a1 - p1 * a0 + r0 * b1 - r1 * b0) / 12.0
    out[3] = w0 + 0.5 * b0 + (p1 * b2 - p2 * b1) / 12.0
    out[4] = w1 + 0.5 * b1 + (p2 * b0 - p0 * b2) / 12.0
    out[5] = w2 + 0.5 * b2 + (p0 * b1 - p1 * b0) / 12.0
    return out


def rkmk4_step(model: pin.Model, state: State, dt: float, accel: Accel) -> State:
    """One RKMK4 step of size dt (s) with accelerations from ``accel`` (held inputs: ZOH)."""
    q0, v0, e0, ed0 = state.q, state.v, state.eta, state.etadot
    h = 0.5 * dt
    integrate = pin.integrate
    if e0.size == 0:  # rigid system: no modal arithmetic
        a1, _ = accel(q0, v0, e0, ed0)
        th = h * v0
        v2 = v0 + h * a1
        a2, _ = accel(integrate(model, q0, th), v2, e0, ed0)
        k2 = _dexpinv_neg(th, v2)
        th = h * k2
        v3 = v0 + h * a2
        a3, _ = accel(integrate(model, q0, th), v3, e0, ed0)
        k3 = _dexpinv_neg(th, v3)
        th = dt * k3
        v4 = v0 + dt * a3
        a4, _ = accel(integrate(model, q0, th), v4, e0, ed0)
        k4 = _dexpinv_neg(th, v4)
        theta = (dt / 6.0) * (v0 + 2.0 * (k2 + k3) + k4)
        return State(integrate(model, q0, theta), v0 + (dt / 6.0) * (a1 + 2.0 * (a2 + a3) + a4), e0, ed0)

    # with modes: stage arithmetic on the packed vector y = [v; η; η̇] (fewer small numpy operations)
    nv, ne = v0.size, e0.size
    iv, ie, ied = slice(0, nv), slice(nv, nv + ne), slice(nv + ne, nv + 2 * ne)
    y0 = np.concatenate([v0, e0, ed0])

    def slope(q, y):
        a, b = accel(q, y[iv], y[ie], y[ied])
        return np.concatenate([a, y[ied], b])

    d1 = slope(q0, y0)
    th = h * v0
    y2 = y0 + h * d1
    d2 = slope(integrate(model, q0, th), y2)
    k2 = _dexpinv_neg(th, y2[iv])
    th = h * k2
    y3 = y0 + h * d2
    d3 = slope(integrate(model, q0, th), y3)
    k3 = _dexpinv_neg(th, y3[iv])
    th = dt * k3
    y4 = y0 + dt * d3
    d4 = slope(integrate(model, q0, th), y4)
    k4 = _dexpinv_neg(th, y4[iv])
    c = dt / 6.0
    theta = c * (v0 + 2.0 * (k2 + k3) + k4)
    y1 = y0 + c * (d1 + 2.0 * (d2 + d3) + d4)
    return State(integrate(model, q0, theta), y1[iv], y1[ie], y1[ied])
