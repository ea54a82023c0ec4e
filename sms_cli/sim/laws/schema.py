"""Mission-file specs of the control laws (one per law, chosen by ``law:``) and their factories.

Attitude gains are a scalar (all axes) or three numbers (x, y, z base axes) and accept units
("0.5 N m/rad"); arm gains are a scalar (all joints) or one number per arm joint, SI.
``inertia`` of the model-based attitude laws: ``initial`` (the SystemModel's locked inertia at
the initial configuration, wheels free), ``online`` (recomputed at each control instant, with
its rate J̇), or a tensor [ixx, iyy, izz(, ixy, ixz, iyz)] (kg m², base frame, about the CoM).

Examples::

    attitude: {law: quaternion_pd, kp: 0.5, kd: 5.0, ki: 0}
    attitude: {law: mrp_feedback, K: 3.5, P: 30.0}
    attitude: {law: smc, k: 0.08, c: 0.008, mu: 10}
    attitude: {law: twisting_smc, k1: 0.05, k2: 0.02, lambda: 0.5}
    attitude: {law: backstepping, K1: 0.5, K2: 0.3}
    attitude: {law: wheels_free_floating, kp: 50, kd: 1e-3, inertia_shaping: false}
    attitude: {law: free_flying, kp: 50, kd_base: 400, kd_wheels: 1e-3, kp_position: 10, kd_position: 100}
    attitude: {law: hierarchical, kp: 50, kd_base: 400, kd_wheels: 1e-3, mu_threshold: 1e-4}
    attitude: {law: se3_pd, kp: 50, kd: 400, kp_position: 10, kd_position: 100}
    arm: {law: joint_pd, kp: 1.0, kd: 100}
    arm: {law: smc, k: 0.5, lambda: 0.2}
    arm: {law: computed_torque, kp: 0.04, kd: 0.4}
    arm: {law: smc_computed_torque, k1: 0.058, k2: 8.5e-4, c: 0.001}
    resolved_rate: {gain: 1.0, kd: 10}
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Union

from pydantic import BeforeValidator, Field, model_validator

from sms_cli.errors import InputError, Problem
from sms_cli.mission.base import InertiaTensor, StrictModel
from sms_cli.mission.units import Time, Torque, UnitError, to_si


def _quantity_or_list(dimension: str, what: str):
    def convert(v: Any):
        try:
            if isinstance(v, (list, tuple)):
                return [to_si(x, dimension) for x in v]
            return to_si(v, dimension)
        except UnitError as exc:
            raise ValueError(str(exc)) from None

    return Annotated[Union[float, list[float]], BeforeValidator(convert),
                     Field(description=f"{what}: one value or one per axis/joint ({dimension})")]


Stiffness = _quantity_or_list("rotational stiffness", "N m/rad")
Damping = _quantity_or_list("rotational damping", "N m s/rad")
Rate = _quantity_or_list("frequency", "1/s")
AngRate = _quantity_or_list("angular rate", "rad/s")
AngAccel = _quantity_or_list("angular acceleration", "rad/s²")
TorqueGain = _quantity_or_list("torque", "N m")
Plain = _quantity_or_list("dimensionless", "SI")
InertiaChoice = Union[Literal["initial", "online"], InertiaTensor]


# ---------------------------------------------------------------------------- attitude specs
class QuaternionPdSpec(StrictModel):
    """τ = −kp θ_e − kd δω − ki ∫θ_e (θ_e = 2 q_v, rad) [+ gyroscopic/reference feedforward]."""

    law: Literal["quaternion_pd"]
    kp: Stiffness
    kd: Damping
    ki: Plain = Field(0.0, description="integral gain (N m/(rad s))")
    integral_limit: float | None = Field(None, gt=0, description="clip of each ∫θ_e component (rad s); none: no clip")
    feedforward: bool = Field(False, description="add ω×(Jω+h) + J(ω̇_r − ω×ω_r)")
    inertia: InertiaChoice = "initial"


class MrpFeedbackSpec(StrictModel):
    """Basilisk's mrpFeedback: L_r = −Kσ − Pδω − P K_i z + v×(Iω + G_s h_s) − I(ω×ω_r − ω̇_r) − L."""

    law: Literal["mrp_feedback"]
    K: float = Field(gt=0, description="MRP gain (N m)")
    P: float = Field(gt=0, description="rate gain (N m s)")
    Ki: float = Field(-1.0, description="integral gain (1/s); ≤ 0 disables it (Basilisk default)")
    integral_limit: float | None = Field(None, gt=0, description="clip of each K∫σ component; none: no clip")
    control_law_type: Literal[0, 1] = Field(0, description="0: v = ω_r + K_i z; 1: v = ω")
    wheels: bool = Field(True, description="compensate the wheel momentum G_s h_s")
    known_torque: list[Torque] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)
    inertia: InertiaChoice = "initial"


