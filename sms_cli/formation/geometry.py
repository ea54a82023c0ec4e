"""Do the two spacecraft overlap at t = 0? Each link's collision geometry (its visual geometry when it has
none) as oriented boxes — a box exactly, a cylinder or sphere by its enclosing box; meshes are skipped — placed
at the initial configuration, tested pairwise across the two spacecraft with the separating-axis theorem."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from lxml import etree

from sms_cli.errors import InputError, Problem


def link_boxes(sm) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(link, 4x4 pose in the link frame, half extents (3,) m) of every primitive of the SystemModel's URDF."""
    boxes = []
    root = etree.fromstring(sm.urdf_text.encode())
    for link in root.iter("link"):
        shapes = link.findall("collision") or link.findall("visual")
        for shape in shapes:
            geom = shape.find("geometry")
            if geom is None or len(geom) == 0:
                continue
            g = geom[0]
            if g.tag == "box":
                half = 0.5 * np.array([float(x) for x in g.get("size").split()])
            elif g.tag == "cylinder":
                r, h = float(g.get("radius")), float(g.get("length"))
                half = np.array([r, r, 0.5 * h])
            elif g.tag == "sphere":
                half = np.full(3, float(g.get("radius")))
            else:
                continue
            origin = shape.find("origin")
            xyz = [float(x) for x in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()]
            rpy = [float(x) for x in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()]
            boxes.append((link.get("name"), pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz)).homogeneous, half))
    return boxes


def placed_boxes(sm, g_base: pin.SE3) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """(link, centre (3) world, axes (3x3, columns) world, half extents) with the base at ``g_base`` and the
    joints at the SystemModel's initial configuration."""
    q = sm.q0.copy()
    q[:3] = g_base.translation
    q[3:7] = pin.Quaternion(g_base.rotation).coeffs()
    data = sm.model.createData()
    pin.framesForwardKinematics(sm.model, data, q)
    out = []
    for link, local, half in link_boxes(sm):
        fid = sm.link_frames.get(link)
        if fid is None:
            continue
        world = data.oMf[fid].homogeneous @ local
        out.append((link, world[:3, 3], world[:3, :3], half))
    return out


def boxes_overlap(c1, A1, h1, c2, A2, h2, margin: float = 0.0) -> bool:
    """Separating-axis test of two oriented boxes (centres c, column axes A, half extents h); True when they
    intersect by more than ``margin`` (m) along every candidate axis."""
    d = c2 - c1
    axes = [A1[:, i] for i in range(3)] + [A2[:, i] for i in range(3)]
    axes += [np.cross(A1[:, i], A2[:, j]) for i in range(3) for j in range(3)]
    for a in axes:
        n = np.linalg.norm(a)
        if n < 1e-9:
            continue
        a = a / n
        r1 = np.sum(h1 * np.abs(A1.T @ a))
        r2 = np.sum(h2 * np.abs(A2.T @ a))
        if abs(d @ a) >= r1 + r2 - margin:
            return False
    return True


def check_no_overlap(loaded, servicer, client) -> None:
    """InputError (exit 2) at ``client.pose`` when a body of one spacecraft intersects one of the other at t = 0."""
    from sms_cli.formation.client import initial_poses

    g_s, g_c = initial_poses(loaded.mission, servicer)
    for ls, cs, As, hs in placed_boxes(servicer, g_s):
        for lc, cc, Ac, hc in placed_boxes(client, g_c):
            if boxes_overlap(cs, As, hs, cc, Ac, hc, margin=1e-6):
                gap = float(np.linalg.norm(cc - cs))
                raise InputError(problems=[Problem(
                    f"the spacecraft overlap at t = 0: the servicer's link '{ls}' intersects the client's link '{lc}' "
                    f"(their centres are {gap:.3g} m apart)", loaded.source.locate(("client", "pose", "position")),
                    "client.pose", "move the client further from the servicer (client.pose.position, m, in the "
                                   "servicer's base frame)")])
