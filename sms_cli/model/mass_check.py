"""Is the assembled rigid model usable? Its joint-space mass matrix must be positive definite.

A singular mass matrix means some motion costs no kinetic energy: a moving link that carries no
mass or inertia about its joint (a visual-only link from a xacro, a point mass on its own joint
axis), or two joints that move the same inertia. ``diagnose`` names the joints and links in the
null space of the matrix and what to do. ``add_placeholders`` is the kinematics-only way out
(``robot.kinematics_only``): each such body gets a tiny documented inertia so that kinematic
studies run; stages that need the dynamics refuse the model.

Units: kg, m, kg m²; the mass matrix is Pinocchio's (free-flyer velocity in the base frame).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from sms_cli.errors import Location, Problem

#: Relative size of the smallest eigenvalue below which the mass matrix is singular.
SINGULAR_RTOL = 1e-12
#: Placeholder inertia of a massless moving body in a kinematics-only model: this fraction of the
#: robot's mass (1e-6 kg if the robot is massless) as a solid sphere of radius PLACEHOLDER_RADIUS
#: centred on the body's joint.
PLACEHOLDER_MASS_FRACTION = 1e-6
PLACEHOLDER_RADIUS = 0.05


def mass_matrix(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """The symmetric joint-space mass matrix at q."""
    M = pin.crba(model, model.createData(), q)
    return np.triu(M) + np.triu(M, 1).T


def _joint_dofs(model: pin.Model, j: int) -> list[int]:
    return list(range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv))


def _null_joints(model: pin.Model, M: np.ndarray) -> list[list[int]]:
    """Joint ids at fault when M is not positive definite: first each joint whose own diagonal is zero
    (it moves no inertia: one group each), then the joints spanning each null direction of the rest."""
    if not np.all(np.isfinite(M)):
        return [[1]]
    scale = max(float(np.abs(M).max()), 1e-300)
    tiny = SINGULAR_RTOL * scale
    diag = np.diag(M)
    alone = [j for j in range(1, model.njoints) if np.any(diag[_joint_dofs(model, j)] <= tiny)]
    groups = [[j] for j in alone]
    keep = [d for d in range(model.nv) if not any(d in _joint_dofs(model, j) for j in alone)]
    if not keep:
        return groups
    eig, vec = np.linalg.eigh(M[np.ix_(keep, keep)])
    for k in np.flatnonzero(eig <= tiny):
        v = np.abs(vec[:, k])
        dofs = {keep[i] for i in np.flatnonzero(v > 0.3 * v.max())}
        joints = [j for j in range(1, model.njoints) if dofs & set(_joint_dofs(model, j))]
        if joints and joints not in groups:
            groups.append(joints)
    return groups


def _body_links(info, joint_name: str) -> list[str]:
    """The URDF links moved rigidly by a joint: its child and the links fixed below it."""
    if joint_name not in info.joints:
        return []
    out, stack = [], [info.joints[joint_name].child]
    while stack:
        link = stack.pop()
        out.append(link)
        stack.extend(info.joints[jn].child for jn in info.children.get(link, []) if info.joints[jn].kind == "fixed")
    return out


def diagnose(model: pin.Model, q: np.ndarray, info, kinematics_hint: bool = True) -> list[Problem]:
    """Why the rigid mass matrix at q is not positive definite, in terms of the robot; [] if it is."""
    M = mass_matrix(model, q)
    problems = []
    fix_kin = "; or set robot.kinematics_only: true for workspace and kinematic-index studies" if kinematics_hint else ""
    for joints in _null_joints(model, M):
        if joints == [1] or (1 in joints and len(joints) == 1):
            problems.append(Problem(
                "the robot has no mass or no rotational inertia as a free body: the base and everything fixed to it "
                "carry none", Location(info.path, info.links.get(info.root, 0)),
                hint=f"give the base link '{info.root}' an <inertial> with its mass and inertia"))
            continue
        names = [model.names[j] for j in joints if j != 1]
        first = names[0]
        jline = info.joints[first].line if first in info.joints else 0
        links = _body_links(info, first)
        lines = ("link" + ("s " if len(links) > 1 else " ") + ", ".join(f"'{ln}' (line {info.links[ln]})" for ln in links[:4])
                 + (" …" if len(links) > 4 else "")) if links else f"the rotor of '{first}'"
        if len(names) == 1:
            problems.append(Problem(
                f"joint '{first}' moves {lines}, and nothing it moves carries mass or inertia about its axis: "
                "the mass matrix is singular", Location(info.path, jline),
                hint=f"add an <inertial> to link '{links[0] if links else first}', or make joint '{first}' fixed if "
                     f"it does not move{fix_kin}"))
        else:
            problems.append(Problem(
                f"joints {', '.join(repr(n) for n in names)} move the same inertia (their motions are not independent: "
                f"typically a massless link between them; the first moves {lines}): the mass matrix is singular",
                Location(info.path, jline),
                hint=f"add an <inertial> to link '{links[0] if links else first}' or fix one of the joints{fix_kin}"))
    return problems


def add_placeholders(model: pin.Model, q: np.ndarray, info) -> list[str]:
    """Give each massless moving body a placeholder inertia until the mass matrix is positive definite.

    Returns the URDF links (or joint names) that received one. Leaves the model unchanged when it is usable."""
    total = sum(model.inertias[j].mass for j in range(model.njoints))
    mass = PLACEHOLDER_MASS_FRACTION * total if total > 0 else 1e-6
    placeholder = pin.Inertia.FromSphere(mass, PLACEHOLDER_RADIUS)
    given: list[str] = []
    for _ in range(model.njoints):
        groups = _null_joints(model, mass_matrix(model, q))
        if not groups:
            break
        for joints in groups:
            j = joints[-1]  # the outermost joint of the group: its body is the massless one
            model.inertias[j] = model.inertias[j] + placeholder
            links = _body_links(info, model.names[j])
            given.append(links[0] if links else model.names[j])
    return given