class SmcAttitudeSpec(StrictModel):
    """Caldera 2019 first-order SMC, s = δω + k q_v, ṡ = −c tanh(μ s) (self-consistent signs)."""

    law: Literal["smc"]
    k: Rate
    c: AngAccel
    mu: Plain | None = Field(None, description="tanh slope μ (s/rad)")
    boundary: AngRate | None = Field(None, description="boundary-layer width 1/μ (rad/s), instead of mu")
    smoothing: Literal["tanh", "sign"] = "tanh"
    momentum: bool = Field(True, description="compensate ω × h (wheels, arm)")
    inertia: InertiaChoice = "initial"

    @model_validator(mode="after")
    def _mu(self):
        if (self.mu is None) == (self.boundary is None):
            raise ValueError("give exactly one of 'mu' (tanh slope, s/rad) and 'boundary' (1/mu, rad/s)")
        return self


class TwistingSpec(StrictModel):
    """Ruggiero 2020 twisting SMC, σ = λ q_v + δω, u = −k1 tanh(η σ) − k2 tanh(η σ̇)."""

    law: Literal["twisting_smc"]
    k1: TorqueGain
    k2: TorqueGain
    lam: Rate = Field(alias="lambda")
    eta: Plain = 1.0
    smoothing: Literal["tanh", "sign"] = "tanh"
    filter_time: Time = Field(0.0, ge=0, description="first-order filter on the numerical σ̇ (s)")


class BacksteppingSpec(StrictModel):
    """Ruggiero 2020 backstepping, ω_c = −K1 q_v + ω_r, V̇2 = −q_vᵀK1q_v − ω̃ᵀK2ω̃."""

    law: Literal["backstepping"]
    K1: Rate
    K2: Damping
    disturbance: Literal["gyroscopic", "none"] = "gyroscopic"
    inertia: InertiaChoice = "online"


class WheelsFreeFloatingSpec(StrictModel):
    """Vicariotto 2023 (4.13): wheels only at zero momentum, τ_w = Λᵀγ − K_dθ̇, γ = (skew(K_p R_e))^∨;
    ``inertia_shaping``: §4.2.2, τ_w = M_θ(ΛᵀM_θ)⁻¹(Λᵀγ − K_dθ̇) (sms_cli.sim.laws.momentum)."""

    law: Literal["wheels_free_floating"]
    kp: Stiffness = Field(description="K_p of the potential ½tr(K_p(1 − R_e)) (N m/rad), diagonal")
    kd: Damping = Field(description="K_d on the wheel rates θ̇ (N m s/rad): one value or one per wheel")
    inertia_shaping: bool = Field(False, description="§4.2.2: shaped rotor inertia ΛᵀM_θ (needs 3 wheels, A = I)")


class _TranslationPd(StrictModel):
    """The translation PD (3.7) of Vicariotto 2023 on the CoM, optional in the laws that command a force."""

    kp_position: Plain | None = Field(None, description="K_p of (3.7) on the CoM position error (N/m); none: no force")
    kd_position: Plain | None = Field(None, description="K_d of (3.7) on the CoM velocity (N s/m)")
    target_com: list[float] | None = Field(None, description="CoM target, world (m); none: the CoM at the first tick")

    @model_validator(mode="after")
    def _both(self):
        if (self.kp_position is None) != (self.kd_position is None):
            raise ValueError("kp_position and kd_position go together (the translation PD (3.7))")
        if self.target_com is not None and (len(self.target_com) != 3 or self.kp_position is None):
            raise ValueError("target_com: three numbers, with kp_position/kd_position")
        return self


class FreeFlyingSpec(_TranslationPd):
    """Vicariotto 2023 (4.15)/(4.16): thrusters τ_c = −γ − K_d^b μ + (Iμ)×(Λθ̇), wheels with the Coriolis
    coupling cancelled, translation PD (3.7) on the CoM rotated into the base frame (sms_cli.sim.laws.momentum)."""

    law: Literal["free_flying"]
    kp: Stiffness = Field(description="K_p of the attitude potential (N m/rad), diagonal")
    kd_base: Damping = Field(description="K_d^b on the locked velocity μ (N m s/rad)")
    kd_wheels: Damping = Field(description="K_d^w on the wheel rates θ̇ (N m s/rad): one value or one per wheel")
    inertia_shaping: bool = Field(True, description="rotor kinetic energy ½θ̇ᵀΛᵀM_θθ̇ (the thesis's) or ½θ̇ᵀM_θθ̇")


