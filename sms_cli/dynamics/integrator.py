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
    """dexp⁻¹_{−θ}(v) truncated after the second bracket, on the free-flyer block (first 6)."""
    out = v.copy()
    t = pin.Motion(theta[:6])
    c1 = t.cross(pin.Motion(v[:6]))
    c2 = t.cross(c1)
    out[:6] = v[:6] + 0.5 * c1.vector + c2.vector / 12.0
    return out


def rkmk4_step(model: pin.Model, state: State, dt: float, accel: Accel) -> State:
    """One RKMK4 step of size dt (s) with accelerations from ``accel`` (held inputs: ZOH)."""
    q0, v0, e0, ed0 = state.q, state.v, state.eta, state.etadot
    a1, b1 = accel(q0, v0, e0, ed0)
    k1 = v0

    th = 0.5 * dt * k1
    v2, e2, ed2 = v0 + 0.5 * dt * a1, e0 + 0.5 * dt * ed0, ed0 + 0.5 * dt * b1
    a2, b2 = accel(pin.integrate(model, q0, th), v2, e2, ed2)
    k2 = _dexpinv_neg(th, v2)

    th = 0.5 * dt * k2
    v3, e3, ed3 = v0 + 0.5 * dt * a2, e0 + 0.5 * dt * ed2, ed0 + 0.5 * dt * b2
    a3, b3 = accel(pin.integrate(model, q0, th), v3, e3, ed3)
    k3 = _dexpinv_neg(th, v3)

    th = dt * k3
    v4, e4, ed4 = v0 + dt * a3, e0 + dt * ed3, ed0 + dt * b3
    a4, b4 = accel(pin.integrate(model, q0, th), v4, e4, ed4)
    k4 = _dexpinv_neg(th, v4)

    theta = dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return State(
        pin.integrate(model, q0, theta),
        v0 + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
        e0 + dt / 6.0 * (ed0 + 2.0 * ed2 + 2.0 * ed3 + ed4),
        ed0 + dt / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4),
    )
