"""Mission-file sections that describe the physical system: robot, wheels, appendages,
spring joints, payloads and the initial state. The compiler (``sms_cli.model``) reads them.

Frames: positions and axes are in the frame of the named mount link (URDF link frame),
in metres; inertias are about the body's centre of mass in that frame, kg m^2.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from sms_cli.mission.base import (
    InertiaTensor,
    Position3,
    Rate3,
    Rotation3,
    StrictModel,
    Vector3,
    Vector6,
    unique,
    vector,
)
from sms_cli.mission.units import (
    Angle,
    AngularRate,
    Dimensionless,
    Inertia,
    Length,
    Mass,
    RotationalDamping,
    RotationalStiffness,
    Torque,
    Velocity,
)


class LinkInertialSpec(StrictModel):
    """Replaces parts of a URDF link's ``<inertial>``; a field not given keeps the URDF's value.

    Frames: the link frame (as the URDF's ``<inertial><origin xyz>``); the inertia is about the
    CoM in the link axes (an ``<inertial>`` whose origin has an rpy is replaced by this one in
    the link axes). The six numbers follow ``sms_cli.inertia`` (URDF's ixy = −∫xy dm)."""

    mass: Mass | None = Field(None, gt=0, description="link mass (kg); default: the URDF's")
    com: Position3 | None = Field(None, description="centre of mass in the link frame (m); default: the URDF's "
                                                     "<inertial><origin xyz>")
    inertia: InertiaTensor | None = Field(
        None, description="[ixx, iyy, izz] or [ixx, iyy, izz, ixy, ixz, iyz] about the CoM in the link axes "
                          "(kg m^2), as in a URDF <inertia>; default: the URDF's")


class RobotSpec(StrictModel):
    """The URDF robot. Its root link (or ``base_link``) becomes a free-flying base."""

    urdf: str = Field(description="path to the URDF file, relative to the mission file")
    base_link: str | None = Field(None, description="base link (default: the URDF root link)")
    end_effector: str | None = Field(
        None, description="end-effector frame (a link name; default: the last link of the arm chain)")
    arm_joints: list[str] | None = Field(
        None, description="actuated manipulator joints in order (default: every movable URDF joint "
                          "that is not a wheel or a spring joint, in tree order)")

    @model_validator(mode="after")
    def _check(self):
        unique(self.arm_joints or [], "joint", "arm_joints")
        return self
    strict: bool = Field(
        False, description="refuse, as a lint, what is accepted with a warning: massless or point-mass links, "
                           "inertias off the triangle inequality, non-physical inertias (as sms compile --strict)")
    kinematics_only: bool = Field(
        False, description="for robots with massless moving links (visual-only descriptions): give each such body a "
                           "placeholder inertia (1e-6 of the robot's mass as a 5 cm sphere at its joint) so that "
                           "workspace maps and kinematic indices run; dynamics stages then refuse the model")
    links: dict[str, LinkInertialSpec] = Field(
        default_factory=dict, description="per URDF link name: mass, com and/or inertia replacing the URDF's "
                                          "<inertial> values (links merged by fixed joints included)")


class WheelLimits(StrictModel):
    """Actuator limits and initial speed of a reaction wheel."""

    max_torque: Torque = Field(gt=0, description="motor torque limit (N m), > 0")
    max_speed: AngularRate = Field(gt=0, description="wheel speed limit relative to the base (rad/s), > 0")
    initial_speed: AngularRate = Field(0.0, description="wheel speed at t=0 relative to the base (rad/s)")


class WheelRotor(WheelLimits):
    """A wheel rotor the compiler adds to the model."""

    spin_inertia: Inertia = Field(gt=0, description="inertia about the spin axis (kg m^2)")
    transverse_inertia: Inertia | None = Field(
        None, ge=0, description="inertia about a transverse axis through the rotor CoM (default: spin/2)")
    mass: Mass = Field(0.0, ge=0, description="rotor mass (kg); 0 keeps the base mass unchanged")


class UrdfWheel(WheelLimits):
    """A URDF joint (continuous or revolute) used as a reaction wheel; its child link is the rotor."""

    joint: str


class DeclaredWheel(WheelRotor):
    """One wheel added by the compiler at a position and axis of a mount link."""

    name: str
    mount: str | None = Field(None, description="mount link (default: the base link)")
    position: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    axis: Vector3 = Field(description="spin axis in the mount frame (normalised with a warning)")


class WheelArray(WheelRotor):
    """A standard wheel layout.

    ``pyramid``: ``count`` wheels whose axes make the angle ``beta`` with the array axis (z
    of the array frame), at azimuths ``azimuth0 + k·360°/count``; wheel k spins about
    ``[sinβ cos φk, sinβ sin φk, cosβ]`` (Caldera 2019 eq. 3.5 for count=4, azimuth0=0).
    ``orthogonal``: three wheels along x, y, z of the array frame (``beta`` unused).
    """

    name: str = Field("rw", description="wheel name prefix: rw1, rw2, ...")
    layout: Literal["pyramid", "orthogonal"]
    count: int = Field(4, ge=3, le=12, description="number of wheels (pyramid only)")
    beta: Angle = Field(0.0, description="angle between each wheel axis and the array axis")
    azimuth0: Angle = Field(0.0, description="azimuth of the first wheel")
    mount: str | None = None
    position: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0],
                                description="array centre; wheels sit at the centre unless radius > 0")
    rpy: Rotation3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="array frame orientation in the mount frame")
    radius: Length = Field(0.0, ge=0, description="distance of each rotor from the centre, along its axis")

    @model_validator(mode="after")
    def _check(self):
        if self.layout == "orthogonal" and "count" in self.model_fields_set and self.count != 3:
            raise ValueError("an orthogonal array has exactly 3 wheels; remove 'count'")
        return self