class Se3PdSpec(_TranslationPd):
    """Vicariotto 2023 (3.7)/(3.9), Bullo-Murray: τ_c = −γ − K_dω, f = Rᵀ(−K_pΔx − K_dċ); wheels idle."""

    law: Literal["se3_pd"]
    kp: Stiffness = Field(description="K_p of the attitude potential ½tr(K_p(1 − R_e)) (N m/rad), diagonal")
    kd: Damping = Field(description="K_d on the base rate ω (N m s/rad)")


class QuaternionLyapunovSpec(_TranslationPd):
    """Vicariotto 2023 §3.3.1: τ_c = −k q₀ q − K_dω (error quaternion (q₀, q)), W = ½ωᵀIω + k qᵀq; wheels idle."""

    law: Literal["quaternion_lyapunov"]
    k: float = Field(gt=0, description="k of the potential k qᵀq (N m), one number (the proof needs a scalar)")
    kd: Damping = Field(description="K_d on the base rate ω (N m s/rad)")


class HierarchicalSpec(StrictModel):
    """Vicariotto 2023 §4.2.4: thrusters detumble μ (L826) until |μ| ≤ mu_threshold, then the wheels' (4.18)."""

    law: Literal["hierarchical"]
    kp: Stiffness = Field(description="K_p^w of the attitude potential of task 2 (N m/rad), diagonal")
    kd_base: Damping = Field(description="K_d^b on μ in task 1 (N m s/rad)")
    kd_wheels: Damping = Field(description="K_d^w on θ̇ in task 2 (N m s/rad): one value or one per wheel")
    mu_threshold: float = Field(gt=0, description="|μ| (rad/s) below which task 2 starts (the thesis gives none)")
    inertia_shaping: bool = Field(True, description="task 2 with the shaped rotor inertia ΛᵀM_θ (4.18) or M_θ")


AttitudeLawSpec = Annotated[
    Union[QuaternionPdSpec, MrpFeedbackSpec, SmcAttitudeSpec, TwistingSpec, BacksteppingSpec,
          WheelsFreeFloatingSpec, FreeFlyingSpec, HierarchicalSpec, Se3PdSpec, QuaternionLyapunovSpec],
    Field(discriminator="law"),
]


# ---------------------------------------------------------------------------- arm specs
ArmModel = Literal["free_floating", "attitude_held", "fixed_base"]


class JointPdSpec(StrictModel):
    """Chevallard 2019 cascaded PD, τ = kd (kp (q_d − q) + q̇_d − q̇); kp (1/s), kd (N m s/rad)."""

    law: Literal["joint_pd"]
    kp: Plain
    kd: Plain
    rate_feedforward: bool = True


class ArmSmcSpec(StrictModel):
    """Ruggiero 2020 joint SMC, σ = λ(q − q_d) + (q̇ − q̇_d), τ = −k tanh(η σ); k (N m), λ (1/s)."""

    law: Literal["smc"]
    k: Plain
    lam: Plain = Field(alias="lambda")
    eta: Plain = 1.0
    smoothing: Literal["tanh", "sign"] = "tanh"


class ComputedTorqueSpec(StrictModel):
    """τ = M*(q̈_d + kd ė + kp e) + h*; kp (1/s²), kd (1/s)."""

    law: Literal["computed_torque"]
    kp: Plain
    kd: Plain
    model: ArmModel = "free_floating"


class SmcComputedTorqueSpec(StrictModel):
    """Caldera 2019 joint SMC, τ = M*(q̈_d + k1 ė + k2 e + c tanh(μ s)) + h*, s = ė + λ e, k1² ≥ 4 k2."""

    law: Literal["smc_computed_torque"]
    k1: Plain
    k2: Plain
    c: Plain = Field(0.0, description="robust gain (rad/s², multiplies M*)")
    mu: Plain = 1.0
    model: ArmModel = "free_floating"
    smoothing: Literal["tanh", "sign"] = "tanh"


ArmLawSpec = Annotated[
    Union[JointPdSpec, ArmSmcSpec, ComputedTorqueSpec, SmcComputedTorqueSpec],
    Field(discriminator="law"),
]


