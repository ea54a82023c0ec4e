"""Propellant drawn from the tank: the base body loses a point mass at the tank location.

Mass flow of thruster i while on: ṁ_i = F_i / (Isp_i g0) (kg/s). The base body's spatial inertia
(Pinocchio ``model.inertias[base joint]``, base joint frame) is that of the loaded spacecraft minus a
point mass m_removed at the tank position; as for a released payload (``SystemModel.detach_payload``)
the body's dynamic parameters are changed in place and the velocity state is kept (the propellant
leaves with the velocity of the tank, so the remaining body's velocity does not jump: the rocket
equation m v̇ = F). ``set_removed`` makes the model hold a given removed mass (linear in the
dynamic parameters, so payloads attached or released meanwhile stay exact).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


class Tank:
    """Point-mass propellant removal from the base body of ``sm`` (see the module docstring)."""

    def __init__(self, sm, position: np.ndarray, load: float):
        self.sm = sm
        self.position = np.asarray(position, float)
        self.load = float(load)
        self.removed = 0.0  # kg currently taken out of the model
        self._unit = pin.Inertia(1.0, self.position, np.zeros((3, 3))).toDynamicParameters()

    def set_removed(self, mass: float) -> bool:
        """Make the model's base body hold ``load − mass`` of propellant; True when it changed."""
        dm = float(mass) - self.removed
        if dm == 0.0:
            return False
        j = self.sm.base_joint_id
        Y = self.sm.model.inertias[j]
        self.sm.model.inertias[j] = pin.Inertia.FromDynamicParameters(Y.toDynamicParameters() - dm * self._unit)
        self.removed = float(mass)
        return True
