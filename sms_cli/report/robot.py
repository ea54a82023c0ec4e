"""Drawing of the robot in its initial configuration (matplotlib 3D, world frame, metres).

Draws the URDF visual primitives (box, cylinder, sphere; meshes are shown by their link origin
only) placed by Pinocchio's forward kinematics at ``q0``, the kinematic tree as segments between
link origins, the joints as dots, the end effector, the reaction-wheel spin axes and the base
triad (x red, y green, z blue).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sms_cli.report import figstyle as S


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _floats(text: str | None, n: int) -> np.ndarray:
    return np.array([float(x) for x in text.split()]) if text else np.zeros(n)


def visual_primitives(urdf_text: str) -> list[tuple[str, str, np.ndarray, np.ndarray, np.ndarray]]:
    """(link, kind, size params, R, p) of every visual primitive, in the link frame."""
    from lxml import etree

    root = etree.fromstring(urdf_text.encode("utf-8"))
    out = []
    for link in root.findall("link"):
        for vis in link.findall("visual"):
            origin = vis.find("origin")
            xyz = _floats(origin.get("xyz") if origin is not None else None, 3)
            rpy = _floats(origin.get("rpy") if origin is not None else None, 3)
            geom = vis.find("geometry")
            if geom is None or len(geom) == 0:
                continue
            g = geom[0]
            if g.tag == "box":
                size = _floats(g.get("size"), 3)
            elif g.tag == "cylinder":
                size = np.array([float(g.get("radius", 0)), float(g.get("length", 0))])
            elif g.tag == "sphere":
                size = np.array([float(g.get("radius", 0))])
            else:
                continue
            out.append((link.get("name"), g.tag, size, _rpy(*rpy), xyz))
    return out


def _box_faces(size: np.ndarray) -> list[np.ndarray]:
    hx, hy, hz = size / 2
    c = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    idx = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return [c[list(f)] for f in idx]


def _cylinder_faces(radius: float, length: float, n: int = 18) -> list[np.ndarray]:
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(n)], axis=1)
    top, bot = ring + [0, 0, length / 2], ring - [0, 0, length / 2]
    sides = [np.array([bot[i], bot[(i + 1) % n], top[(i + 1) % n], top[i]]) for i in range(n)]
    return sides + [top, bot]


@S.styled
def draw_robot(sm, target: Path | None = None, title: str = "") -> bytes:
    """PNG bytes of the robot at ``sm.q0`` (also written atomically to ``target`` when given)."""
    import pinocchio as pin
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    q = sm.q0
    pin.forwardKinematics(sm.model, sm.data, q)
    pin.updateFramePlacements(sm.model, sm.data)

    def pose(name: str):
        fid = sm.link_frames.get(name)
        if fid is None:
            return None
        M = sm.data.oMf[fid]
        return M.rotation.copy(), M.translation.copy()

    fig = S.new_figure(S.HALF_PX, 470)
    ax = fig.add_subplot(111, projection="3d")
    pts = []
    colors = {"box": "#8fa9c9", "cylinder": "#d9a86c", "sphere": "#9fc98f"}
    for link, kind, size, R, p in visual_primitives(sm.urdf_text):
        pl = pose(link)
        if pl is None:
            continue
        Rl, pw = pl
        Rw, tw = Rl @ R, pw + Rl @ p
        if kind == "sphere":
            ax.scatter(*tw, s=60, color=colors[kind], edgecolor="k", linewidth=0.4)
            pts.append(tw)
            continue
        faces = _box_faces(size) if kind == "box" else _cylinder_faces(size[0], size[1])
        world = [f @ Rw.T + tw for f in faces]
        ax.add_collection3d(Poly3DCollection(world, facecolor=colors[kind], edgecolor="0.35", linewidth=0.15, alpha=0.35))
        pts.extend(np.vstack(world))
    origins = {}
    for link in sm.link_parents:
        pl = pose(link)
        if pl is not None:
            origins[link] = pl[1]
    for link, parent in sm.link_parents.items():
        if link in origins and parent in origins:
            a, b = origins[parent], origins[link]
            ax.plot(*np.stack([a, b]).T, color="k", lw=1.6)
    if origins:
        o = np.array(list(origins.values()))
        ax.scatter(o[:, 0], o[:, 1], o[:, 2], s=10, color="k", label="link frames / joints")
        pts.extend(o)
    ee = sm.data.oMf[sm.ee_frame_id].translation
    ax.scatter(*ee, s=90, marker="*", color="crimson", label=f"end effector ({sm.model.frames[sm.ee_frame_id].name})", zorder=5)
    pts.append(ee)
    P = np.array(pts) if pts else np.zeros((1, 3))
    span = float(np.max(P.max(axis=0) - P.min(axis=0))) or 1.0
    Rb, pb = sm.data.oMf[sm.base_frame_id].rotation, sm.data.oMf[sm.base_frame_id].translation
    for k, c in enumerate(("r", "g", "b")):
        ax.quiver(*pb, *(Rb[:, k] * 0.25 * span), color=c, lw=1.5, arrow_length_ratio=0.15)
    if sm.wheels:
        for i, w in enumerate(sm.wheels):
            a = Rb @ np.asarray(w.axis, dtype=float)
            ax.quiver(*pb, *(a * 0.18 * span), color="purple", lw=1.0, arrow_length_ratio=0.2,
                      label="wheel spin axes" if i == 0 else None)
    mid = (P.max(axis=0) + P.min(axis=0)) / 2
    for setter, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
        setter(m - span / 2, m + span / 2)
    S.box3d(ax)
    ax.set_title(title or f"{sm.name}: initial configuration, world frame")
    fig.legend(loc="outside lower center", ncols=2, title="base triad x, y, z: red, green, blue")
    data = S.render(fig)
    if target is not None:
        from sms_cli.results import write_bytes_atomic

        write_bytes_atomic(target, data)
    return data
