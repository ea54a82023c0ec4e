"""Manipulator joint control laws. Each returns joint torques/forces (N m or N), arm order, before
saturation. Errors e = q_d − q (rad or m), ė = q̇_d − q̇; gains are per joint (scalar or (n_m,)).
Continuous joints (``wrap``) take the error modulo 2π into (−π, π].
"""

from __future__ import annotations

import math

import numpy as np

from sms_cli.sim.laws.switching import check_smoothing
from sms_cli.sim.interfaces import ArmRef, Sensed
from sms_cli.sim.laws.plant_models import ArmDynamics


def _errors(s: Sensed, ref: ArmRef, wrap: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    e = np.asarray(ref.q, dtype=float) - np.asarray(s.q_arm, dtype=float)
    if wrap is not None and np.any(wrap):
        e = np.where(wrap, (e + math.pi) % (2.0 * math.pi) - math.pi, e)
    return e, np.asarray(ref.qd, dtype=float) - np.asarray(s.qd_arm, dtype=float)


def _mask(wrap) -> np.ndarray | None:
    return None if wrap is None else np.asarray(wrap, dtype=bool)


class JointPD:
    """Cascaded joint PD of Chevallard 2019 (§5.4, Fig. 5.4): a P position loop feeding a
    D rate loop, τ = K_D (K_P (q_d − q) + q̇_d − q̇) (the seed has q̇_d = 0; ``rate_feedforward``
    adds it). K_P (1/s), K_D (N m s/rad). On a joint of inertia I: I ë + K_D ė + K_D K_P e = 0,
    ω_n = √(K_D K_P / I), ζ = K_D / (2 √(K_D K_P I)).
    """

    def __init__(self, kp, kd, rate_feedforward: bool = True, wrap=None):
        self.kp, self.kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
        self.ff = 1.0 if rate_feedforward else 0.0
        self.wrap = _mask(wrap)

    def reset(self) -> None:
        pass

    def torque(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        e, _ = _errors(s, ref, self.wrap)
        qd_cmd = self.kp * e + self.ff * np.asarray(ref.qd, dtype=float)
        return self.kd * (qd_cmd - np.asarray(s.qd_arm, dtype=float))


class JointSMC:
    """First-order joint SMC of Ruggiero 2020 ((4.1)–(4.4), (5.1)):

        σ = λ (q − q_d) + (q̇ − q̇_d),   τ = −k tanh(η σ)   (or −k sign(σ))

    Model-free and bounded by k. k (N m or N), λ (1/s), η (s/rad). With an inertia I and k/I larger
    than the bound of |λ ė + q̈_d|, σ reaches 0 and the error then decays as e^{−λ t}.
    """

    def __init__(self, k, lam, eta=1.0, smoothing: str = "tanh", wrap=None):
        self.k, self.lam, self.eta = (np.asarray(x, dtype=float) for x in (k, lam, eta))
        self.smoothing = check_smoothing(smoothing)
        self.wrap = _mask(wrap)

    def reset(self) -> None:
        pass

    def surface(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        e, ed = _errors(s, ref, self.wrap)
        return -(self.lam * e + ed)

    def torque(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        sig = self.surface(s, ref)
        sw = np.tanh(self.eta * sig) if self.smoothing == "tanh" else np.sign(sig)
        return -self.k * sw


class ComputedTorque:
    """Computed torque on the SystemModel: τ = M* (q̈_d + K_d ė + K_p e) + h*, with (M*, h*) the
    arm's joint-space dynamics under ``model`` (see ``plant_models.ArmDynamics``: free_floating,
    attitude_held, fixed_base). With an exact model the error obeys ë + K_d ė + K_p e = 0.
    K_p (1/s²), K_d (1/s).
    """

    def __init__(self, sm, kp, kd, model: str = "free_floating", wrap=None):
        self.dyn = ArmDynamics(sm, model)
        self.kp, self.kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
        self.wrap = _mask(wrap)

    def reset(self) -> None:
        pass

    def torque(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        e, ed = _errors(s, ref, self.wrap)
        M, h = self.dyn.terms(s)
        return M @ (np.asarray(ref.qdd, dtype=float) + self.kd * ed + self.kp * e) + h


class ComputedTorqueSMC:
    """Joint SMC of Caldera 2019 ((4.13)–(4.15)) made self-consistent.

    The seed's law is computed torque with PD gains (k₁, k₂), designed critically damped
    (k₁² = 4 k₂, L578), plus a tanh robust term. Here the surface is s = ė + λ e with λ the slow
    root of λ² − k₁ λ + k₂ = 0 (real because k₁² ≥ 4 k₂ is required), and

        τ = M* (q̈_d + k₁ ė + k₂ e + c tanh(μ s)) + h*

    so that ë + k₁ ė + k₂ e = −c tanh(μ s), i.e. ṡ = −(k₁ − λ) s − c tanh(μ s): s → 0, then
    ė = −λ e (no overshoot). k₁ (1/s), k₂ (1/s²), c (rad/s², multiplies M*), μ (s/rad).
    """

    def __init__(self, sm, k1, k2, c, mu=1.0, model: str = "free_floating", smoothing: str = "tanh", wrap=None):
        self.dyn = ArmDynamics(sm, model)
        self.k1, self.k2, self.c, self.mu = (np.asarray(x, dtype=float) for x in (k1, k2, c, mu))
        disc = self.k1**2 - 4.0 * self.k2
        if np.any(disc < -1e-12 * np.maximum(self.k1**2, 1e-300)) or np.any(self.k1 <= 0) or np.any(self.k2 < 0):
            raise ValueError("k1 > 0, k2 ≥ 0 and k1² ≥ 4 k2 (critically damped or overdamped) are required")
        self.lam = 0.5 * (self.k1 - np.sqrt(np.maximum(disc, 0.0)))
        self.smoothing = check_smoothing(smoothing)
        self.wrap = _mask(wrap)

    def reset(self) -> None:
        pass

    def surface(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        e, ed = _errors(s, ref, self.wrap)
        return ed + self.lam * e

    def torque(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        e, ed = _errors(s, ref, self.wrap)
        sig = ed + self.lam * e
        sw = np.tanh(self.mu * sig) if self.smoothing == "tanh" else np.sign(sig)
        M, h = self.dyn.terms(s)
        return M @ (np.asarray(ref.qdd, dtype=float) + self.k1 * ed + self.k2 * e + self.c * sw) + h
