"""The mission's ``simulation:`` section: time steps, controllers, actuators, sensors,
disturbances and the phase sequence."""

from __future__ import annotations

from typing import Annotated, Literal

from annotated_types import Gt
from pydantic import Field, model_validator

from sms_cli.mission.base import InertiaTensor, Position3, Rotation3, StrictModel, Vector3, vector
from sms_cli.mission.units import Angle, AngularRate, Dimensionless, Force, Frequency, Mass, Time, Torque
from sms_cli.sim.laws.schema import ArmLawSpec, AttitudeLawSpec, ResolvedRateSpec

BaseMode = Literal["free-floating", "rotation-free-floating", "free-flying", "fixed"]
# free-floating: nothing controls the base; rotation-free-floating: attitude by the attitude law
# (wheels or thrusters), translation free; free-flying: attitude law through thrusters;
# fixed: the base is held perfectly (Chevallard 2019's "base perfectly controlled"): its acceleration is
# zero and the wrench needed to hold it is reported as /base/reaction.


class Waypoint(StrictModel):
    """Joint positions to reach at a time from the phase start (quintic interpolation, rest to rest)."""

    at: Time | None = Field(None, description="time from the phase start (s); omitted in a phase of duration 'auto', "
                                              "whose segments are sized from the actuator authority")
    joints: dict[str, Angle] = Field(description="joint positions by name (rad or m); others keep their value")


class EndEffectorTarget(StrictModel):
    """End-effector target in the inertial frame: a fixed point, or a point moving at constant velocity."""

    position: Position3
    velocity: vector(float, 3, "m/s, inertial") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    relative_to_start: bool = Field(False, description="position is an offset from the EE position at the phase start")


class PhaseSpec(StrictModel):
    """One phase of the mission. It ends after ``duration``; with ``until_settled`` it may end
    earlier, once the attitude error has stayed below the tolerance for ``settle_time``."""

    name: str
    kind: Literal["slew", "deploy", "grasp", "move_payload", "release", "track", "hold"] = "hold"
    duration: Time | Literal["auto"] = Field(
        description="phase length (s); 'auto' (joint-waypoint phases): each rest-to-rest segment gets the shortest "
                    "duration whose reference needs at most simulation.auto_duration's fraction of every actuator's "
                    "torque and speed limit (inverse dynamics, see sms compile)")
    base_mode: BaseMode = "rotation-free-floating"
    attitude: Rotation3 | None = Field(None, description="target base attitude, roll-pitch-yaw (Z-Y-X), inertial")
    attitude_profile: Literal["step", "smooth"] = Field(
        "step", description="step: target at once; smooth: quintic eigen-axis slew over 'slew_time'")
    slew_time: Time | None = None
    waypoints: list[Waypoint] = Field(default_factory=list)
    joint_profile: Literal["quintic", "step"] = Field(
        "quintic", description="quintic: smooth rest-to-rest segments ending at each waypoint; "
                               "step: the reference jumps to each waypoint at its time (Caldera 2019 style)")
    end_effector: EndEffectorTarget | None = None
    attach: list[str] = Field(default_factory=list, description="payloads attached at the phase start")
    detach: list[str] = Field(default_factory=list, description="payloads released at the phase start")
    until_settled: Angle | None = Field(None, description="end early when the attitude error stays below this")
    settle_time: Time = 5.0

    @model_validator(mode="after")
    def _check(self):
        if self.waypoints and self.end_effector is not None:
            raise ValueError("a phase has either joint waypoints or an end_effector target, not both")
        if self.duration == "auto":
            if not self.waypoints:
                raise ValueError("duration 'auto' sizes joint moves: this phase has no waypoints (give a duration in s)")
            if any(w.at is not None for w in self.waypoints):
                raise ValueError("in a phase of duration 'auto' the waypoints take no 'at' (each segment is sized from the "
                                 "actuator authority): remove 'at', or give the phase a duration in s")
            if self.until_settled is not None or self.attitude_profile == "smooth":
                raise ValueError("duration 'auto' cannot be combined with until_settled or a smooth attitude slew")
            return self
        if any(w.at is None for w in self.waypoints):
            raise ValueError("every waypoint needs 'at' (time from the phase start), unless the phase duration is 'auto'")
        if self.duration <= 0:
            raise ValueError("the phase duration must be positive")
        times = [w.at for w in self.waypoints]
        if times != sorted(times) or any(t <= 0 for t in times):
            raise ValueError("waypoint times must be positive and increasing")
        if times and times[-1] > self.duration + 1e-9:
            raise ValueError(f"last waypoint at {times[-1]:g} s is after the phase end ({self.duration:g} s)")
        if self.attitude_profile == "smooth" and self.slew_time is None:
            raise ValueError("a smooth attitude profile needs slew_time")
        return self


