"""The facility file of ``sms export hil``: where the two spacecraft mock-ups sit in a robotic HIL
facility (DLR's OOS-SIM in Vicariotto 2023 §6.2), which robot carries each, which one replays the
relative motion, and the envelope the moving robot's tool may sweep.

Frames: every pose is world<-child in the facility world frame (``world_frame``), position in m,
orientation as roll-pitch-yaw (URDF convention, ``R = Rz(y) Ry(p) Rx(r)``; angles with units,
``"90 deg"``, a bare number is rad), a unit quaternion ``[x, y, z, w]`` or a 3x3 rotation matrix
(rows). A quaternion off unit length by more than 1e-6, or a matrix that is not orthonormal with
determinant +1 (to 1e-6), is refused with its file:line.

Loading goes through the mission loader's YAML reader (``load_yaml``: line-numbered values) and its
pydantic error mapping (``validation_problems``), so a facility file's errors read like a mission's.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, ValidationError, model_validator

from sms_cli.errors import InputError, Location, Problem
from sms_cli.inputs import absolute
from sms_cli.mission.base import Position3, Rotation3, StrictModel, vector
from sms_cli.mission.units import Angle, Dimensionless, Length, SpecError
from sms_cli.mission.yaml_source import SourceMap, load_yaml

#: Largest deviation from unit length of a quaternion, and from orthonormality of a matrix.
RIGID_TOL = 1e-6

Quaternion4 = vector(Dimensionless, 4, "unit quaternion [x, y, z, w] (scalar last)")


class PoseSpec(StrictModel):
    """A rigid transform world<-frame: ``xyz`` (m) and at most one of ``rpy``, ``quaternion``, ``matrix``
    (none: the identity rotation)."""

    xyz: Position3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    rpy: Rotation3 | None = None
    quaternion: Quaternion4 | None = None
    matrix: list[list[float]] | None = Field(None, description="3x3 rotation matrix, rows")

    @model_validator(mode="after")
    def _check(self):
        given = [k for k in ("rpy", "quaternion", "matrix") if getattr(self, k) is not None]
        if len(given) > 1:
            raise SpecError(f"give one orientation, not {' and '.join(given)}", (given[1],),
                            f"keep '{given[0]}' and remove '{given[1]}'")
        if self.quaternion is not None:
            n = float(np.linalg.norm(self.quaternion))
            if abs(n - 1.0) > RIGID_TOL:
                raise SpecError(f"the quaternion has norm {n:.9g}, not 1 (tolerance {RIGID_TOL:g}): not a rotation",
                                ("quaternion",), "give a unit quaternion [x, y, z, w] (divide each entry by the norm)")
        if self.matrix is not None:
            rows = self.matrix
            if len(rows) != 3 or any(len(r) != 3 for r in rows):
                raise SpecError("the rotation matrix must be 3 rows of 3 numbers", ("matrix",), "write [[r11, r12, r13], [r21, ...], [...]]")
            R = np.array(rows, dtype=float)
            off = float(np.abs(R.T @ R - np.eye(3)).max())
            det = float(np.linalg.det(R))
            if off > RIGID_TOL or det < 0:
                why = f"RᵀR differs from the identity by {off:.3g}" if off > RIGID_TOL else f"its determinant is {det:.6g} (a reflection)"
                raise SpecError(f"the matrix is not a rotation: {why} (tolerance {RIGID_TOL:g})", ("matrix",),
                                "give an orthonormal matrix with determinant +1 (or use rpy: [roll, pitch, yaw])")
        return self

    def rotation(self) -> np.ndarray:
        """Rotation matrix world<-frame (3x3); a quaternion within tolerance is normalised."""
        import pinocchio as pin

        if self.rpy is not None:
            return pin.rpy.rpyToMatrix(*self.rpy)
        if self.quaternion is not None:
            x, y, z, w = self.quaternion
            return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
        if self.matrix is not None:
            U, _, Vt = np.linalg.svd(np.array(self.matrix, dtype=float))  # nearest rotation (within 1e-6 of it)
            return U @ Vt
        return np.eye(3)

    def se3(self):
        """``pinocchio.SE3`` world<-frame."""
        import pinocchio as pin

        return pin.SE3(self.rotation(), np.array(self.xyz, dtype=float))


class RobotSpec(StrictModel):
    """The industrial robot that carries a mock-up (a fixed-base URDF)."""

    urdf: str = Field(description="URDF of the robot, relative to the facility file")
    base: PoseSpec = Field(default_factory=PoseSpec, description="pose of the robot's base link in the facility world")
    tool_frame: str = Field(description="URDF link (or frame) the mock-up is bolted to, e.g. the flange")
    flange_to_mockup: PoseSpec = Field(default_factory=PoseSpec,
                                       description="pose of the mock-up's base frame in the tool frame")
    home: list[Angle] | None = Field(None, description="joint angles the first inverse kinematics starts from "
                                                      "(rad, or with units; default: all zero)")


class MountSpec(StrictModel):
    """One spacecraft mock-up: its pose at t = 0 and, optionally, its robot."""

    mount: PoseSpec = Field(description="pose of the mock-up's base frame in the facility world at t = 0 (g_HW(0))")
    robot: RobotSpec | None = None


class EnvelopeSpec(StrictModel):
    """Where the moving mock-up may go from its start pose: a box (half-ranges along the facility
    world's axes) or a ball (radius), and a largest rotation angle."""

    translation: Position3 | None = Field(None, description="half-ranges along facility x, y, z (m), each > 0")
    radius: Length | None = Field(None, gt=0, description="largest distance from the start position (m)")
    rotation: Angle = Field(gt=0, description="largest rotation angle from the start orientation")

    @model_validator(mode="after")
    def _check(self):
        if (self.translation is None) == (self.radius is None):
            raise SpecError("give either translation (half-ranges per axis) or radius", (),
                            "e.g. translation: [1.0 m, 1.0 m, 0.8 m], or radius: 1.5 m")
        if self.translation is not None:
            for i, h in enumerate(self.translation):
                if not h > 0:
                    raise SpecError(f"a half-range must be > 0 (got {h:g} m)", ("translation", i), "give a positive length")
        return self


class Facility(StrictModel):
    """A HIL facility file."""

    name: str = Field(description="facility name")
    description: str = ""
    world_frame: str = Field("facility", min_length=1, description="name of the facility world frame (MCAP /tf)")
    moving: str = Field("master", description="which mock-up's robot replays the relative motion: master (Vicariotto "
                                              "2023 (6.2): g1_HW = g2_HW g12^-1, the other held), other (the mirror, "
                                              "g2_HW = g1_HW g12), or a spacecraft name")
    spacecraft: dict[str, MountSpec] = Field(description="the two mock-ups, keyed master/other or by spacecraft name")
    envelope: EnvelopeSpec


@dataclass
class LoadedFacility:
    """A validated facility file with where each value came from."""

    facility: Facility
    path: Path
    source: SourceMap
    text: str

    def where(self, *key: Any, prefer_key: bool = False) -> Location:
        return self.source.locate(tuple(key), prefer_key=prefer_key)

    def resolve(self, relative: str, key: tuple[Any, ...]) -> Path:
        """A path written in the facility file, relative to the file's folder."""
        if "\0" in relative:
            raise InputError(problems=[Problem(f"the path {relative!r} holds a NUL character (\\0)", self.where(*key),
                                               ".".join(map(str, key)), "remove the \\0 escape from the quoted path")])
        p = Path(relative)
        return p if p.is_absolute() else absolute(self.path.parent / p)


def load_facility(path: Path | str) -> LoadedFacility:
    """Read and validate a facility file; InputError (exit 2) listing every problem with file:line."""
    from sms_cli.mission.load import validation_problems

    path = absolute(path) if os.path.exists(path) else Path(path)
    data, smap = load_yaml(path, what="facility file")
    if not isinstance(data, dict):
        raise InputError(problems=[Problem("a facility file is a mapping (key: value) at the top level", smap.locate(()),
                                           hint="start from missions/facilities/oos_sim.yaml")])
    try:
        facility = Facility.model_validate(data)
    except ValidationError as exc:
        problems = validation_problems(exc, Facility, smap)
        raise InputError(f"{path}: {len(problems)} problem(s) in the facility file", problems) from None
    return LoadedFacility(facility, path, smap, smap.text)


__all__ = ["Facility", "LoadedFacility", "MountSpec", "PoseSpec", "RobotSpec", "EnvelopeSpec", "load_facility", "RIGID_TOL"]
