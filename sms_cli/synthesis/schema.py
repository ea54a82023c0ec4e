"""The mission file's ``synthesis:`` section (read by ``sms synthesize``).

Units: rates in rad/s (``"0.5 Hz"`` works), angles in rad (``"60 deg"`` works), torques in
N m. Every bound is a *request*; the solver either meets it or ``sms synthesize`` fails with
exit code 3 naming the constraint group that cannot be met.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from sms_cli.mission.base import StrictModel
from sms_cli.mission.units import Angle, AngularRate, Dimensionless, Torque


class PoleRegionSpec(StrictModel):
    """An LMI region of the complex plane (Chilali–Gahinet): the intersection of the half
    plane Re s ≤ −decay_rate, the damping cone (every pole's damping ratio ≥ min_damping,
    i.e. |Im s| ≤ −Re s·tan(acos ζ_min)) and the disk |s| ≤ max_frequency. The disk bounds
    the gains."""

    decay_rate: AngularRate = Field(gt=0, description="α: every pole has Re s ≤ −α (1/s)")
    min_damping: Dimensionless = Field(0.0, ge=0, lt=1, description="ζ_min: damping ratio of every pole ≥ ζ_min")
    max_frequency: AngularRate = Field(gt=0, description="r: every pole has |s| ≤ r (rad/s); bounds the gains")

    @model_validator(mode="after")
    def _check(self):
        if self.decay_rate >= self.max_frequency:
            raise ValueError(
                f"decay_rate ({self.decay_rate:g} 1/s) must be below max_frequency ({self.max_frequency:g} rad/s): "
                "the region would be empty")
        return self


class InitialErrors(StrictModel):
    """Bounds on the initial errors that define the ellipsoids of the γ guarantee.

    Observer errors: the box |η_k| ≤ modal_displacement, |η̇_k| ≤ modal_rate,
    |ω0_i| ≤ base_rate is inscribed in the ellipsoid εᵀEε ≤ 1 (E = diag(1/(n·b_i²))).
    Tracking errors (optional, absent = z(0) = 0 as in Kraiem 2022): |ε_c,i| ≤ tracking,
    |ε̇_c,i| ≤ tracking_rate, same construction.
    """

    modal_displacement: Dimensionless = Field(0.05, gt=0, description="bound on |η| (sqrt(kg) m)")
    modal_rate: Dimensionless = Field(0.05, gt=0, description="bound on |η̇| (sqrt(kg) m/s)")
    base_rate: AngularRate = Field(0.01, gt=0, description="bound on the base-rate estimate error (rad/s)")
    tracking: Dimensionless | None = Field(None, gt=0, description="bound on |q_d − q| at t=0 (rad or m)")
    tracking_rate: Dimensionless | None = Field(None, gt=0, description="bound on |q̇_d − q̇| at t=0 (rad/s or m/s)")
    disturbance_torque: Torque = Field(
        0.01, gt=0, description="chapter 4 only: bound on the initial NDO error |τ_d − τ̂_d| per actuator (N m)")


class WorkspaceSampling(StrictModel):
    """Where the ρ relaxations are sampled: joint configurations drawn in a box around the
    nominal configuration (Kraiem 2022 Algorithm 2 samples the task's workspace)."""

    samples: int = Field(4, ge=0, le=5000, description="number of sampled configurations (0: nominal only)")
    spread: Angle = Field(0.5, ge=0, description="half-width of the box around each configuration (rad or m)")
    seed: int = Field(0, description="random seed of the sampling")
    configurations: list[dict[str, float]] = Field(
        default_factory=list,
        description="extra linearisation points: joint positions by name (each adds one LMI block)")


class LmiSpec(StrictModel):
    """Kraiem 2022 simultaneous controller + observer synthesis (Prop. 3.3.3.1 / 4.2.5)."""

    variant: Literal["ndi_observer", "ndi_observer_ndo"] = Field(
        "ndi_observer", description="chapter 3 (NDI + state observer) or chapter 4 (+ disturbance observer)")
    controller_region: PoleRegionSpec
    observer_region: PoleRegionSpec | None = Field(None, description="default: the controller region")
    relaxation: Literal["polytopic", "scaled", "thesis", "none"] = Field(
        "polytopic", description="robustness along the motion: 'polytopic' (every sampled configuration is one more "
                                 "linearisation sharing the same variables: the guarantee covers their convex hull), "
                                 "'scaled' (ρ multiplier form), 'thesis' ((3.52) as printed), 'none' (nominal only)")
    initial_errors: InitialErrors = Field(default_factory=InitialErrors)
    sampling: WorkspaceSampling = Field(default_factory=WorkspaceSampling)
    tracking_error_amplitude: Dimensionless = Field(
        0.05, gt=0, description="error the loop must absorb without exceeding the actuator torque (rad or m)")


class PdSpec(StrictModel):
    """Per-axis attitude PD from bandwidth and damping on the worst-case inertia."""

    bandwidth: AngularRate = Field(gt=0, description="natural frequency ω_n of each axis (rad/s)")
    damping: Dimensionless = Field(1.0, gt=0, description="damping ratio ζ")
    target_law: Literal["quaternion_pd", "wheels_free_floating", "inertia_shaping", "free_flying", "hierarchical",
                        "se3_pd"] = Field(
        "quaternion_pd", description="attitude law gains.yaml is written for: the per-axis K_p = I ω_n², K_d = 2ζω_n I "
        "mapped through Λ = J/I for the Vicariotto 2023 wheel laws (sms_cli/sim/laws/momentum.py; wheels along the base axes)")
    mu_threshold: AngularRate | None = Field(None, gt=0, description="target_law: hierarchical, its |μ| switch (rad/s)")

    @model_validator(mode="after")
    def _threshold(self):
        if (self.target_law == "hierarchical") != (self.mu_threshold is not None):
            raise ValueError("mu_threshold goes with target_law: hierarchical (and is needed by it)")
        return self


class LqrSpec(StrictModel):
    """Per-axis LQR on the worst-case double integrator: cost ∫(q_pos e² + q_vel ė² + r u²)."""

    q_position: Dimensionless = Field(1.0, gt=0)
    q_velocity: Dimensionless = Field(0.0, ge=0)
    r_effort: Dimensionless = Field(1.0, gt=0)


class SmcSpec(StrictModel):
    """Sliding-mode attitude gains (Caldera 2019 first-order tanh SMC; Ruggiero 2020 twisting conditions (4.6)),
    from a disturbance bound estimated from the arm motion over the sampled workspace."""

    surface_slope: AngularRate = Field(gt=0, description="λ of σ = λ e + ė (1/s)")
    kind: Literal["first_order", "twisting"] = Field(
        "first_order", description="first_order: Caldera 2019 tanh SMC (k, c, mu); twisting: Ruggiero 2020 (k1, k2, lambda)")
    margin: Dimensionless = Field(1.5, gt=1, description="safety factor over the disturbance bound")
    max_joint_acceleration: AngularRate = Field(
        0.01, gt=0, description="joint acceleration of the arm motion used to bound the disturbance (rad/s²)")
    max_joint_rate: AngularRate = Field(0.05, gt=0, description="joint rate of the arm motion (rad/s)")


class SynthesisSpec(StrictModel):
    """Gain synthesis: which law, and its requirements."""

    law: Literal["lmi", "pd", "lqr", "smc"] = Field(description="which synthesis to run")
    lmi: LmiSpec | None = None
    pd: PdSpec | None = None
    lqr: LqrSpec | None = None
    smc: SmcSpec | None = None
    max_torque: Torque | None = Field(
        None, gt=0, description="joint torque limit where the URDF has none (N m)")
    workspace: WorkspaceSampling = Field(
        default_factory=WorkspaceSampling,
        description="pd/lqr/smc: arm configurations over which the worst-case inertia and disturbance are taken")

    @model_validator(mode="after")
    def _check(self):
        if getattr(self, self.law) is None:
            raise ValueError(f"law '{self.law}' needs a '{self.law}:' block in the synthesis section")
        return self
