"""Pinocchio model construction: URDF (linted) + free-flyer base + mission-declared wheels
and payload inertias. Zero gravity.

Pinocchio's URDF parser merges links attached by fixed joints into their parent body and
keeps them as frames; every URDF link name is therefore a frame name of the model.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from sms_cli.errors import InputError, Location, Problem
from sms_cli.inertia import inertia_tensor
from sms_cli.model.conventions import euler_zyx_to_matrix


@contextlib.contextmanager
def captured_c_stderr():
    """Capture what C/C++ code writes to file descriptor 2 (Pinocchio/urdfdom diagnostics)."""
    out: dict[str, str] = {"text": ""}
    try:
        fd = 2
        saved = os.dup(fd)
    except OSError:  # no real stderr (some embedded runners)
        yield out
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), fd)
        try:
            yield out
        finally:
            os.dup2(saved, fd)
            os.close(saved)
            tmp.seek(0)
            out["text"] = tmp.read().decode("utf-8", "replace").strip()


def build_rigid_model(xml: str, urdf_path) -> pin.Model:
    """Free-flyer Pinocchio model from cleaned URDF XML; Pinocchio's own errors are shown."""
    with captured_c_stderr() as err:
        try:
            model = pin.buildModelFromXML(xml, pin.JointModelFreeFlyer())
            failure = None
        except Exception as exc:  # noqa: BLE001 - pinocchio raises ValueError/RuntimeError/...
            model, failure = None, exc
    if failure is not None:
        detail = _urdfdom_message(err["text"]) or "the URDF parser refused the file"
        raise InputError(problems=[Problem(f"Pinocchio could not build the model: {detail}", Location(urdf_path),
                                           hint="the URDF lint found nothing wrong: please report this file")])
    model.gravity = pin.Motion.Zero()
    return model


def _urdfdom_message(text: str) -> str:
    """urdfdom's diagnostics without its own C++ source locations ("at line 243 in …/model.cpp")."""
    lines = [ln.strip() for ln in text.splitlines()]
    lines = [re.sub(r"^(Error|Warning):\s*", "", ln) for ln in lines if ln and not re.match(r"at line \d+ in ", ln)]
    return "; ".join(dict.fromkeys(lines))


#: Frame types in the order a name is looked up: a URDF link is a BODY frame, a fixed joint a
#: FIXED_JOINT frame, a movable joint a JOINT frame. A joint and a link may share a name.
_FRAME_PREFERENCE = (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT, pin.FrameType.JOINT,
                     pin.FrameType.SENSOR)


def find_frame(model: pin.Model, name: str) -> int | None:
    """Frame id of a name, links first (see ``_FRAME_PREFERENCE``); None when no frame has it."""
    for kind in _FRAME_PREFERENCE:
        if model.existFrame(name, kind):
            return model.getFrameId(name, kind)
    return None


@dataclass
class AddedRotor:
    """A wheel rotor to add as a revolute joint (frames: mount link frame)."""

    name: str
    mount_frame: str
    position: np.ndarray  # in the mount link frame (m)
    axis: np.ndarray  # unit, in the mount link frame
    spin_inertia: float
    transverse_inertia: float
    mass: float


def rotation_z_to(axis: np.ndarray) -> np.ndarray:
    """A rotation matrix whose z column is ``axis`` (unit)."""
    z = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def frame_id(model: pin.Model, name: str, what: str, where: Location | None = None) -> int:
    """Frame id of a URDF link name (links first, then other frames); InputError with a suggestion if none."""
    fid = find_frame(model, name)
    if fid is not None:
        return fid
    import difflib

    names = [f.name for f in model.frames]
    close = difflib.get_close_matches(name, names, n=1)
    raise InputError(problems=[Problem(f"{what}: no link or frame named '{name}' in the robot", where,
                                       hint=f"did you mean '{close[0]}'?" if close else "use a URDF link name")])


def add_rotor(model: pin.Model, rotor: AddedRotor, where: Location | None = None) -> int:
    """Append a wheel as a revolute joint about its axis; return the joint id."""
    fid = frame_id(model, rotor.mount_frame, f"wheel '{rotor.name}' mount", where)
    frame = model.frames[fid]
    placement = frame.placement * pin.SE3(rotation_z_to(rotor.axis), np.asarray(rotor.position, float))
    jid = model.addJoint(frame.parentJoint, pin.JointModelRZ(), placement, rotor.name,
                         np.array([1e10]), np.array([1e10]), np.array([-1e10]), np.array([1e10]))
    it, isp = rotor.transverse_inertia, rotor.spin_inertia
    inertia = pin.Inertia(rotor.mass, np.zeros(3), np.diag([it, it, isp]))
    model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
    joint_frame = model.addJointFrame(jid, fid)
    model.addBodyFrame(rotor_link_name(rotor.name), jid, pin.SE3.Identity(), joint_frame)
    return jid


def rotor_link_name(wheel_name: str) -> str:
    """Link (body frame) name of a compiler-added wheel rotor; the joint carries the wheel name."""
    return f"{wheel_name}_rotor"


def payload_inertia(mass: float, com: np.ndarray, inertia6: list[float]) -> pin.Inertia:
    """Pinocchio spatial inertia of a payload: inertia6 about its CoM, in the attach frame's axes."""
    return pin.Inertia(mass, np.asarray(com, float), inertia_tensor(*inertia6))


def link_inertia(mass: float, com, inertia6, rpy=(0.0, 0.0, 0.0)) -> pin.Inertia:
    """Spatial inertia of a URDF link in its link frame: ``inertia6`` (sms_cli.inertia convention) about
    the CoM ``com`` (m, link frame), in the axes of the inertial frame rotated by URDF ``rpy`` (rad)."""
    R = euler_zyx_to_matrix(*rpy)
    return spatial_inertia(mass, com, R @ inertia_tensor(*inertia6) @ R.T)


def spatial_inertia(mass: float, com, tensor: np.ndarray) -> pin.Inertia:
    """``pin.Inertia(mass, com, tensor)`` (tensor about the CoM) without the constructor's positivity
    check: the URDF lint accepts moments that are negative by round-off, as Pinocchio's parser does."""
    Y = pin.Inertia.Zero()
    Y.mass, Y.lever, Y.inertia = float(mass), np.asarray(com, float), np.asarray(tensor, float)
    return Y


def replace_link_inertia(model: pin.Model, fid: int, old: pin.Inertia, new: pin.Inertia) -> None:
    """Swap a link's inertia ``old`` for ``new`` (both in the link frame) in the body that carries it:
    the parent joint of its frame ``fid``. Pinocchio merges a link fixed to its parent into that
    parent's body, at the link frame's placement; the other links of the body keep their share."""
    frame = model.frames[fid]
    j = frame.parentJoint
    params = (model.inertias[j].toDynamicParameters() - frame.placement.act(old).toDynamicParameters()
              + frame.placement.act(new).toDynamicParameters())
    model.inertias[j] = pin.Inertia.FromDynamicParameters(params)
