"""Batched rigid-transform algebra for the recorder: world poses → parent-relative poses.

A pose row is ``[x, y, z, qx, qy, qz, qw]``: the position (m) of a frame's origin and the unit
quaternion (scalar last, Hamilton convention, as Pinocchio's ``SE3ToXYZQUAT`` and Foxglove) of
its orientation, both in the world frame. The relative pose of child c in parent p is
``T_p⁻¹ T_c``: translation ``R_pᵀ (r_c − r_p)``, rotation ``q_p* ⊗ q_c``.

Two implementations with the same result: vectorised with constant tensors (≈ 10 µs whatever
the number of links: numpy call overhead) and a plain-Python loop (≈ 0.7 µs per link), used
for small trees.
"""

from __future__ import annotations

import numpy as np


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of quaternion ``q = [x, y, z, w]`` (homogeneous form: exact for unit q)."""
    x, y, z, w = (float(v) for v in q)
    return np.array(
        [
            [x * x + w * w - y * y - z * z, 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), y * y + w * w - x * x - z * z, 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), z * z + w * w - x * x - y * y],
        ]
    )


def left_product_matrix(p: np.ndarray) -> np.ndarray:
    """4×4 matrix L(p) with ``p ⊗ q = L(p) q`` for quaternions ``[x, y, z, w]``."""
    x, y, z, w = (float(v) for v in p)
    return np.array([[w, -z, y, x], [z, w, -x, y], [-y, x, w, z], [-x, -y, -z, w]])


def _transpose_rotation_tensor() -> np.ndarray:
    """C (16, 9) with ``Rᵀ(q).ravel() = (q qᵀ).ravel() @ C`` (polarisation of a quadratic form)."""
    eye = np.eye(4)
    f = [rotation_matrix(e).T.ravel() for e in eye]
    c = np.zeros((16, 9))
    for a in range(4):
        for b in range(4):
            if a == b:
                c[4 * a + b] = f[a]
            else:
                c[4 * a + b] = 0.5 * (rotation_matrix(eye[a] + eye[b]).T.ravel() - f[a] - f[b])
    return c


def _conjugate_product_tensor() -> np.ndarray:
    """B (4, 16) with ``L(q*).ravel() = q @ B``: the left product by the conjugate is linear in q."""
    conj = np.array([-1.0, -1.0, -1.0, 1.0])
    return np.stack([left_product_matrix(conj * e).ravel() for e in np.eye(4)])


_C = _transpose_rotation_tensor()
_B = _conjugate_product_tensor()


def _relative_python(world: list[list[float]], parents: list[int]) -> list[float]:
    """Plain-Python ``T_p⁻¹ T_c`` per link (rows as lists); returns the flat (n·7) result."""
    out: list[float] = []
    for child, p in zip(world, parents):
        if p < 0:
            out += child
            continue
        px, py, pz, ux, uy, uz, w = world[p]
        dx, dy, dz = child[0] - px, child[1] - py, child[2] - pz
        ux, uy, uz = -ux, -uy, -uz  # conjugate: rotate by R_pᵀ
        tx, ty, tz = 2.0 * (uy * dz - uz * dy), 2.0 * (uz * dx - ux * dz), 2.0 * (ux * dy - uy * dx)
        qx, qy, qz, qw = child[3], child[4], child[5], child[6]
        out += (
            dx + w * tx + (uy * tz - uz * ty),
            dy + w * ty + (uz * tx - ux * tz),
            dz + w * tz + (ux * ty - uy * tx),
            w * qx + qw * ux + (uy * qz - uz * qy),
            w * qy + qw * uy + (uz * qx - ux * qz),
            w * qz + qw * uz + (ux * qy - uy * qx),
            w * qw - ux * qx - uy * qy - uz * qz,
        )
    return out


class RelativePoses:
    """World poses of n links → each link's pose in its parent's frame (parent −1 = world).

    ``parents[i]`` is the row of link i's parent in the same array, or −1 for the world frame.
    ``__call__`` returns a new (n, 7) array; trees with at most ``python_below`` links whose
    parent is not the world use the plain-Python loop, others the vectorised form.
    """

    def __init__(self, parents: list[int], python_below: int = 12) -> None:
        n = len(parents)
        self.n = n
        self._parents = list(parents)
        self._python = sum(p >= 0 for p in parents) < python_below
        self._pidx = np.array([p if p >= 0 else n for p in parents], dtype=np.intp)
        self._ext = np.zeros((n + 1, 7))
        self._ext[n, 6] = 1.0  # the world frame: identity pose

    @property
    def parents(self) -> list[int]:
        return list(self._parents)

    def __call__(self, world: np.ndarray) -> np.ndarray:
        n = self.n
        if self._python:
            return np.array(_relative_python(world.tolist(), self._parents)).reshape(n, 7)
        ext = self._ext
        ext[:n] = world
        parent = ext[self._pidx]
        qp = parent[:, 3:]
        d = world[:, :3] - parent[:, :3]
        qq = (qp[:, :, None] * qp[:, None, :]).reshape(n, 16)
        rt = (qq @ _C).reshape(n, 3, 3)
        out = np.empty((n, 7))
        out[:, :3] = (rt @ d[:, :, None])[:, :, 0]
        lp = (qp @ _B).reshape(n, 4, 4)
        out[:, 3:] = (lp @ world[:, 3:, None])[:, :, 0]
        return out


__all__ = ["RelativePoses", "rotation_matrix", "left_product_matrix"]
