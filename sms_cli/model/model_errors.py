"""The model a control law believes in, when it is not the plant: Kraiem 2022 §4.3 validates its robust law with
±3 % errors on the bodies' inertias, ±10 % on their centres of mass and +10 % on the flexible parameters between
the controller's model and the simulated plant.

``law_model(sm, errors)`` returns a copy of the SystemModel with, for every body of the Pinocchio model (the base,
the arm links, the wheels' rotors; fixed links merged into their body):

- the rotational inertia about the body's CoM scaled by 1 + s_I·inertia,
- the CoM position in the body's joint frame scaled by 1 + s_c·com,
- the mass unchanged (a mass error is a payload error: the tasks' loads are known),

with the signs s_I, s_c = ±1 drawn per body from ``seed`` (so the errors are the thesis's bounds, in both
directions across the bodies), and every appendage mode's frequency scaled by 1 + modal_frequency (stiffness by
(1 + modal_frequency)², the damping ratio unchanged). The participation factors are not scaled: a uniform beam's
first bending mode already carries 97 % of its root inertia (robots/pulsar_full.urdf), and +10 % on its factors
would give the law a modal mass above the appendage's rigid inertia, a model no structure has.

Payloads keep their nominal inertias; ``follow_payloads`` attaches or releases them on the copy as the plant does.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from sms_cli.model.system import Appendage, Payload, SystemModel


def body_error_signs(n_bodies: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(s_I, s_c): ±1 per body (Pinocchio joints 1 … n_bodies), the inertia's and the CoM's, from ``seed``."""
    rng = np.random.default_rng(seed)
    s = rng.integers(0, 2, size=(2, n_bodies)) * 2 - 1
    return s[0].astype(float), s[1].astype(float)


def law_model(sm: SystemModel, inertia: float = 0.0, com: float = 0.0, modal_frequency: float = 0.0,
              seed: int = 0) -> SystemModel:
    """A copy of ``sm`` with the errors of the module docstring (fractions: 0.03 is 3 %). The payloads are copied
    with their current attached state, their inertias removed before and added back after the bodies are perturbed
    (the errors are on the robot, not on the loads)."""
    model = sm.model.copy()
    attached = [p for p in sm.payloads.values() if p.attached]
    for p in attached:  # the robot's own bodies
        Y = model.inertias[p.joint_id]
        model.inertias[p.joint_id] = pin.Inertia.FromDynamicParameters(
            Y.toDynamicParameters() - p.inertia_in_joint.toDynamicParameters())
    s_I, s_c = body_error_signs(model.njoints - 1, seed)
    for j in range(1, model.njoints):
        Y = model.inertias[j]
        model.inertias[j] = pin.Inertia(Y.mass, Y.lever * (1.0 + s_c[j - 1] * com), Y.inertia * (1.0 + s_I[j - 1] * inertia))
    for p in attached:
        model.inertias[p.joint_id] = model.inertias[p.joint_id] + p.inertia_in_joint
    appendages = [Appendage(a.name, a.frame_id, a.L.copy(), a.omega * (1.0 + modal_frequency), a.zeta.copy(), a.modes)
                  for a in sm.appendages]
    payloads = {n: Payload(p.name, p.frame_id, p.joint_id, p.inertia_in_joint.copy(), p.attached)
                for n, p in sm.payloads.items()}
    return dataclasses.replace(sm, model=model, appendages=appendages, payloads=payloads, warnings=list(sm.warnings))


def follow_payloads(law: SystemModel, plant: SystemModel) -> bool:
    """Attach or release on ``law`` the payloads whose state differs from ``plant``'s; True when any changed."""
    changed = False
    for name, p in plant.payloads.items():
        if law.payloads[name].attached != p.attached:
            (law.attach_payload if p.attached else law.detach_payload)(name)
            changed = True
    return changed
