"""Mission sections of a two-spacecraft study (Vicariotto 2023 ch. 5): ``client:`` (the second
spacecraft) and ``formation:`` (the relative-motion simulation of the pair).

Frames: body 1 is the *master* (Vicariotto's reference system): locked quantities are in its base
frame, shape (relative) quantities in the other body's base frame. Twists are [v; ω] (m/s, rad/s),
wrenches [f; τ] (N, N m), linear first, as Pinocchio's.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from sms_cli.mission.base import Position3, Rate3, Rotation3, StrictModel, vector
from sms_cli.mission.system import RobotSpec, WheelsSpec
from sms_cli.thrusters.schema import ThrustersSpec
from sms_cli.mission.units import (
    Force,
    Frequency,
    Length,
    LinearDamping,
    LinearStiffness,
    Angle,
    RotationalDamping,
    RotationalStiffness,
    Time,
    Velocity,
)

SERVICER = "servicer"


class PoseSpec(StrictModel):
    """A rigid pose: position (m) and roll-pitch-yaw (URDF convention) of a frame in another."""

    position: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    attitude: Rotation3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])

    def se3(self):
        """The pose as a ``pinocchio.SE3`` (roll-pitch-yaw by the project's convention, ``sms_cli.model.conventions``)."""
        import numpy as np
        import pinocchio as pin

        from sms_cli.model.conventions import euler_zyx_to_matrix

        return pin.SE3(euler_zyx_to_matrix(*map(float, self.attitude)), np.asarray(self.position, float))


class TwistSpec(StrictModel):
    """A twist [v; ω]: linear (m/s) and angular (rad/s) velocity, components in the frame the field names."""

    linear: vector(Velocity, 3, "m/s") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    angular: Rate3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])

    def as_array(self):
        """[v; ω] (6,), linear first as Pinocchio's."""
        import numpy as np

        return np.array([*self.linear, *self.angular], dtype=float)


class ClientSpec(StrictModel):
    """The client spacecraft: a second free-flying URDF robot with its own wheels, placed relative to the
    servicer's base frame at t = 0 (its velocity is set by ``formation.initial``)."""

    name: str = Field("client", pattern=r"^[A-Za-z][A-Za-z0-9_]*$",
                      description="name used in topics, reports and formation.master (not 'servicer')")
    robot: RobotSpec = Field(description="the client's URDF (its root link is its free-flying base)")
    wheels: WheelsSpec = Field(default_factory=WheelsSpec, description="the client's reaction wheels, as the servicer's")
    thrusters: ThrustersSpec | None = Field(
        None, description="the client's on/off thrusters, as the servicer's top-level thrusters: (Vicariotto 2023 "
                          "Table 3.1); in a formation each spacecraft with a thruster set realises its base wrench by "
                          "allocation, on/off firing and propellant, one without by an ideal wrench source")
    pose: PoseSpec = Field(description="the client's base frame in the servicer's base frame at t = 0")

    @model_validator(mode="after")
    def _name(self):
        if self.name == SERVICER:
            raise ValueError("the client cannot be called 'servicer' (the mission's own robot is)")
        return self


class SubsystemControl(StrictModel):
    """PD gains of one artificial subsystem (locked = the pair's total motion, shape = the relative motion)
    and its setpoint. Gains are diagonal, per axis of the subsystem's frame."""

    controlled: bool = Field(False, description="false: the subsystem moves freely (its wrench is zero)")
    kp_linear: vector(LinearStiffness, 3, "N/m") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    kd_linear: vector(LinearDamping, 3, "N s/m") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    kp_angular: vector(RotationalStiffness, 3, "N m/rad") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    kd_angular: vector(RotationalDamping, 3, "N m s/rad") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    setpoint_offset: PoseSpec = Field(
        default_factory=PoseSpec,
        description="the setpoint as an offset from the pose at t = 0, in that pose's frame: locked, g1_des = g1(0) "
                    "offset (the master's base pose); shape, g12_des = g12(0) offset (the other body's base in the "
                    "master's base frame)")


class InitialMotion(StrictModel):
    """Initial velocities, either as the two artificial systems' twists (Vicariotto 2023 (5.5)) — the locked twist
    V_L in the master's frame and the shape twist V_E (the body twist of g12) in the other body's frame; each base's
    twist is then set so that its locked twist (momentum-based, wheels included) is the one these imply — or as each
    spacecraft's own base twist (``bodies``, its base frame). The wheels keep their initial speeds."""

    locked: TwistSpec = Field(default_factory=TwistSpec)
    shape: TwistSpec = Field(default_factory=TwistSpec)
    bodies: dict[str, TwistSpec] = Field(
        default_factory=dict, description="base twist per spacecraft ('servicer', the client's name), base frame; "
                                          "instead of locked and shape")

    @model_validator(mode="after")
    def _one_way(self):
        if self.bodies and ({"locked", "shape"} & self.model_fields_set):
            raise ValueError("give the initial motion as locked/shape twists or per body (bodies:), not both")
        return self


class PushSpec(StrictModel):
    """An external force pulse on one spacecraft (Vicariotto 2023 §6.2: 10 N and 20 N along −z): constant over
    [at, at + duration), applied at a point of the base frame, components in the base frame."""

    name: str | None = Field(None, description="name in metrics and plots (default push1, push2, …)")
    body: str = Field(description="'servicer' or the client's name")
    at: Time = Field(ge=0, description="start time (s)")
    duration: Time = Field(gt=0, description="how long the force acts (s)")
    force: vector(Force, 3, "N, base frame") = Field(description="force (N) in the body's base frame")
    point: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0],
                             description="application point in the base frame (m); off the CoM it also torques")