class TileSpec(StrictModel):
    """One tile of the assembly (Kraiem 2022 §4.3.1: 55 kg per tile, loads 0–220 kg). Its CoM and inertia
    are given in the frame of its store slot; the arm grasps it with the end-effector frame at the grasp
    pose in the slot frame and releases it at the same pose in the place frame, so the same numbers hold in
    the place frame, and their transform by the grasp pose in the end-effector frame."""

    mass: Mass = Field(gt=0)
    inertia: InertiaTensor = Field(description="about its CoM, in the slot frame's axes (kg m^2)")
    com: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="CoM in the slot frame (m)")


class GraspSpec(StrictModel):
    """Pose of the end-effector frame in a slot's (or place's) frame when it holds the tile there."""

    position: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="m, in the slot frame")
    rpy: Rotation3 = Field(default_factory=lambda: [0.0, 0.0, 0.0],
                           description="roll-pitch-yaw of the end-effector axes in the slot frame (URDF convention: "
                                       "R = Rz(yaw) Ry(pitch) Rx(roll)), e.g. [180 deg, 0, 0]: tool z against the "
                                       "slot's z")


class AssemblyTaskSpec(StrictModel):
    """One assembly task: pick the tiles of these store slots in order (the load grows by one tile at each
    grasp), carry them all to ``place`` and release them there."""

    pick: list[int] = Field(min_length=1, description="store slot numbers (1-based) whose tiles the arm picks")
    place: str = Field(description="frame (URDF link) on which the end-effector frame releases the tiles")


class AssemblySpec(StrictModel):
    """Tile assembly tasks (Kraiem 2022 §4.3.1), expanded into phases run after ``phases``: for each task, a
    move to each slot (duration 'auto'), a grasp (the tile's mass leaves the store for the end effector), a
    move to the place frame with the tiles, a release (their mass joins the place frame's body); at the end
    a move back to the initial joint configuration. Each move's target is the joint configuration that puts
    the end-effector frame on the slot's (or place's) pose, by inverse kinematics of the arm with the base
    and wheels fixed (``sms_cli.model.ik``): store and sites are frames of the base, so the target holds
    whatever the base does. Zero initial momentum and the wheels' momentum-conserving reference
    (Kraiem 2022 (4.51)) are the law's and the initial state's."""

    tile: TileSpec
    store: str = Field(description="slot frame names with the slot number as '{index}', e.g. 'tile_slot_{index:02d}'")
    tiles: int = Field(gt=0, description="tiles in the store at t = 0, in slots 1..tiles (their mass is on the "
                                         "store's body until picked)")
    tasks: list[AssemblyTaskSpec] = Field(min_length=1)
    grasp: GraspSpec = Field(default_factory=GraspSpec, description="end-effector pose in the slot (place) frame at "
                                                                   "grasp (release); default: on the frame")
    dwell: Time = Field(10.0, gt=0, description="length of each grasp and release phase (s)")
    return_home: bool = Field(True, description="end with a move back to the initial joint configuration")

    @model_validator(mode="after")
    def _check(self):
        try:
            names = [self.store.format(index=k) for k in (1, 2)]
        except (KeyError, IndexError, ValueError) as exc:
            raise ValueError(f"store '{self.store}' must name the slot number as {{index}} (e.g. "
                             f"'tile_slot_{{index:02d}}'): {exc}") from None
        if names[0] == names[1]:
            raise ValueError(f"store '{self.store}' gives every slot the same frame name: put the slot number in it "
                             "as {index}")
        seen: set[int] = set()
        for task in self.tasks:
            for k in task.pick:
                if not 1 <= k <= self.tiles:
                    raise ValueError(f"slot {k} is not in the store (slots 1..{self.tiles})")
                if k in seen:
                    raise ValueError(f"the tile of slot {k} is picked twice")
                seen.add(k)
        return self


