"""``sms compile`` on a two-spacecraft mission: the client's model summary and the pair's geometry at t = 0
(relative pose, distance, total mass, the locked and shape inertias of Vicariotto 2023 §5.3)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin


def locked_inertia(sm) -> np.ndarray:
    """The 6x6 locked spatial inertia of a spacecraft about its base frame, base axes (the CRBA's base block)."""
    return sm.rigid_mass_matrix(sm.q0)[:6, :6]


def com_in_base(sm) -> np.ndarray:
    """A spacecraft's CoM (m) in its base frame at its initial configuration."""
    base = pin.XYZQUATToSE3(sm.q0[:7])
    return base.actInv(np.asarray(sm.com(sm.q0), float))


def pair_summary(loaded, servicer, client) -> dict[str, Any]:
    """The relative geometry at t = 0 with body 1 = ``formation.master`` (the servicer without a formation), and the
    locked and shape inertias M_L (master frame) and M_E (the other body's frame) of Vicariotto 2023 §5.3."""
    from sms_cli.formation.decomposition import decompose
    from sms_cli.formation.schema import SERVICER

    m = loaded.mission
    g_sc = m.client.pose.se3()
    master = m.formation.master if m.formation is not None else SERVICER
    models = {SERVICER: servicer, m.client.name: client}
    other = m.client.name if master == SERVICER else SERVICER
    g12 = g_sc if master == SERVICER else g_sc.inverse()
    dec = decompose(locked_inertia(models[master]), locked_inertia(models[other]), g12)
    return {
        "master": master, "other": other,
        "client_in_servicer": {"position_m": g_sc.translation.tolist(),
                               "rpy_deg": np.degrees(pin.rpy.matrixToRpy(g_sc.rotation)).tolist()},
        "base_distance_m": float(np.linalg.norm(g_sc.translation)),
        "com_distance_m": float(np.linalg.norm(g_sc.act(com_in_base(client)) - com_in_base(servicer))),
        "total_mass_kg": servicer.total_mass + client.total_mass,
        "locked_inertia_diagonal": np.diag(dec.M_L).tolist(),
        "shape_inertia_diagonal": np.diag(dec.M_E).tolist(),
        "reduced_mass_kg": servicer.total_mass * client.total_mass / (servicer.total_mass + client.total_mass),
    }


def format_pair(s: dict[str, Any]) -> list[str]:
    p = s["client_in_servicer"]
    return [
        f"pair      master (body 1) {s['master']}, other {s['other']}; client in the servicer's base frame at "
        f"[{', '.join(f'{x:.4g}' for x in p['position_m'])}] m, rpy [{', '.join(f'{x:.4g}' for x in p['rpy_deg'])}] deg",
        f"          bases {s['base_distance_m']:.4g} m apart, CoMs {s['com_distance_m']:.4g} m; total mass "
        f"{s['total_mass_kg']:.4g} kg, two-body reduced mass {s['reduced_mass_kg']:.4g} kg",
        "          locked inertia M_L diagonal (kg, kg m^2, master frame): "
        + " ".join(f"{x:.4g}" for x in s["locked_inertia_diagonal"]),
        "          shape inertia M_E diagonal (kg, kg m^2, other body's frame): "
        + " ".join(f"{x:.4g}" for x in s["shape_inertia_diagonal"]),
    ]
