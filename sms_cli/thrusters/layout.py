"""The thruster set as the base sees it: application points, force directions, limits, and the 6 × n
map from thrust to base wrench.

Frame: the base joint frame (Pinocchio's FreeFlyer frame, the frame of ``tau[:6]``): a wrench is
``[f; n]`` with ``n`` about the base-link origin, N and N m. Thruster ``i`` firing at thrust ``x_i``
(N) applies ``x_i b_i`` with ``b_i = [d_i; r_i × d_i]`` (``r_i`` position, m; ``d_i`` unit force
direction on the spacecraft). Thrusters must be on the base body (the base link or a link fixed to it),
so ``B`` is constant.

The ``cube`` preset (Vicariotto 2023 L546: "three orthogonal thrusters at each of the eight edges of
the cube", i.e. its corners; notes §9 item 7): the corner ``c = c0 + (s/2)(σx, σy, σz)``, σ = ±1,
``c0`` the base CoM, carries three thrusters pushing the spacecraft toward the cube's inside along
each axis, ``d = −σx e_x``, ``−σy e_y``, ``−σz e_z`` (exhaust pointing out of the cube). Pure forces
up to ±4F per axis (the four thrusters of one face) and pure torques up to ±4F s per axis (eight
thrusters, each with lever s/2) — full 6-D authority.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

G0 = 9.80665  # m/s², standard gravity (Isp definition)


@dataclass
class ThrusterSet:
    """n thrusters in the base joint frame (see the module docstring); arrays of length n or n × 3."""

    names: list[str]
    position: np.ndarray  # (n, 3) m
    direction: np.ndarray  # (n, 3) unit
    max_force: np.ndarray  # (n,) N
    isp: np.ndarray  # (n,) s
    firing_cycle: float  # s
    mib: float  # s, minimum on-time
    quantization: float  # on-time step / firing cycle
    tank_position: np.ndarray  # (3,) m, base joint frame
    propellant: float  # kg at t = 0

    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def B(self) -> np.ndarray:
        """6 × n: base wrench [f; n] per newton of each thruster's thrust."""
        return np.vstack([self.direction.T, np.cross(self.position, self.direction).T])

    @property
    def mass_flow(self) -> np.ndarray:
        """(n,) kg/s of each thruster while on: F / (Isp g0)."""
        return self.max_force / (self.isp * G0)


def cube_thrusters(size: float, force: float, isp: float, centre=(0.0, 0.0, 0.0)):
    """The 24 (name, position, direction, force, isp) of the cube preset (module docstring)."""
    out = []
    c0 = np.asarray(centre, float)
    axes = "xyz"
    for sx, sy, sz in product((1, -1), repeat=3):
        sig = np.array([sx, sy, sz], float)
        corner = c0 + 0.5 * size * sig
        tag = "".join("p" if s > 0 else "m" for s in sig)
        for k in range(3):
            d = np.zeros(3)
            d[k] = -sig[k]
            out.append((f"c{tag}_{axes[k]}", corner.copy(), d, force, isp))
    return out
