"""Base attitude control laws. Each returns the torque to put on the base (N m, base frame).

Conventions (one place, used by every law here):
- quaternions [x, y, z, w], Hamilton product, q maps base → world (``Sensed.quat``, ``AttitudeRef.quat``);
- error quaternion q_e = q_R⁻¹ ⊗ q_B (base relative to the reference), sign chosen so w ≥ 0;
  its vector part q_v is ≈ θ/2 (θ = rotation vector, base frame) and C = R(q_e) maps base → reference;
- ``AttitudeRef.omega``/``omega_dot``: rate and acceleration of the reference frame, in the reference
  frame. In the base frame ω_r = Cᵀ ω_ref and its base-frame derivative is Cᵀ ω̇_ref − ω × ω_r;
- δω = ω − ω_r; kinematics q̇_v = ½ (q_w I + [q_v×]) δω.
Inertia J, its rate J̇ and the internal momentum h come from a body model (``plant_models``).
"""

from __future__ import annotations

import math

import numpy as np

from sms_cli.sim.laws.switching import check_smoothing
from sms_cli.sim.interfaces import AttitudeRef, Sensed
from sms_cli.sim.laws.plant_models import RigidBody


def _cross(a, b) -> np.ndarray:
    """a × b for 3-vectors (plain float arithmetic: several times faster than np.cross)."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _gain(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


_ZERO3 = np.zeros(3)


def _floats(x) -> list:
    """Python floats of a small vector (numpy scalar arithmetic is slow)."""
    return x.tolist() if isinstance(x, np.ndarray) else [float(v) for v in x]


class TrackingError:
    """Attitude tracking error of the base at a control instant (see module docstring)."""

    __slots__ = ("q", "omega_r", "domega_r", "dw", "qv", "qw")

    def __init__(self, s: Sensed, ref: AttitudeRef):
        from sms_cli.sim.compiled.control import error_quaternion

        self.q = np.empty(4)
        error_quaternion(np.asarray(s.quat, dtype=float), np.asarray(ref.quat, dtype=float), self.q)
        w = float(self.q[3])
        self.qv = self.q[:3]
        self.qw = w
        omega = np.asarray(s.omega, dtype=float)
        wr, dwr = np.asarray(ref.omega, dtype=float), np.asarray(ref.omega_dot, dtype=float)
        if any(_floats(wr)) or any(_floats(dwr)):
            from sms_cli.sim.compiled.profiles import reference_rates

            self.omega_r, self.domega_r = np.empty(3), np.empty(3)
            reference_rates(self.q, _f64(wr), _f64(dwr), self.omega_r, self.domega_r)  # Cᵀ ω_ref, Cᵀ ω̇_ref, C = R(q_e)
            self.dw = omega - self.omega_r
        else:
            self.omega_r = self.domega_r = _ZERO3
            self.dw = omega

    def qv_dot(self) -> np.ndarray:
        """q̇_v = ½ (q_w δω + q_v × δω)."""
        return 0.5 * (self.qw * self.dw + _cross(self.qv, self.dw))

    def mrp(self) -> np.ndarray:
        """Modified Rodrigues parameters σ_BR = q_v / (1 + q_w), |σ| ≤ 1 (shadow set)."""
        return self.qv / (1.0 + self.qw)

    def angle(self) -> float:
        """Eigen-axis error angle (rad)."""
        return 2.0 * math.atan2(float(np.linalg.norm(self.qv)), self.qw)


def _matrix(g: np.ndarray) -> np.ndarray:
    """A gain as the 3×3 matrix the kernels take: scalar → g I, per-axis (3,) → diag, 3×3 as is."""
    g = np.asarray(g, dtype=float)
    if g.ndim == 2:
        return g
    return np.diag(np.broadcast_to(g, (3,))).astype(float)


def _params(*parts) -> np.ndarray:
    """A law's flat parameter array (``sms_cli.sim.compiled.attitude_laws``): 3×3 gains row-major, then scalars."""
    return np.ascontiguousarray(np.concatenate([np.ravel(_matrix(p)) if isinstance(p, np.ndarray) else [float(p)]
                                                for p in parts]), dtype=float)


