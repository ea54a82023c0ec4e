"""What control laws see and return. Frames and units are fixed here, once.

- Attitude: quaternion ``[x, y, z, w]`` of the base in the inertial frame (world ← base),
  scalar last, the Pinocchio/ROS order. Angular velocity ω of the base in the BASE frame (rad/s).
- Base position and linear velocity in the inertial frame (m, m/s), base-link origin.
- Joint positions/rates of the arm in ``SystemModel.arm`` order (rad or m; rad/s or m/s).
- Wheel speeds relative to the base (rad/s), ``SystemModel.wheels`` order.
- An attitude law returns the desired torque on the base (N m, base frame). The simulator turns
  it into wheel torques (allocation, saturation) or applies it directly (thrusters, free-flying).
- An arm law returns joint torques/forces (N m or N), arm order, before saturation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass
class Sensed:
    """Measurements available to the controllers at a control instant (after sensor models)."""

    t: float
    quat: np.ndarray  # (4,) xyzw, world ← base
    omega: np.ndarray  # (3,) base frame
    position: np.ndarray  # (3,) world
    velocity: np.ndarray  # (3,) world
    q_arm: np.ndarray
    qd_arm: np.ndarray
    wheel_speed: np.ndarray
    q: np.ndarray  # full Pinocchio configuration as sensed (model-based laws)
    v: np.ndarray  # full Pinocchio velocity as sensed
    eta: np.ndarray = field(default_factory=lambda: np.zeros(0))  # modal states: only observers may estimate them
    etadot: np.ndarray = field(default_factory=lambda: np.zeros(0))


@dataclass
class AttitudeRef:
    """Attitude reference: quaternion xyzw (world ← reference), ω and ω̇ of the reference, expressed in
    the REFERENCE frame (the laws map them into the base frame)."""

    quat: np.ndarray
    omega: np.ndarray = field(default_factory=lambda: np.zeros(3))
    omega_dot: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass
class ArmRef:
    """Joint-space reference of the arm: positions, rates, accelerations (arm order)."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


@dataclass
class EndEffectorRef:
    """End-effector reference in the inertial frame: position (m), velocity (m/s)."""

    position: np.ndarray
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))


class AttitudeLaw(Protocol):
    """Base attitude control law."""

    def torque(self, s: Sensed, ref: AttitudeRef) -> np.ndarray:  # (3,) N m, base frame
        ...


class ArmLaw(Protocol):
    """Manipulator joint control law."""

    def torque(self, s: Sensed, ref: ArmRef) -> np.ndarray:  # (n_m,) N m or N
        ...
