"""A Pinocchio model flattened into arrays for the compiled kernels (``dynamics.py``).

Supported: a free-flyer root joint followed by 1-DoF joints (revolute about any axis, bounded
or unbounded (cos, sin), prismatic along any axis), no gravity. Frames are Pinocchio's:
joint i's placement in its parent joint (``jointPlacements``), body inertia in the joint frame
(``inertias``), motion vectors linear first ``[v; ω]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

# joint kinds in the kernels
FREE_FLYER, REVOLUTE, REVOLUTE_UNBOUNDED, PRISMATIC = 0, 1, 2, 3

def _joint_kind(model: pin.Model, j: int) -> tuple[int, tuple[float, float, float]] | None:
    """(kind, unit axis in the joint frame) of joint j, None when unsupported. The axis is read off
    the joint's motion subspace S (6×1), which covers the aligned and unaligned variants."""
    name = model.joints[j].shortname()
    if name == "JointModelFreeFlyer":
        return FREE_FLYER, (0.0, 0.0, 0.0)
    if model.joints[j].nv != 1:
        return None
    data = model.joints[j].createData()
    model.joints[j].calc(data, pin.neutral(model))
    S = np.asarray(data.S).ravel()
    if name.startswith("JointModelRUB") or name == "JointModelRevoluteUnboundedUnaligned":
        kind = REVOLUTE_UNBOUNDED
    elif name.startswith("JointModelR") and name != "JointModelRevoluteUnboundedUnaligned":
        kind = REVOLUTE
    elif name.startswith("JointModelP"):
        kind = PRISMATIC
    else:
        return None
    axis = S[:3] if kind == PRISMATIC else S[3:]
    if abs(np.linalg.norm(axis) - 1.0) > 1e-12 or np.linalg.norm(S[3:] if kind == PRISMATIC else S[:3]) > 0:
        return None
    return kind, tuple(float(x) for x in axis)


@dataclass
class Tree:
    """Arrays of joints 1..n (index 0 of each array is joint 1, the free-flyer root)."""

    parent: np.ndarray  # (n,) int: index of the parent joint in these arrays, -1 for the root
    kind: np.ndarray  # (n,) int
    axis: np.ndarray  # (n, 3) joint axis in the joint frame
    place_R: np.ndarray  # (n, 3, 3) joint placement in the parent joint frame
    place_p: np.ndarray  # (n, 3)
    inertia: np.ndarray  # (n, 6, 6) spatial inertia of the body at the joint origin, joint frame
    leaf_IA: np.ndarray  # (n, 6, 6) constant articulated inertia a leaf passes to its parent (NaN: not constant)
    mass: np.ndarray  # (n,)
    com: np.ndarray  # (n, 3) body CoM in the joint frame
    idx_q: np.ndarray  # (n,) int
    idx_v: np.ndarray  # (n,) int
    armature: np.ndarray  # (nv,) rotor inertia added on the diagonal of M
    nq: int
    nv: int


def spatial_inertia(mass: float, com: np.ndarray, inertia_com: np.ndarray) -> np.ndarray:
    """6×6 inertia at the frame origin, linear first: [[m 1, −m [c]×], [m [c]×, I_c − m [c]×²]]."""
    c = np.asarray(com, float)
    cx = pin.skew(c)
    out = np.zeros((6, 6))
    out[:3, :3] = mass * np.eye(3)
    out[:3, 3:] = -mass * cx
    out[3:, :3] = mass * cx
    out[3:, 3:] = np.asarray(inertia_com, float) - mass * cx @ cx
    return out


def unsupported_reason(model: pin.Model) -> str | None:
    """Why the compiled kernels cannot run this model (None when they can)."""
    if np.any(np.asarray(model.gravity.linear) != 0) or np.any(np.asarray(model.gravity.angular) != 0):
        return "the model has gravity"
    if model.njoints < 2 or model.joints[1].shortname() != "JointModelFreeFlyer":
        return "the root joint is not a free flyer"
    for j in range(2, model.njoints):
        kind = _joint_kind(model, j)
        if kind is None or kind[0] == FREE_FLYER:
            return f"joint {model.names[j]} ({model.joints[j].shortname()}) is not supported by the compiled kernels"
        if model.parents[j] == 0:
            return f"joint {model.names[j]} hangs from the world, not from the free-flying base"
    return None