class CaptureSpec(StrictModel):
    """Capture (beyond Vicariotto 2023, which has no contact model): from ``at`` on, a servicer frame (end effector or
    docking port) and a client frame (grapple fixture) are joined by a compliant 6-DoF interface, a spring-damper on
    SE(3) whose stiffness and damping put every mode of the linearised interface at ``natural_frequency`` with
    ``damping_ratio`` (K = ω²Λ_rel, D = 2ζωΛ_rel, Λ_rel the relative operational inertia at the capture time)."""

    at: Time = Field(ge=0, description="capture time (s)")
    servicer_frame: str | None = Field(None, description="servicer link or frame (default: its end effector)")
    servicer_offset: PoseSpec = Field(default_factory=PoseSpec, description="interface frame in servicer_frame")
    client_frame: str = Field(description="client link or frame of the grapple fixture")
    client_offset: PoseSpec = Field(default_factory=PoseSpec, description="interface frame in client_frame")
    natural_frequency: Frequency = Field(gt=0, description="the interface's natural frequency (Hz); the plant step "
                                                            "must give ≥ 20 steps per period")
    damping_ratio: float = Field(0.7, ge=0, description="the interface's damping ratio ζ")
    tolerance_position: Length = Field(0.05, gt=0, description="largest distance (m) between the two frames at 'at'")
    tolerance_angle: Angle = Field(5 * 3.141592653589793 / 180, gt=0,
                                   description="largest angle between the two frames at 'at'")


class ArmHoldSpec(StrictModel):
    """A joint PD holding the servicer's arm at its initial configuration: τ = −kp (q − q0) − kd q̇ (internal
    torques: the pair's momentum is unchanged)."""

    kp: RotationalStiffness = Field(gt=0, description="N m/rad (N/m for a prismatic joint)")
    kd: RotationalDamping = Field(ge=0, description="N m s/rad (N s/m)")


class FormationSpec(StrictModel):
    """The two-spacecraft simulation (``sms simulate`` when the mission has this section): the locked/shape
    decomposition of Vicariotto 2023 §5.3 and its relative laws (§5.4)."""

    master: str = Field(SERVICER, description="body 1, the reference system: 'servicer' or the client's name")
    dt: Time = Field(0.05, gt=0, description="plant step (s)")
    duration: Time = Field(gt=0, description="simulated time (s)")
    control_rate: Frequency = Field(5.0, gt=0, description="control rate (Hz), ZOH between updates")
    record_rate: Frequency = Field(5.0, gt=0, description="MCAP and relative_motion.csv sample rate (Hz)")
    relative_law: Literal["free_flying", "free_floating", "hierarchical"] = Field(
        "free_flying",
        description="free_flying: wrenches on the bases (ideal thrusters) for the controlled subsystems plus the wheels' "
                    "compensation and damping (Vicariotto 2023 (5.11), passivity form); free_floating: wheels only, "
                    "valid at zero momentum of each body (Vicariotto 2023 (5.10)); hierarchical: the thrusters damp the "
                    "momenta and hold the translation, the wheels turn the attitudes (Vicariotto 2023 §5.4)")
    actuation: str = Field(
        "both", description="who applies the shape wrench when the locked system is free (Vicariotto 2023 L1068, the "
                            "redistribution): both (an internal, equal and opposite pair: total momentum conserved), or one "
                            "spacecraft only, by name ('servicer', the client's name) or role ('master', 'other'): the "
                            "locked system then receives the wrench that makes the other body's zero")
    locked: SubsystemControl = Field(default_factory=SubsystemControl, description="the pair's total motion")
    shape: SubsystemControl = Field(default_factory=SubsystemControl, description="the relative motion")
    wheel_damping: RotationalDamping = Field(
        0.0, ge=0, description="K_w (N m s/rad) of every wheel: the wheels' rate damping in the Lyapunov law")
    initial: InitialMotion = Field(default_factory=InitialMotion)
    pushes: list[PushSpec] = Field(default_factory=list)
    capture: CaptureSpec | None = Field(None, description="join a servicer frame to a client frame at a given time")
    arm_hold: ArmHoldSpec | None = Field(None, description="the servicer's arm joints held by a joint PD (an arm "
                                                             "without it is left free: zero joint torque)")
    integrator: Literal["plain", "decomposed"] = Field(
        "plain", description="plain: RKMK4 on both spacecraft's absolute velocities; decomposed: Vicariotto 2023's HIL "
                             "integrator (L1159-L1167) on the locked, shape and joint rates [V_L; V_E; θ̇] (same "
                             "trajectories to O(dt⁴), ~15x the cost per step)")
    engine: Literal["auto", "python"] = Field(
        "auto", description="the plant step of the plain integrator: auto: compiled (numba; both spacecraft's models "
                            "rigid trees of 1-DoF joints on a free-flying base, which every two-spacecraft mission is), "
                            "else Pinocchio's; python: always Pinocchio's (the reference). The decomposed integrator is "
                            "Python")
    facility: str | None = Field(
        None, description="a hardware-in-the-loop facility file (sms export hil --facility): when given, the run "
                          "also exports the facility robots' commands and the workspace comparison into <results>/hil/")
    settle_position: Length = Field(0.01, gt=0, description="shape position band for settling time (m)")
    settle_angle: Angle = Field(0.5 * 3.141592653589793 / 180, gt=0, description="shape angle band for settling time")

    @model_validator(mode="after")
    def _check(self):
        ratio = (1.0 / self.control_rate) / self.dt
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ValueError(f"the control period ({1 / self.control_rate:g} s) must be a whole number of plant steps "
                             f"(dt = {self.dt:g} s)")
        if self.relative_law == "free_floating" and "actuation" in self.model_fields_set:
            raise ValueError("a free_floating law applies no base wrench: 'actuation' has no meaning there, remove it")
        return self