def _f64(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


_ZERO33 = np.zeros((3, 3))
_EYE3 = np.eye(3)


class _KernelLaw:
    """A law computed by its kernel in ``sms_cli.sim.compiled.attitude_laws`` (``kernel``, ``code``):
    parameters ``par``, state ``memory`` (zeroed by ``reset``) and the body model ``body`` (None: the
    law uses no body quantity). ``needs_body``: whether the torque uses J, J̇ and h this time."""

    kernel = ""
    code = -1
    memory_size = 1
    uses_inertia_rate = False
    body = None
    par: np.ndarray

    def reset(self) -> None:
        self.memory = np.zeros(self.memory_size)

    def needs_body(self) -> bool:
        return self.body is not None

    def _kernel(self):
        from sms_cli.sim.compiled import attitude_laws

        return getattr(attitude_laws, self.kernel)

    def torque(self, s: Sensed, ref: AttitudeRef) -> np.ndarray:
        e = TrackingError(s, ref)
        J, Jd, h = _EYE3, _ZERO33, _ZERO3
        if self.needs_body():
            b = self.body
            J = _f64(b.inertia(s))
            h = _f64(b.internal_momentum(s))
            if self.uses_inertia_rate:
                Jd = _f64(b.inertia_rate(s))
        out = np.empty(3)
        self._kernel()(e.q, _f64(s.omega), _f64(e.omega_r), _f64(e.domega_r), J, Jd, h, self.par, self.memory,
                       float(s.t), out)
        return out

    def warm_calls(self) -> list:
        """This law's kernel calls with the argument types of ``torque`` (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        from sms_cli.sim.laws.plant_models import SystemBody

        q, w = np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)
        ctl, att = "sms_cli.sim.compiled.control", "sms_cli.sim.compiled.attitude_laws"
        calls = [KernelCall(f"{ctl}:error_quaternion", (q, q.copy(), np.empty(4)), cost=0.2),
                 KernelCall(f"{att}:{self.kernel}", (q, w, w.copy(), w.copy(), np.eye(3), np.zeros((3, 3)), w.copy(),
                                                     self.par.copy(), np.zeros(self.memory_size), 0.0, np.empty(3)), cost=0.6)]
        b = self.body
        if hasattr(self, "surface"):
            calls.append(KernelCall(f"{att}:sliding_surface", (q, w, w.copy(), self.par.copy(), 0, np.empty(3)), cost=0.2))
        if hasattr(self, "lyapunov"):
            calls.append(KernelCall(f"{att}:backstepping_lyapunov", (q, w, w.copy(), np.eye(3), self.par.copy()), cost=0.2))
        if not self.needs_body():
            pass
        elif isinstance(b, SystemBody):  # the body model's h (plant_models)
            calls.append(KernelCall(f"{att}:system_momentum", (q, w, np.eye(3), w.copy(), np.empty(3)), cost=0.2))
        elif isinstance(b, RigidBody) and b.Js.size:
            calls.append(KernelCall(f"{att}:wheel_momentum", (b.G, b.Js, w, np.zeros(b.Js.size), np.empty(3)), cost=0.2))
        return calls


class QuaternionPD(_KernelLaw):
    """τ = −k_p θ_e − k_d δω − k_i ∫θ_e dt [+ ω×(Jω + h) + J(ω̇_r − ω×ω_r)].

    θ_e = 2 q_v (rad; the rotation vector for small errors), so on a rigid axis of inertia I the
    small-angle loop is I θ̈ + k_d θ̇ + k_p θ = 0: ω_n = √(k_p/I), ζ = k_d/(2√(k_p I)).
    k_p in N m/rad, k_d in N m s/rad, k_i in N m/(rad s); scalar, per-axis (3,) or 3×3.
    ``integral_limit`` (rad s) clips each component of ∫θ_e. ``feedforward`` needs a body model.
    The integral advances by θ_e × (time since the previous call; 0 on the first).
    Computed by ``sms_cli.sim.compiled.attitude_laws.quaternion_pd``.
    """

    kernel, memory_size = "quaternion_pd", 5

    def __init__(self, kp, kd, ki=0.0, integral_limit: float = math.inf, feedforward: bool = False, body=None):
        from sms_cli.sim.compiled.attitude_laws import QUATERNION_PD

        self.code = QUATERNION_PD
        self.kp, self.kd, self.ki = _gain(kp), _gain(kd), _gain(ki)
        self.integral_limit = float(integral_limit)
        self.feedforward = feedforward
        if feedforward and body is None:
            raise ValueError("QuaternionPD: feedforward needs a body model (inertia)")
        self.body = body
        self.par = _params(self.kp, self.kd, self.ki, self.integral_limit, float(feedforward))
        self.reset()

    def needs_body(self) -> bool:
        return self.feedforward

    @property
    def integral(self) -> np.ndarray:
        """∫θ_e dt (rad s), as clipped."""
        return self.memory[2:5]


class MrpFeedback:
    """Basilisk's ``mrpFeedback`` (AVSLab/basilisk, src/fswAlgorithms/attControl/mrpFeedback), same
    formula, inputs and quirks, so that its torque histories can be compared one to one:

        L_r = −K σ − P δω − P K_i z + (v × (I ω + G_s h_s)) − I (ω × ω_r − ω̇_r) − L
        h_s,i = J_s,i (ĝ_s,iᵀ ω + Ω_i),   v = ω_r + K_i z (control_law_type 0) or ω (type 1)
        z = K ∫σ dt + I δω  (only when K_i > 0; each component of K∫σ clipped to integral_limit)

    σ = σ_B/R (MRP, |σ| ≤ 1), δω = ω_B/R in B, ω_r = ω_R/N in B, L = known external torque; the
    result is the net torque on the spacecraft (Basilisk's ``torqueRequestBody``), which the wheels
    produce with G_s u_s = −L_r. K (N m), P (N m s), K_i (1/s; ≤ 0 disables the integral).
    The integration step is the time since the previous call, zero on the first call and, as in
    Basilisk, also zero on the call after one made at t = 0 (``priorTime == 0`` sentinel).
    """

    def __init__(self, K: float, P: float, inertia, Ki: float = -1.0, integral_limit: float = math.inf,
                 control_law_type: int = 0, wheel_axes=None, wheel_spin=None, known_torque=(0.0, 0.0, 0.0)):
        self.K, self.P, self.Ki = float(K), float(P), float(Ki)
        self.integral_limit = float(integral_limit)
        if control_law_type not in (0, 1):
            raise ValueError("control_law_type is 0 (normal) or 1 (simple integral)")
        self.law_type = control_law_type
        self.body = RigidBody(inertia, wheel_axes, wheel_spin)
        self.L = np.asarray(known_torque, dtype=float)
        self.reset()

    code = 0  # attitude_laws.MRP_FEEDBACK

    @property
    def par(self) -> np.ndarray:
        """[K, P, Ki, integral_limit, control_law_type, L (3)]: the compiled loop's parameters
        (``attitude_laws.attitude_law``)."""
        return np.array([self.K, self.P, self.Ki, self.integral_limit, float(self.law_type), *self.L], dtype=float)

    def warm_calls(self) -> list:
        """This law's kernel calls with the argument types of ``torque`` (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        q, w, b = np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), self.body
        ctl = "sms_cli.sim.compiled.control"
        return [KernelCall(f"{ctl}:error_quaternion", (q, q.copy(), np.empty(4)), cost=0.2),
                KernelCall(f"{ctl}:mrp_feedback", (q, w, w.copy(), w.copy(), np.zeros(b.Js.size), b.J, b.G, b.Js, self.K,
                                                   self.P, self.Ki, self.integral_limit, self.law_type, self.L,
                                                   np.zeros(4), 0.0, np.empty(3)), cost=0.9)]

    def reset(self) -> None:
        self.memory = np.zeros(4)  # [prior_time, K∫σ dt (3)], as the compiled law keeps it

    @property
    def prior_time(self) -> float:
        return float(self.memory[0])

    def torque(self, s: Sensed, ref: AttitudeRef) -> np.ndarray:
        from sms_cli.sim.compiled.control import mrp_feedback

        e = TrackingError(s, ref)
        out = np.empty(3)
        b = self.body
        mrp_feedback(e.q, np.asarray(s.omega, dtype=float), np.asarray(e.omega_r, dtype=float),
                     np.asarray(e.domega_r, dtype=float), np.asarray(s.wheel_speed, dtype=float), b.J, b.G, b.Js,
                     self.K, self.P, self.Ki, self.integral_limit, self.law_type, self.L, self.memory, float(s.t), out)
        return out


class SlidingModeAttitude(_KernelLaw):
    """First-order SMC of Caldera 2019 ((3.9)–(3.17)) with self-consistent signs.

    Surface s = δω + k q_v (the seed's s_s = ω_e + k q_e with q_e = q⁻¹ ∘ q_r, ω_e = ω_r − ω is
    exactly −s). Law, from ṡ = −c tanh(μ s) on J ω̇ = τ − ω×(Jω + h):

        τ = ω × (J ω + h) + J (ω̇_r − ω × ω_r − k q̇_v − c tanh(μ s))

    (the printed (3.16)–(3.17) have the opposite signs on the k and c terms and diverge). With an
    exact model each component obeys sinh(μ s(t)) = sinh(μ s(0)) e^{−c μ t}; on s = 0 the error
    obeys q̇_v = −½ k q_w q_v (rate ≈ k/2 for small errors).
    k (1/s), c (rad/s², multiplies J), μ (s/rad); ``smoothing='sign'`` gives the ideal law.
    ``momentum=False`` leaves h out (the seed's ω × I_s ω only).
    Computed by ``sms_cli.sim.compiled.attitude_laws.smc``.
    """

    kernel = "smc"

    def __init__(self, k, c, mu, body, smoothing: str = "tanh", momentum: bool = True):
        from sms_cli.sim.compiled.attitude_laws import SMC

        self.code = SMC
        self.k, self.c, self.mu = _gain(k), _gain(c), _gain(mu)
        self.smoothing = check_smoothing(smoothing)
        self.body = body
        self.momentum = momentum
        self.par = _params(self.k, self.c, self.mu, float(smoothing == "sign"), float(momentum))
        self.reset()

    def surface(self, s: Sensed, ref: AttitudeRef) -> np.ndarray:
        from sms_cli.sim.compiled.attitude_laws import SMC_K, sliding_surface

        e = TrackingError(s, ref)
        out = np.empty(3)
        sliding_surface(e.q, _f64(s.omega), _f64(e.omega_r), self.par, SMC_K, out)
        return out


class TwistingAttitude(_KernelLaw):
    """Twisting SMC of Ruggiero 2020 ((4.5)–(4.8), L538, (5.2)):

        σ = λ q_v + δω,   u = −k₁ tanh(η σ) − k₂ tanh(η σ̇)   (or sign)

    σ̇ is differentiated numerically as in the thesis: backward difference between control calls
    (0 on the first call), optionally through a first-order filter of time constant
    ``filter_time`` (s). |u_i| ≤ k₁ᵢ + k₂ᵢ always. k₁, k₂ (N m), λ (1/s), η (dimensionless).
    For σ̇ = a + J⁻¹u with |a| ≤ A, each σ_i reaches 0 within |σ_i(0)| / ((k₁−k₂)/J_ii − A)
    (ideal sign law, k₁ > k₂). Computed by ``sms_cli.sim.compiled.attitude_laws.twisting_smc``.
    """

    kernel, memory_size = "twisting_smc", 8

    def __init__(self, k1, k2, lam, eta=1.0, smoothing: str = "tanh", filter_time: float = 0.0):
        from sms_cli.sim.compiled.attitude_laws import TWISTING_SMC

        self.code = TWISTING_SMC
        self.k1, self.k2, self.lam, self.eta = _gain(k1), _gain(k2), _gain(lam), _gain(eta)
        self.smoothing = check_smoothing(smoothing)
        self.filter_time = float(filter_time)
        self.par = _params(self.k1, self.k2, self.lam, self.eta, float(smoothing == "sign"), self.filter_time)
        self.reset()

    @property
    def prev_sigma(self) -> np.ndarray | None:
        """σ at the previous call (None before the first)."""
        return self.memory[2:5] if self.memory[0] else None

    @property
    def sigma_dot(self) -> np.ndarray:
        """The (filtered) numerical σ̇ of the last call."""
        return self.memory[5:8]

    def surface(self, s: Sensed, ref: AttitudeRef) -> np.ndarray:
        from sms_cli.sim.compiled.attitude_laws import TW_LAM, sliding_surface

        e = TrackingError(s, ref)
        out = np.empty(3)
        sliding_surface(e.q, _f64(s.omega), _f64(e.omega_r), self.par, TW_LAM, out)
        return out


class BacksteppingAttitude(_KernelLaw):
    """Backstepping of Ruggiero 2020 ((4.15)–(4.28)), with ω̃ = ω − ω_c:

        ω_c = −K₁ q_v + ω_r,   γ = (J ω_c) × ω_c − J ω̇_c − J̇ ω_c,
        u = −K₂ ω̃ − q_v − T̂_dis − γ + ω_c × (J ω̃) + ½ J̇ ω̃,

    ω̇_c = −K₁ q̇_v + ω̇_r − ω × ω_r analytically. On d(Jω)/dt = u + T_dis − ω×Jω with T̂_dis = T_dis,
    V₂ = q_vᵀq_v + (1 − q_w)² + ½ ω̃ᵀ J ω̃ has V̇₂ = −q_vᵀK₁q_v − ω̃ᵀK₂ω̃ (4.28).
    T̂_dis = −ω × h (``disturbance='gyroscopic'``, h from the body model) or 0 (``'none'``).
    K₁ (1/s), K₂ (N m s/rad); scalar, per-axis or 3×3 (symmetric positive definite).
    Computed by ``sms_cli.sim.compiled.attitude_laws.backstepping``.
    """

    kernel, uses_inertia_rate = "backstepping", True

    def __init__(self, K1, K2, body, disturbance: str = "gyroscopic"):
        from sms_cli.sim.compiled.attitude_laws import BACKSTEPPING

        self.code = BACKSTEPPING
        self.K1, self.K2 = _gain(K1), _gain(K2)
        if disturbance not in ("gyroscopic", "none"):
            raise ValueError("disturbance is 'gyroscopic' or 'none'")
        self.disturbance = disturbance
        self.body = body
        self.par = _params(self.K1, self.K2, float(disturbance == "gyroscopic"))
        self.reset()

    def lyapunov(self, s: Sensed, ref: AttitudeRef) -> float:
        """V₂ = q_vᵀq_v + (1 − q_w)² + ½ ω̃ᵀ J ω̃."""
        from sms_cli.sim.compiled.attitude_laws import backstepping_lyapunov

        e = TrackingError(s, ref)
        return float(backstepping_lyapunov(e.q, _f64(s.omega), _f64(e.omega_r), _f64(self.body.inertia(s)), self.par))