def flatten(model: pin.Model) -> Tree:
    """The arrays of ``model`` (check ``unsupported_reason`` first)."""
    why = unsupported_reason(model)
    if why:
        raise ValueError(why)
    n = model.njoints - 1
    parent = np.array([model.parents[j] - 1 for j in range(1, n + 1)], dtype=np.int64)
    kinds, axes = zip(*(_joint_kind(model, j) for j in range(1, n + 1)))
    place_R = np.array([model.jointPlacements[j].rotation for j in range(1, n + 1)])
    place_p = np.array([model.jointPlacements[j].translation for j in range(1, n + 1)])
    mass = np.array([model.inertias[j].mass for j in range(1, n + 1)])
    com = np.array([model.inertias[j].lever for j in range(1, n + 1)])
    inertia = np.array([spatial_inertia(model.inertias[j].mass, model.inertias[j].lever, model.inertias[j].inertia)
                        for j in range(1, n + 1)])
    kind = np.array(kinds, dtype=np.int64)
    axis = np.array(axes, float)
    armature = np.asarray(model.armature, float).copy()
    idx_v = np.array([model.idx_vs[j] for j in range(1, n + 1)], dtype=np.int64)
    leaf_IA = _constant_leaf_inertias(parent, kind, axis, place_R, place_p, inertia, armature, idx_v)
    return Tree(parent=parent, kind=kind, axis=axis, leaf_IA=leaf_IA,
                place_R=np.ascontiguousarray(place_R), place_p=np.ascontiguousarray(place_p), inertia=inertia,
                mass=mass, com=np.ascontiguousarray(com),
                idx_q=np.array([model.idx_qs[j] for j in range(1, n + 1)], dtype=np.int64),
                idx_v=idx_v, armature=armature, nq=model.nq, nv=model.nv)


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    return pin.AngleAxis(angle, np.asarray(axis, float)).toRotationMatrix()


def _constant_leaf_inertias(parent, kind, axis, place_R, place_p, inertia, armature, idx_v) -> np.ndarray:
    """For a revolute joint with no child whose articulated inertia I − U Uᵀ/D (U = I S) does not
    change when the body turns about the joint axis (a rotor: axisymmetric about its spin axis),
    the inertia ABA passes to the parent, Xᵀ (I − U Uᵀ/D) X, is a constant (X: the joint's fixed
    placement); NaN marks the others. It saves ABA's most expensive step for reaction wheels."""
    from sms_cli.sim.compiled.dynamics import add_inertia_to_parent

    n = parent.size
    out = np.full((n, 6, 6), np.nan)
    has_child = np.zeros(n, dtype=bool)
    has_child[parent[parent >= 0]] = True
    for i in range(n):
        if has_child[i] or parent[i] < 0 or kind[i] not in (REVOLUTE, REVOLUTE_UNBOUNDED):
            continue
        S = np.concatenate([np.zeros(3), axis[i]])
        U = inertia[i] @ S
        Ia = inertia[i] - np.outer(U, U) / (S @ U + armature[idx_v[i]])
        scale = max(np.abs(Ia).max(), 1e-300)
        symmetric = True
        for angle in (0.7, 2.3):
            R = _axis_rotation(axis[i], angle)
            B = np.zeros((6, 6))
            B[:3, :3] = B[3:, 3:] = R
            if np.abs(B @ Ia @ B.T - Ia).max() > 1e-12 * scale:
                symmetric = False
        if symmetric:  # the transform ABA applies, at joint angle 0 (the joint's fixed placement)
            out[i] = 0.0
            add_inertia_to_parent(np.ascontiguousarray(place_R[i]), np.ascontiguousarray(place_p[i]), Ia,
                                  np.empty((6, 6)), np.empty((6, 6)), out[i])
            out[i] = np.tril(out[i]) + np.tril(out[i], -1).T  # add_inertia_to_parent fills the lower triangle
    return out


def frame_table(model: pin.Model, frame_ids: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(joint index in the Tree arrays, rotation, translation) of each frame's placement in its joint."""
    joint = np.array([model.frames[f].parentJoint - 1 for f in frame_ids], dtype=np.int64)
    R = np.array([model.frames[f].placement.rotation for f in frame_ids]).reshape(len(frame_ids), 3, 3)
    p = np.array([model.frames[f].placement.translation for f in frame_ids]).reshape(len(frame_ids), 3)
    return joint, np.ascontiguousarray(R), np.ascontiguousarray(p)