class AllocationSpec(StrictModel):
    """Wheel torque allocation for a desired base torque: minimum-norm pseudo-inverse, plus optional
    null-space momentum management driving the wheel speeds toward ``target_speed``."""

    method: Literal["pinv"] = "pinv"
    null_space_gain: float = Field(0.0, ge=0, description="1/s; 0 disables momentum management")
    target_speed: AngularRate = 0.0


class WheelFriction(StrictModel):
    """Wheel bearing friction: τ_f = −coulomb·sign(ω) − viscous·ω (relative speed)."""

    coulomb: Torque = 0.0
    viscous: float = Field(0.0, ge=0, description="N m s/rad")


class NoiseSpec(StrictModel):
    """White noise (standard deviation per sample) and constant bias of one sensor."""

    noise: float = Field(0.0, ge=0)
    bias: Vector3 | float = 0.0


class SensorsSpec(StrictModel):
    """Sensors with seeded noise: gyro (rad/s), attitude (rad, small rotation), joints (rad or m)."""

    seed: int = 0
    gyro: NoiseSpec = Field(default_factory=NoiseSpec)
    attitude: NoiseSpec = Field(default_factory=NoiseSpec)
    joints: NoiseSpec = Field(default_factory=NoiseSpec)


class DisturbanceSpec(StrictModel):
    """External wrench on the base: constant, or a pulse from ``start`` for ``duration``."""

    kind: Literal["constant", "pulse"] = "pulse"
    frame: Literal["base", "inertial"] = "base"
    force: vector(Force, 3, "x y z (N)") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    torque: vector(Torque, 3, "x y z (N m)") = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    start: Time = 0.0
    duration: Time = 0.0


class AutoDurationSpec(StrictModel):
    """How phases of duration 'auto' are sized: the reference's inverse dynamics (free-floating base held at
    rest by the wheels, zero momentum: Kraiem 2022 (4.51); payloads as attached in that phase; modes at rest)
    scales exactly as 1/T² in torque and 1/T in speed, so the shortest segment duration meeting
    ``torque_fraction`` of every torque limit and ``speed_fraction`` of every speed limit is closed-form."""

    torque_fraction: float = Field(0.5, gt=0, le=1, description="largest share of each actuator's torque limit the "
                                                                "reference may need (the rest is left to feedback)")
    speed_fraction: float = Field(0.8, gt=0, le=1, description="largest share of each wheel and joint speed limit")
    hold_after: Time = Field(10.0, ge=0, description="time the phase continues after its last segment (s)")
    round_to: Time = Field(1.0, gt=0, description="segment durations are rounded up to a multiple of this (s)")


class JointStopsSpec(StrictModel):
    """The arm joints' URDF limits as rigid unilateral stops of the plant (sms_cli.dynamics.joint_stops): an
    impulse at arrival (momentum conserved), then the joint held on its stop by a constraint force until
    the drive pulls it away. Continuous joints and joints without limits have none."""

    enabled: bool = Field(True, description="model the stops (false: the joints move through their limits)")
    restitution: float = Field(0.0, ge=0, le=1, description="joint rate after an impact = −restitution × the rate "
                                                            "before; 0: inelastic (the joint stays on its stop)")


class DivergenceSpec(StrictModel):
    """When the simulation counts as diverged (exit code 3, recording kept)."""

    max_rate: AngularRate = Field(1e4, description="any generalized velocity above this")
    max_modal_amplitude: float = 1e3


