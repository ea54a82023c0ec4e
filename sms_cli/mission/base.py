"""Building blocks shared by every section of the mission schema."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from sms_cli.mission.units import Angle, AngularRate, Dimensionless, Inertia, Length, SpecError


class StrictModel(BaseModel):
    """A mission-file section: unknown keys are errors (with a nearest-key suggestion), and every
    number must be finite: NaN and infinity are refused in plain numbers, quantities (``"1e999 kg"``),
    vectors and gains alike (``allow_inf_nan=False`` applies to every float the section holds)."""

    model_config = ConfigDict(extra="forbid", frozen=False, populate_by_name=False, allow_inf_nan=False)


def unique(names: list[str], what: str, field: str, key: str = "") -> None:
    """Refuse a name listed twice in the list ``field`` (``key``: the item's field holding it)."""
    first: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in first:
            raise SpecError(f"{what} '{name}' is listed twice (items {first[name]} and {i})",
                            (field, i, key) if key else (field, i), "remove one of the two entries")
        first[name] = i


@dataclass(frozen=True)
class ItemCount:
    """JSON Schema of a list's length, for lengths the loader checks in a validator (whose message,
    "expected 3 numbers, got 2", pydantic's ``min_length`` would replace): ``ItemCount(3)`` is
    minItems = maxItems = 3; ``ItemCount(3, 6)`` is exactly 3 or exactly 6 items."""

    counts: tuple[int, ...]

    def __init__(self, *counts: int):
        object.__setattr__(self, "counts", counts)

    def __get_pydantic_json_schema__(self, core_schema: Any, handler: Any) -> dict[str, Any]:
        schema = handler(core_schema)
        forms = [{"minItems": n, "maxItems": n} for n in self.counts]
        return {**schema, **forms[0]} if len(forms) == 1 else {**schema, "anyOf": forms}


def _fixed_length(n: int):
    def check(v: list[float]) -> list[float]:
        if len(v) != n:
            raise ValueError(f"expected {n} numbers, got {len(v)}")
        return v

    return AfterValidator(check)


def vector(item: Any, n: int, description: str) -> Any:
    """A list of exactly ``n`` items (checked at load, and stated in the JSON Schema)."""
    return Annotated[list[item], _fixed_length(n), ItemCount(n), Field(description=description)]


Vector3 = vector(Dimensionless, 3, "3 numbers")
Position3 = vector(Length, 3, "x y z position (m)")
Rotation3 = vector(Angle, 3, "roll pitch yaw, URDF convention (rad)")
Rate3 = vector(AngularRate, 3, "angular velocity (rad/s)")
Vector6 = vector(Dimensionless, 6, "6 numbers")


def _inertia6(v: list[float]) -> list[float]:
    """[ixx, iyy, izz(, ixy, ixz, iyz)] → 6 numbers, refused unless a rigid body can have it:
    principal moments ≥ 0 and each at most the sum of the other two (kg m^2)."""
    if len(v) == 3:
        v = [v[0], v[1], v[2], 0.0, 0.0, 0.0]
    if len(v) != 6:
        raise ValueError("inertia is [ixx, iyy, izz] or [ixx, iyy, izz, ixy, ixz, iyz]")
    from sms_cli.inertia import principal_moments

    moments = principal_moments(*v)
    tol = 1e-9 * max(float(abs(moments).sum()), 1e-300)
    shown = ", ".join(f"{m:.6g}" for m in moments)
    if moments[0] < -tol:
        raise SpecError(f"principal moments of inertia {shown} kg m^2: a moment of inertia cannot be negative",
                        hint="check the signs: ixx, iyy, izz are positive (products of inertia may be negative)")
    if moments[2] > moments[0] + moments[1] + tol:
        raise SpecError(f"principal moments of inertia {shown} kg m^2 break the triangle inequality "
                        f"({moments[2]:.6g} > {moments[0]:.6g} + {moments[1]:.6g}): no rigid body has this inertia",
                        hint="each principal moment is at most the sum of the other two (a thin rod along z: [I, I, 0])")
    return v


InertiaTensor = Annotated[
    list[Inertia],
    AfterValidator(_inertia6),
    ItemCount(3, 6),
    Field(description="[ixx, iyy, izz] or [ixx, iyy, izz, ixy, ixz, iyz] about the CoM (kg m^2)"),
]


def field_names(model: type[BaseModel]) -> list[str]:
    """Keys a section accepts (aliases where defined), for suggestions."""
    return [f.alias or name for name, f in model.model_fields.items()]


def dump_jsonable(model: BaseModel) -> dict[str, Any]:
    """A section as plain JSON-friendly data (SI values)."""
    return model.model_dump(mode="json")
