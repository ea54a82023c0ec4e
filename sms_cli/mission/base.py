"""Building blocks shared by every section of the mission schema."""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from sms_cli.mission.units import Angle, AngularRate, Dimensionless, Inertia, Length


class StrictModel(BaseModel):
    """A mission-file section: unknown keys are errors (with a nearest-key suggestion)."""

    model_config = ConfigDict(extra="forbid", frozen=False, populate_by_name=False)


def _fixed_length(n: int):
    def check(v: list[float]) -> list[float]:
        if len(v) != n:
            raise ValueError(f"expected {n} numbers, got {len(v)}")
        return v

    return AfterValidator(check)


Vector3 = Annotated[list[Dimensionless], _fixed_length(3), Field(description="3 numbers")]
Position3 = Annotated[list[Length], _fixed_length(3), Field(description="x y z position (m)")]
Rotation3 = Annotated[list[Angle], _fixed_length(3), Field(description="roll pitch yaw, URDF convention (rad)")]
Rate3 = Annotated[list[AngularRate], _fixed_length(3), Field(description="angular velocity (rad/s)")]
Vector6 = Annotated[list[Dimensionless], _fixed_length(6), Field(description="6 numbers")]


def _inertia6(v: list[float]) -> list[float]:
    if len(v) == 3:
        return [v[0], v[1], v[2], 0.0, 0.0, 0.0]
    if len(v) != 6:
        raise ValueError("inertia is [ixx, iyy, izz] or [ixx, iyy, izz, ixy, ixz, iyz]")
    return v


InertiaTensor = Annotated[
    list[Inertia],
    AfterValidator(_inertia6),
    Field(description="[ixx, iyy, izz] or [ixx, iyy, izz, ixy, ixz, iyz] about the CoM (kg m^2)"),
]


def field_names(model: type[BaseModel]) -> list[str]:
    """Keys a section accepts (aliases where defined), for suggestions."""
    return [f.alias or name for name, f in model.model_fields.items()]


def dump_jsonable(model: BaseModel) -> dict[str, Any]:
    """A section as plain JSON-friendly data (SI values)."""
    return model.model_dump(mode="json")