class ResolvedRateSpec(StrictModel):
    """Chevallard 2019 GJM resolved rate, q̇_d = J*⁺(ẋ_d + K e), τ = kd (q̇_d − q̇)."""

    gain: Rate = Field(description="K of the outer position loop (1/s)")
    orientation_gain: Rate | None = Field(None, description="K of the orientation loop (1/s); default: gain")
    kd: Plain = Field(description="rate-loop gain per joint (N m s/rad)")
    damping: float = Field(0.05, ge=0, description="maximum damped-least-squares λ (m/rad)")
    threshold: float = Field(0.05, ge=0, description="singular value below which damping starts (m/rad)")
    jacobian: Literal["generalized", "fixed_base"] = "generalized"
    max_rate: AngRate | None = Field(None, description="joint rate limits (rad/s); default: the URDF's")


# ---------------------------------------------------------------------------- factories
def _vec(value, n: int, field: str, what: str):
    """A scalar or a list of length n as a float array (InputError otherwise)."""
    import numpy as np

    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise InputError(problems=[Problem(f"expected one value or {n} values ({what}), got {a.size}", field=field,
                                           hint=f"write a single number or a list of {n}")])
    return a


def _limit(x: float | None) -> float:
    return math.inf if x is None else float(x)


def _body(spec, sm):
    from sms_cli.sim.laws.plant_models import RigidBody, SystemBody

    inertia = spec.inertia
    if isinstance(inertia, str):
        return SystemBody(sm, online=(inertia == "online"))
    import numpy as np

    from sms_cli.inertia import inertia_tensor

    J = inertia_tensor(*inertia)
    G = np.array([w.axis for w in sm.wheels]).T if sm.wheels else None
    Js = [w.spin_inertia for w in sm.wheels] if sm.wheels else None
    return RigidBody(J, G, Js)


def build_attitude_law(spec, sm):
    """An attitude law object (``torque(sensed, AttitudeRef) -> (3,)``) from its spec."""
    from sms_cli.sim.laws import attitude as A

    f = f"attitude.{spec.law}"
    v3 = lambda x, name, what: _vec(x, 3, f"{f}.{name}", what)  # noqa: E731
    if isinstance(spec, QuaternionPdSpec):
        return A.QuaternionPD(v3(spec.kp, "kp", "axes"), v3(spec.kd, "kd", "axes"), v3(spec.ki, "ki", "axes"),
                              _limit(spec.integral_limit), spec.feedforward, _body(spec, sm))
    if isinstance(spec, MrpFeedbackSpec):
        import numpy as np

        from sms_cli.sim.laws.plant_models import effective_inertia

        if spec.inertia == "online":
            raise InputError(problems=[Problem("mrp_feedback uses a constant inertia (as Basilisk's vehConfigInMsg)",
                                               field=f"{f}.inertia", hint="write 'initial' or a tensor")])
        J = effective_inertia(sm, sm.q0) if spec.inertia == "initial" else _body(spec, sm).J
        G = Js = None
        if spec.wheels and sm.wheels:
            G = np.array([w.axis for w in sm.wheels]).T
            Js = [w.spin_inertia for w in sm.wheels]
        return A.MrpFeedback(spec.K, spec.P, J, spec.Ki, _limit(spec.integral_limit), spec.control_law_type, G, Js,
                             spec.known_torque)
    if isinstance(spec, SmcAttitudeSpec):
        mu = v3(spec.mu, "mu", "axes") if spec.mu is not None else 1.0 / v3(spec.boundary, "boundary", "axes")
        return A.SlidingModeAttitude(v3(spec.k, "k", "axes"), v3(spec.c, "c", "axes"), mu, _body(spec, sm),
                                     spec.smoothing, spec.momentum)
    if isinstance(spec, TwistingSpec):
        k1, k2 = v3(spec.k1, "k1", "axes"), v3(spec.k2, "k2", "axes")
        if not (k1 > k2).all() or not (k2 > 0).all():
            raise InputError(problems=[Problem("the twisting law needs k1 > k2 > 0 on every axis", field=f"{f}.k1",
                                               hint="raise k1 or lower k2 (Ruggiero 2020 condition (4.6))")])
        return A.TwistingAttitude(k1, k2, v3(spec.lam, "lambda", "axes"), v3(spec.eta, "eta", "axes"),
                                  spec.smoothing, spec.filter_time)
    if isinstance(spec, BacksteppingSpec):
        return A.BacksteppingAttitude(v3(spec.K1, "K1", "axes"), v3(spec.K2, "K2", "axes"), _body(spec, sm),
                                      spec.disturbance)
    if isinstance(spec, (WheelsFreeFloatingSpec, FreeFlyingSpec, HierarchicalSpec, Se3PdSpec, QuaternionLyapunovSpec)):
        from sms_cli.sim.laws import momentum as L

        nw = len(sm.wheels)
        vw = lambda x, name: _vec(x, nw, f"{f}.{name}", "wheels")  # noqa: E731
        try:
            if isinstance(spec, WheelsFreeFloatingSpec):
                return L.WheelsFreeFloating(sm, v3(spec.kp, "kp", "axes"), vw(spec.kd, "kd"), spec.inertia_shaping)
            if isinstance(spec, FreeFlyingSpec):
                pos = spec.kp_position is not None
                return L.FreeFlying(sm, v3(spec.kp, "kp", "axes"), v3(spec.kd_base, "kd_base", "axes"),
                                    vw(spec.kd_wheels, "kd_wheels"), spec.inertia_shaping,
                                    v3(spec.kp_position, "kp_position", "axes") if pos else None,
                                    v3(spec.kd_position, "kd_position", "axes") if pos else None, spec.target_com)
            if isinstance(spec, (Se3PdSpec, QuaternionLyapunovSpec)):
                pos = spec.kp_position is not None
                law, stiffness = (L.Se3PD, v3(spec.kp, "kp", "axes")) if isinstance(spec, Se3PdSpec) else \
                    (L.QuaternionLyapunov, float(spec.k))
                return law(sm, stiffness, v3(spec.kd, "kd", "axes"),
                           v3(spec.kp_position, "kp_position", "axes") if pos else None,
                           v3(spec.kd_position, "kd_position", "axes") if pos else None, spec.target_com)
            return L.Hierarchical(sm, v3(spec.kp, "kp", "axes"), v3(spec.kd_base, "kd_base", "axes"),
                                  vw(spec.kd_wheels, "kd_wheels"), float(spec.mu_threshold), spec.inertia_shaping)
        except ValueError as exc:
            raise InputError(problems=[Problem(str(exc), field=f, hint="see sms_cli/sim/laws/momentum.py")]) from None
    raise InputError(f"unknown attitude law {getattr(spec, 'law', spec)!r}")