class ModelErrorsSpec(StrictModel):
    """Errors of the law's model against the plant (Kraiem 2022 §4.3 validates its robust law with ±3 % on the
    bodies' inertias, ±10 % on their centres of mass and +10 % on the flexible parameters): the law inverts and
    observes a copy of the model with these errors (``sms_cli.model.model_errors``); the plant is the URDF's."""

    inertia: Dimensionless = Field(0.0, ge=0, lt=1, description="relative error of every body's rotational inertia "
                                   "about its CoM, sign drawn per body from seed (0.03: ±3 %)")
    com: Dimensionless = Field(0.0, ge=0, lt=1, description="relative error of every body's CoM position in its joint "
                               "frame, sign drawn per body from seed (0.1: ±10 %)")
    modal_frequency: Dimensionless = Field(0.0, gt=-1, lt=1, description="relative error of every appendage mode's "
                                           "frequency, signed (0.1: the law's modes 10 % above the plant's)")
    seed: int = Field(0, description="seed of the per-body signs")


class KalmanSpec(StrictModel):
    """Weights of the steady-state Kalman observer gain (``sms_cli.sim.laws.ndi_gains.kalman_gain``): process noise
    intensity w on every state of x_e = [f; ω0; ḟ] and measurement noise intensity v on each gyro axis (their ratio sets
    the observer's bandwidth: a larger w/v, a faster observer)."""

    process: float = Field(1e-2, gt=0, description="w: process noise intensity (W = w I)")
    measurement: float = Field(1e-4, gt=0, description="v: gyro noise intensity ((rad/s)² s; V = v I)")


class NdiSpec(StrictModel):
    """Kraiem 2022 NDI of the wheels + arm with the flexible/base-state observer (replaces the attitude and
    arm laws). Gains from ``gains.yaml`` (written by ``sms synthesize``, found in the results folder or
    at a path relative to the mission file) or given here."""

    gains: str | None = Field(None, description="gains.yaml path (default: <results>/gains.yaml when kp/kv/L are absent)")
    kp: list[float] | float | None = Field(None, description="1/s² per actuator (wheels, then arm)")
    kv: list[float] | float | None = Field(None, description="1/s per actuator")
    L: list[list[float]] | Literal["kalman"] | None = Field(
        None, description="observer gain (2 n_f + 3) × 3 for x = [f; ω0; ḟ], y = ω0, or 'kalman': the steady-state "
                          "Kalman filter of the law's model at rest at the initial configuration (weights in kalman)")
    kalman: KalmanSpec = Field(default_factory=lambda: KalmanSpec(), description="weights of L: kalman")
    attitude_gain: float = Field(0.05, gt=0, description="k_att (1/s): base rate command ω_des = ω_ref − k_att θ_e")
    wheel_feedforward: bool = Field(
        True, description="wheel accelerations that keep the base from rotating under the commanded arm acceleration "
                          "(the derivative of the (3.66) wheel-rate reference); false: the wheels act on the base-rate "
                          "error alone")
    disturbance_observer: bool = Field(
        False, description="Kraiem 2022 ch. 4's nonlinear disturbance observer (4.12): the law subtracts its estimate "
                           "τ̂_d of the actuators' disturbance torques (4.21); gain L_d = Q_d M◇⁻¹ with Q_d from "
                           "gains.yaml (sms synthesize with lmi.variant: ndi_observer_ndo) or given here")
    model_errors: ModelErrorsSpec | None = Field(
        None, description="the law's model differs from the plant by these errors (default: the plant's own model)")
    ndo_bandwidth: AngularRate | None = Field(
        None, gt=0, description="instead of Q_d: Q_d = β M◇ at the initial configuration (the law's model), so that "
                                "every actuator's disturbance estimate converges at β (1/s)")
    Q_d: list[list[float]] | None = Field(None, description="NDO gain matrix (N m s per rad, actuators × actuators: "
                                                            "wheels, then arm); default: gains.yaml's observer.Q_d")


# a frequency > 0 inside a union (the bound on the number itself, as Field(gt=0) puts it on a plain quantity)
_PositiveFrequency = Annotated[(float, Gt(0)) + Frequency.__metadata__]


