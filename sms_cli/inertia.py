"""The rotational inertia convention shared by URDF links and mission payloads: six numbers
[ixx, iyy, izz, ixy, ixz, iyz] (kg m², about the CoM; URDF's ixy = −∫xy dm) and their tensor."""

from __future__ import annotations


def inertia_tensor(ixx: float, iyy: float, izz: float, ixy: float, ixz: float, iyz: float):
    """The symmetric 3×3 tensor of the six URDF numbers (kg m²)."""
    import numpy as np  # here: the mission schema imports this module and `sms --help` stays light

    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


def principal_moments(ixx: float, iyy: float, izz: float, ixy: float, ixz: float, iyz: float):
    """Principal moments (kg m²), ascending."""
    import numpy as np

    return np.linalg.eigvalsh(inertia_tensor(ixx, iyy, izz, ixy, ixz, iyz))
