"""The mission's ``analysis:`` section (``sms analyze``).

Angles in radians, lengths in metres, rates in rad/s (or m/s for prismatic joints), torques in
N m; every quantity also accepts a unit string (``"0.5 rpm"``, ``"180 deg"``).
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, model_validator

from sms_cli.mission.base import ItemCount, StrictModel
from sms_cli.mission.units import Angle, AngularRate, Force, Length, Torque, Velocity

#: A joint coordinate: an angle (revolute) or a length (prismatic).
JointValue = Union[Angle, Length]
#: A joint rate: rad/s (revolute) or m/s (prismatic).
JointRate = Union[AngularRate, Velocity]
#: A joint effort: N m (revolute) or N (prismatic).
JointEffort = Union[Torque, Force]

#: Index groups ``analysis.indices`` may list (see ``sms_cli.analysis.indices``).
INDEX_GROUPS = (
    "manipulability",  # fixed-base and free-floating (GJM) manipulability, singularity test (3.10)-(3.11)
    "dynamic_manipulability",  # Kraiem 2022 (3.14), needs joint torque limits
    "base_indices",  # K^m_w0, K^r_w0 (3.18), needs joint and wheel speed limits
    "null_motion",  # mu^N (3.25), needs joint and wheel speed limits
    "joint_limits",  # normalised distance to the joint limits
    "momentum",  # arm angular momentum at max joint speed vs wheel momentum capacity
)
IndexGroup = Literal[
    "manipulability", "dynamic_manipulability", "base_indices", "null_motion", "joint_limits", "momentum"
]


class SymmetrySpec(StrictModel):
    """Sample half of one joint's range (the system is symmetric about a plane, Kraiem 2022 L1946)."""

    joint: str = Field(description="arm joint whose range is halved (e.g. the shoulder yaw joint)")
    keep: Literal["upper", "lower"] = Field("upper", description="which half of the range to keep")
    about: JointValue | None = Field(
        None, description="where the range is split (default: the middle of the joint range)")


class SamplingSpec(StrictModel):
    """Joint-space samples of the arm; the base attitude stays the initial one."""

    method: Literal["grid", "sobol"] = Field(
        "sobol", description="grid: n values per joint (n^joints samples); sobol: n quasi-random samples")
    n: int = Field(4096, ge=1, description="grid: values per joint; sobol: number of samples (a power of 2 is best)")
    joints: list[str] | None = Field(
        None, description="arm joints to sample (default: all); the others keep their initial value")
    ranges: dict[str, Annotated[list[JointValue], ItemCount(2)]] = Field(
        default_factory=dict, description="per-joint [lower, upper] overriding the URDF limits")
    symmetry: SymmetrySpec | None = None
    seed: int = Field(0, description="Sobol scrambling seed")
    chunk: int = Field(4096, ge=16, le=1 << 20, description="samples evaluated per batch (bounds memory)")
    max_samples: int = Field(10_000_000, ge=1, description="refuse studies larger than this")

    @model_validator(mode="after")
    def _check_ranges(self):
        for name, r in self.ranges.items():
            if len(r) != 2 or not r[0] < r[1]:
                raise ValueError(f"ranges.{name}: expected [lower, upper] with lower < upper, got {r}")
        return self


class LimitOverrides(StrictModel):
    """Actuator limits used by the indices, overriding the URDF / wheel limits.

    A single value applies to every joint (or wheel); a mapping names them one by one.
    ``joint_speed`` and ``wheel_speed`` give Q_max and Omega_max of Kraiem 2022 (3.17);
    ``joint_torque`` gives the torque scaling of the dynamic manipulability (3.14).
    """

    joint_speed: JointRate | dict[str, JointRate] | None = None
    joint_torque: JointEffort | dict[str, JointEffort] | None = None
    wheel_speed: AngularRate | dict[str, AngularRate] | None = None


class VariantSpec(StrictModel):
    """A design variant analysed on the same samples as the nominal system."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$", description="used in file names")
    wheel_inertia_scale: float = Field(1.0, gt=0, description="multiply every wheel's spin inertia (Kraiem 2022: 2)")
    wheel_speed_scale: float = Field(1.0, gt=0, description="multiply every wheel's speed limit")
    joint_speed_scale: float = Field(1.0, gt=0, description="multiply every joint's speed limit")
    attach: list[str] = Field(default_factory=list, description="payloads attached in this variant")


class ModalSpec(StrictModel):
    """Linearised model and coupled modes at one or more configurations (a list can follow a path)."""

    configurations: list[dict[str, JointValue]] = Field(
        default_factory=lambda: [{}],
        description="joint values by name; joints not named keep their initial value ({} = initial state)")
    joints: Literal["free", "locked"] = Field(
        "free", description="free: arm joints and wheels torque-driven (open loop, as Kraiem 2022 Fig. 2.12); "
                            "locked: clamped by their servos")
    export: list[Literal["npz", "mat"]] = Field(default_factory=lambda: ["npz", "mat"])


class AnalysisSpec(StrictModel):
    """What ``sms analyze`` computes: samples, indices, variants, modal analysis, outputs."""

    sampling: SamplingSpec = Field(default_factory=SamplingSpec)
    arm_joints: list[str] | None = Field(
        None, description="arm joints the indices treat as actuated (default: robot.arm_joints); the others "
                          "stay locked at their initial value (e.g. a gripper joint)")
    task: Literal["auto", "position", "pose"] = Field(
        "auto", description="end-effector task rows of the manipulability and singularity indices: "
                            "auto = position for arms with fewer than 6 joints, else pose")
    indices: list[IndexGroup] | Literal["all"] = Field("all", description=f"index groups: {', '.join(INDEX_GROUPS)}")
    limits: LimitOverrides = Field(default_factory=LimitOverrides)
    variants: list[VariantSpec] = Field(default_factory=list, description="analysed besides the nominal system")
    singular_tolerance: float = Field(
        1e-3, gt=0, lt=1, description="a sample is singular when sigma_min/sigma_max of J*_mEE is below this")
    best: int = Field(5, ge=0, le=100, description="best configurations reported per index")
    modal: ModalSpec | None = None
    table: bool | list[Literal["parquet", "csv"]] = Field(
        True, description="per-sample tables analysis_<variant>.parquet|.csv (one row per sample): true = Parquet, "
                          "false = none, or the formats, e.g. [parquet, csv] (sms analyze --csv adds CSV for one run)")
    plots: bool = Field(True, description="write the workspace plots")

    @model_validator(mode="after")
    def _check_variants(self):
        names = [v.name for v in self.variants]
        if "nominal" in names or len(set(names)) != len(names):
            raise ValueError("variant names must be unique and not 'nominal'")
        return self

    def table_formats(self, csv: bool = False) -> tuple[str, ...]:
        """The formats of the per-sample tables (``csv``: CSV asked for on the command line as well)."""
        formats = ("parquet",) if self.table is True else () if self.table is False else tuple(self.table)
        return tuple(f for f in ("parquet", "csv") if f in formats or (csv and f == "csv"))

    def groups(self) -> tuple[str, ...]:
        """The selected index groups, in canonical order."""
        return INDEX_GROUPS if self.indices == "all" else tuple(g for g in INDEX_GROUPS if g in self.indices)
