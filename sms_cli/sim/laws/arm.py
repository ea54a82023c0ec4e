"""Manipulator joint control laws. Each returns joint torques/forces (N m or N), arm order, before
saturation. Errors e = q_d − q (rad or m), ė = q̇_d − q̇; gains are per joint (scalar or (n_m,)).
Continuous joints (``wrap``) take the error modulo 2π into (−π, π].

The torque of every law is computed by its kernel, ``sms_cli.sim.compiled.arm_laws.arm_torque`` (the
one implementation, which the compiled loop calls too): each class holds its law ``code``, its gains as
the kernel's parameter rows ``par`` and the continuous-joint mask ``wrap_mask``.
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


def _f64(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


_NO_MODEL = (np.zeros((0, 0)), np.zeros(0))


class _KernelArmLaw:
    """An arm law computed by ``arm_laws.arm_torque``: ``code``, parameter rows ``par`` (ARM_PAR_ROWS × n,
    filled by ``_params`` once the number of joints is known) and the model ``dyn`` (None: model-free)."""

    code = -1
    dyn = None

    def _params(self, n: int) -> np.ndarray:
        raise NotImplementedError

    def reset(self) -> None:
        pass

    def wrap_mask(self, n: int) -> np.ndarray:
        return np.zeros(n, dtype=np.bool_) if self.wrap is None else np.ascontiguousarray(self.wrap, dtype=np.bool_)

    def torque(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        from sms_cli.sim.compiled.arm_laws import arm_torque

        q = _f64(s.q_arm)
        n = q.size
        Ms, hs = self.dyn.terms(s) if self.dyn is not None else _NO_MODEL
        out = np.empty(n)
        if getattr(self, "_kernel_args", (None,))[0] != n:  # the parameter rows and mask, made once
            self._kernel_args = (n, self._params(n), self.wrap_mask(n))
        _, par, wrap = self._kernel_args
        arm_torque(self.code, par, wrap, _f64(ref.q), _f64(ref.qd), _f64(ref.qdd), q, _f64(s.qd_arm), _f64(Ms), _f64(hs),
                   out)
        return out

    def warm_calls(self, n: int) -> list:
        """The kernel calls of ``torque`` on throw-away data (``sms_cli.sim.compiled.warmup``), model terms included."""
        from sms_cli.sim.compiled.warmup import KernelCall

        z = np.zeros(n)
        calls = [KernelCall("sms_cli.sim.compiled.arm_laws:arm_torque",
                            (self.code, self._params(n), self.wrap_mask(n), z, z.copy(), z.copy(), z.copy(), z.copy(),
                             np.eye(n), z.copy(), np.empty(n)), cost=0.6)]
        if self.dyn is not None:
            calls.append(self.dyn.warm_call())
        return calls


def _rows(n: int, *rows) -> np.ndarray:
    """The kernel's parameter rows: each gain broadcast to the n joints."""
    from sms_cli.sim.compiled.arm_laws import ARM_PAR_ROWS

    par = np.zeros((ARM_PAR_ROWS, n))
    for i, r in enumerate(rows):
        par[i] = np.broadcast_to(np.asarray(r, dtype=float), (n,))
    return par


class JointPD(_KernelArmLaw):
    """Cascaded joint PD of Chevallard 2019 (§5.4, Fig. 5.4): a P position loop feeding a
    D rate loop, τ = K_D (K_P (q_d − q) + q̇_d − q̇) (the seed has q̇_d = 0; ``rate_feedforward``
    adds it). K_P (1/s), K_D (N m s/rad). On a joint of inertia I: I ë + K_D ė + K_D K_P e = 0,
    ω_n = √(K_D K_P / I), ζ = K_D / (2 √(K_D K_P I)).
    """

    def __init__(self, kp, kd, rate_feedforward: bool = True, wrap=None):
        self.kp, self.kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
        self.ff = 1.0 if rate_feedforward else 0.0
        self.wrap = _mask(wrap)
        self.code = 0  # arm_laws.JOINT_PD

    def _params(self, n: int) -> np.ndarray:
        return _rows(n, self.kp, self.kd, self.ff)


class JointSMC(_KernelArmLaw):
    """First-order joint SMC of Ruggiero 2020 ((4.1)–(4.4), (5.1)):

        σ = λ (q − q_d) + (q̇ − q̇_d),   τ = −k tanh(η σ)   (or −k sign(σ))

    Model-free and bounded by k. k (N m or N), λ (1/s), η (s/rad). With an inertia I and k/I larger
    than the bound of |λ ė + q̈_d|, σ reaches 0 and the error then decays as e^{−λ t}.
    """

    def __init__(self, k, lam, eta=1.0, smoothing: str = "tanh", wrap=None):
        self.k, self.lam, self.eta = (np.asarray(x, dtype=float) for x in (k, lam, eta))
        self.smoothing = check_smoothing(smoothing)
        self.wrap = _mask(wrap)
        self.code = 1  # arm_laws.JOINT_SMC

    def _params(self, n: int) -> np.ndarray:
        return _rows(n, self.k, self.lam, self.eta, float(self.smoothing == "sign"))

    def surface(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        e, ed = _errors(s, ref, self.wrap)
        return -(self.lam * e + ed)


class ComputedTorque(_KernelArmLaw):
    """Computed torque on the SystemModel: τ = M* (q̈_d + K_d ė + K_p e) + h*, with (M*, h*) the
    arm's joint-space dynamics under ``model`` (see ``plant_models.ArmDynamics``: free_floating,
    attitude_held, fixed_base). With an exact model the error obeys ë + K_d ė + K_p e = 0.
    K_p (1/s²), K_d (1/s).
    """

    def __init__(self, sm, kp, kd, model: str = "free_floating", wrap=None):
        self.dyn = ArmDynamics(sm, model)
        self.kp, self.kd = np.asarray(kp, dtype=float), np.asarray(kd, dtype=float)
        self.wrap = _mask(wrap)
        self.code = 2  # arm_laws.COMPUTED_TORQUE

    def _params(self, n: int) -> np.ndarray:
        return _rows(n, self.kp, self.kd)


class ComputedTorqueSMC(_KernelArmLaw):
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
        self.code = 3  # arm_laws.SMC_COMPUTED_TORQUE

    def _params(self, n: int) -> np.ndarray:
        return _rows(n, self.k1, self.k2, self.c, self.mu, self.lam, float(self.smoothing == "sign"))

    def surface(self, s: Sensed, ref: ArmRef) -> np.ndarray:
        e, ed = _errors(s, ref, self.wrap)
        return ed + self.lam * e