class SimulationSpec(StrictModel):
    """Nonlinear simulation of the mission (``sms simulate``)."""

    dt: Time = Field(0.01, gt=0, description="plant step (s)")
    control_rate: Frequency = Field(10.0, gt=0, description="controller rate (Hz); ZOH between updates")
    record_rate: _PositiveFrequency | Literal["control"] | None = Field(
        "control", description="MCAP sample rate (Hz): 'control' (the default) samples at the control rate, every "
                                "control tick, so that the recording can be replayed (see the metadata record "
                                "sms.timing); null records every plant step; a rate that is not a whole multiple "
                                "of the control rate makes a recording that cannot be replayed")
    attitude: AttitudeLawSpec | Literal["from_gains"] | None = Field(
        None, description="base attitude law, or 'from_gains': the law `sms synthesize` wrote into gains.yaml "
                          "(simulation.attitude block) in the results folder")
    attitude_actuator: Literal["wheels", "thrusters"] = Field(
        "wheels", description="what applies the attitude law's torque: the wheels, or thrusters; with a top-level "
                              "thrusters: section the real thruster set (allocation, on/off firing, propellant), "
                              "without one an ideal torque source")
    attitude_torque_limit: Torque | None = Field(
        None, gt=0, description="per-axis limit (N m, base frame) of the ideal attitude torque the thrusters apply "
                                "(attitude_actuator: thrusters, or a free-flying phase): each component of the law's "
                                "torque is clipped to ±limit, and a clipped tick counts in saturation_time_s; "
                                "with a thrusters: section, the torque handed to the allocation is clipped; "
                                "null: no limit")
    arm: ArmLawSpec | None = Field(None, description="manipulator joint law")
    resolved_rate: ResolvedRateSpec | None = Field(None, description="end-effector tracking (phases with end_effector)")
    ndi: NdiSpec | None = Field(None, description="Kraiem 2022 NDI + observer on wheels and arm (instead of attitude/arm laws)")
    allocation: AllocationSpec = Field(default_factory=AllocationSpec)
    wheel_friction: WheelFriction = Field(default_factory=WheelFriction)
    sensors: SensorsSpec = Field(default_factory=SensorsSpec)
    disturbances: list[DisturbanceSpec] = Field(default_factory=list)
    divergence: DivergenceSpec = Field(default_factory=DivergenceSpec)
    joint_stops: JointStopsSpec = Field(default_factory=JointStopsSpec)
    auto_duration: AutoDurationSpec = Field(default_factory=AutoDurationSpec)
    settle_tolerance: Angle = Field(0.01, description="attitude error band for settling time (rad)")
    engine: Literal["auto", "compiled", "python"] = Field(
        "auto", description="auto: the compiled loop (numba) when the mission fits it (rigid base, reaction wheels, "
                            "mrp_feedback, no arm, step references), else the Python loop; "
                            "compiled: require it; python: always the Python loop (the reference)")
    phases: list[PhaseSpec] = Field(min_length=1, description="the mission's phases, in order (with 'assembly', the "
                                                               "phases before the assembly tasks, e.g. a hold)")
    assembly: AssemblySpec | None = Field(None, description="tile assembly tasks, expanded into phases run after "
                                                            "'phases' (Kraiem 2022 §4.3.1)")

    @model_validator(mode="after")
    def _check(self):
        if self.ndi is not None and (self.attitude is not None or self.arm is not None):
            raise ValueError("'ndi' drives the wheels and the arm: remove 'attitude' and 'arm'")
        if self.record_rate == "control":
            self.record_rate = self.control_rate  # every control tick: a recording another engine can replay
        period = 1.0 / self.control_rate
        ratio = period / self.dt
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ValueError(f"the control period ({period:g} s) must be a whole number of plant steps (dt = {self.dt:g} s)")
        if (self.attitude_torque_limit is not None and self.attitude_actuator == "wheels"
                and not any(p.base_mode == "free-flying" for p in self.phases)):
            raise ValueError("attitude_torque_limit limits the thrusters' ideal torque: this mission's attitude "
                             "torque goes to the wheels (attitude_actuator: wheels, no free-flying phase), whose "
                             "limits are their max_torque")
        return self