class WheelsSpec(StrictModel):
    """Reaction wheels: URDF joints named as wheels, single declared wheels, and arrays."""

    joints: list[UrdfWheel] = Field(default_factory=list)
    declared: list[DeclaredWheel] = Field(default_factory=list)
    arrays: list[WheelArray] = Field(default_factory=list)

    @model_validator(mode="after")
    def _check(self):
        unique([w.joint for w in self.joints], "wheel joint", "joints", "joint")
        unique([w.name for w in self.declared], "wheel", "declared", "name")
        return self


class Mode(StrictModel):
    """One clamped (Craig–Bampton) mode of an appendage, mass-normalised."""

    frequency: AngularRate = Field(gt=0, description="clamped natural frequency (bare = rad/s; '0.16 Hz' works)")
    damping: Dimensionless = Field(0.0, ge=0, lt=1, description="modal damping ratio ζ")
    participation: Vector6 = Field(description="participation factors L (6) in the order given by 'ordering'")


class AppendageSpec(StrictModel):
    """A flexible appendage: its URDF link stays rigid; the modes add hybrid coordinates at
    the junction frame (the link's frame unless ``frame`` names another link)."""

    name: str
    link: str = Field(description="URDF link of the appendage (its rigid inertia)")
    frame: str | None = Field(None, description="junction frame in which L is expressed (default: 'link')")
    ordering: Literal["TR", "RT"] = Field(
        "TR", description="order of L's entries: TR = [Tx Ty Tz Rx Ry Rz] (Kraiem 2022), RT = [Rx Ry Rz Tx Ty Tz]")
    modes: list[Mode] = Field(min_length=1)
    initial_amplitudes: list[float] | None = Field(None, description="η(0), one per mode (default 0)")


class SpringSpec(StrictModel):
    """A passive spring/damper on a URDF joint (hinged panel): τ = −k (q − rest) − c q̇."""

    joint: str
    stiffness: RotationalStiffness = Field(ge=0)
    damping: RotationalDamping = Field(0.0, ge=0)
    rest: Angle = Field(0.0, description="rest angle (rad) or position (m)")


class PayloadSpec(StrictModel):
    """A rigid body that can be attached to a frame (tile, captured target)."""

    name: str
    frame: str = Field(description="link it attaches to")
    mass: Mass = Field(gt=0)
    inertia: InertiaTensor = Field(description="about its CoM, in the frame's axes (kg m^2)")
    com: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="CoM in the frame (m)")
    attached: bool = Field(False, description="attached at t = 0")


class InitialState(StrictModel):
    """State at t = 0. Base attitude as roll-pitch-yaw of the base in the inertial frame."""

    base_position: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    base_attitude: Rotation3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    base_angular_velocity: Rate3 = Field(default_factory=lambda: [0.0, 0.0, 0.0],
                                         description="ω0 in the base frame (rad/s)")
    base_linear_velocity: vector(Velocity, 3, "base origin velocity in the inertial frame (m/s)") = Field(
        default_factory=lambda: [0.0, 0.0, 0.0])
    joints: dict[str, Angle] = Field(default_factory=dict, description="joint positions by name (rad or m)")
    joint_rates: dict[str, AngularRate] = Field(default_factory=dict)