def build_arm_law(spec, sm):
    """An arm law object (``torque(sensed, ArmRef) -> (n_m,)``) from its spec."""
    from sms_cli.sim.laws import arm as M

    n = len(sm.arm)
    f = f"arm.{spec.law}"
    vn = lambda x, name: _vec(x, n, f"{f}.{name}", "joints")  # noqa: E731
    wrap = [a.kind == "continuous" for a in sm.arm]
    if isinstance(spec, JointPdSpec):
        return M.JointPD(vn(spec.kp, "kp"), vn(spec.kd, "kd"), spec.rate_feedforward, wrap)
    if isinstance(spec, ArmSmcSpec):
        return M.JointSMC(vn(spec.k, "k"), vn(spec.lam, "lambda"), vn(spec.eta, "eta"), spec.smoothing, wrap)
    if isinstance(spec, ComputedTorqueSpec):
        return M.ComputedTorque(sm, vn(spec.kp, "kp"), vn(spec.kd, "kd"), spec.model, wrap)
    if isinstance(spec, SmcComputedTorqueSpec):
        try:
            return M.ComputedTorqueSMC(sm, vn(spec.k1, "k1"), vn(spec.k2, "k2"), vn(spec.c, "c"), vn(spec.mu, "mu"),
                                       spec.model, spec.smoothing, wrap)
        except ValueError as exc:
            hint = "Caldera 2019 designs the arm critically damped: k2 = k1²/4"
            raise InputError(problems=[Problem(str(exc), field=f"{f}.k2", hint=hint)]) from None
    raise InputError(f"unknown arm law {getattr(spec, 'law', spec)!r}")


def build_resolved_rate(spec: ResolvedRateSpec, sm):
    """The end-effector resolved-rate law (``joint_rates``/``torque`` with an EndEffectorRef)."""
    from sms_cli.sim.laws.resolved_rate import ResolvedRate

    n = len(sm.arm)
    f = "resolved_rate"

    def v3(x, name):
        return _vec(x, 3, f"{f}.{name}", "x y z")

    if n == 0:
        raise InputError(problems=[Problem("end-effector tracking needs arm joints; the robot has none",
                                           field=f, hint="remove the resolved_rate section")])
    max_rate = _vec(spec.max_rate, n, f"{f}.max_rate", "joints") if spec.max_rate is not None else None
    return ResolvedRate(sm, v3(spec.gain, "gain"), _vec(spec.kd, n, f"{f}.kd", "joints"), spec.damping,
                        spec.threshold, spec.jacobian, max_rate,
                        v3(spec.orientation_gain, "orientation_gain") if spec.orientation_gain is not None else None)
