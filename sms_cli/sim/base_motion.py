"""Base translation metrics of a free-floating run: how far the base moves and the force the arm puts on it.

Caldera 2019 (eq. 5.21) reports the manipulator's reaction force on the base and the base displacement
it causes. With nothing else pushing the base (no thrusters, no disturbance, massless wheel rotors on
the base), Newton on the base body alone gives that force as m_0 a_0, a_0 the acceleration of the base
CoM; a_0 is taken here as the change of the base's world velocity between control instants.
"""

from __future__ import annotations

import numpy as np


def base_kinematics(sm, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """[world position of the base frame origin (3); world linear momentum of the base body alone (3)]."""
    import pinocchio as pin

    inertia = sm.model.inertias[1]  # the floating joint's body: the base link and what is fixed to it
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    v_com = v[:3] + np.cross(v[3:6], inertia.lever)  # base-frame velocity of the base body's CoM
    return np.concatenate([q[:3], inertia.mass * (R @ v_com)])


def base_motion_metrics(t: np.ndarray, motion: np.ndarray, mask: np.ndarray) -> dict:
    """``base_displacement_peak_m``: largest distance of the base origin from its position at the run
    start over the samples in ``mask``; ``base_force_peak_N``: largest |Δ(m_0 v_0)/Δt| between
    successive control instants ending in ``mask`` (the reaction force on the base when only the arm
    pushes it)."""
    out: dict = {}
    if motion.size == 0 or not np.any(mask):
        return out
    pos, mom = motion[:, :3], motion[:, 3:]
    out["base_displacement_peak_m"] = float(np.max(np.linalg.norm(pos[mask] - pos[0], axis=1)))
    if t.size > 1:
        dt = np.diff(t)
        ok = dt > 1e-12
        force = np.zeros(t.size)
        force[1:][ok] = np.linalg.norm(np.diff(mom, axis=0)[ok], axis=1) / dt[ok]
        sel = mask.copy()
        sel[0] = False
        out["base_force_peak_N"] = float(np.max(force[sel])) if np.any(sel) else None
    return out
