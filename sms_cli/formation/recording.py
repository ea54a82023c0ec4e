"""The numeric MCAP topics of a two-spacecraft sample (``FormationSimulation._sample``'s dict).

Frames and units: locked twist and momentum in the master's base frame, shape twist and momentum in the other
body's base frame (Vicariotto 2023 L936), total momentum in the world frame about its origin; SI units, angles
in degrees where a field says ``_deg``. Body topics are under ``/<name>/`` (``/client/wheels/speed``).
"""

from __future__ import annotations

import numpy as np

_TWIST = ("vx", "vy", "vz", "wx", "wy", "wz")
_WRENCH = ("fx", "fy", "fz", "nx", "ny", "nz")
_MOMENTUM = ("px", "py", "pz", "kx", "ky", "kz")


def _fields(names, x) -> dict:
    return {n: x[..., i] for i, n in enumerate(names)}


def formation_topics(names: tuple[str, str], s: dict) -> dict[str, dict]:
    """topic → {field: value} of samples ``s`` (``FormationSimulation._sample``'s arrays with a leading time axis,
    what ``McapRecorder.write_block`` takes); ``names`` = (master, other)."""
    pos = s["shape_position"]
    out = {
        "/locked/twist": _fields(_TWIST, s["V_L"]),
        "/shape/twist": _fields(_TWIST, s["V_E"]),
        "/momentum/total": _fields(_MOMENTUM, s["H_world"]),
        "/momentum/locked": _fields(_MOMENTUM, s["H_locked"]),
        "/momentum/relative": _fields(_MOMENTUM, s["H_shape"]),
        "/energy": {"locked": s["T_L"], "shape": s["T_E"], "wheels": s["T"] - s["T_L"] - s["T_E"], "total": s["T"],
                    "lyapunov": s["W"]},
        "/shape/error": {"x": pos[..., 0], "y": pos[..., 1], "z": pos[..., 2], "angle_deg": np.degrees(s["shape_angle"])},
        "/locked/wrench": _fields(_WRENCH, s["F_L"]),
        "/shape/wrench": _fields(_WRENCH, s["F_E"]),
    }
    for i, name in enumerate(names):
        k = str(i + 1)
        out[f"/{name}/twist"] = _fields(_TWIST, s["V" + k])
        out[f"/{name}/position"] = _fields(("x", "y", "z"), s["p" + k])
        out[f"/{name}/wrench"] = _fields(_WRENCH, s["F" + k])
        out[f"/{name}/wrench/delivered"] = _fields(_WRENCH, s["D" + k])
        if s["wheels" + k].shape[-1]:
            out[f"/{name}/wheels/speed"] = {"rate": s["wheels" + k]}
            out[f"/{name}/wheels/torque"] = {"torque": s["tau_w" + k]}
    return out


def formation_timing(spec) -> dict[str, str]:
    """The ``sms.timing`` metadata record of a two-spacecraft recording (``sms_cli.sim.timing``'s keys, strings):
    its rates and stamps, and why another engine cannot replay it from its topics."""
    from sms_cli.sim.timing import HOLD, TIMING_VERSION

    rate, dt, record = float(spec.control_rate), float(spec.dt), float(spec.record_rate)
    return {
        "version": TIMING_VERSION, "control_rate_hz": repr(rate), "control_period_s": repr(1.0 / rate),
        "plant_dt_s": repr(dt), "plant_steps_per_control_period": str(int(round(1.0 / rate / dt))),
        "record_rate_hz": repr(record), "record_period_s": repr(1.0 / record),
        "integrator": f"{spec.integrator}: fixed-step RKMK4 of both free-flyers (sms_cli.formation.plant)",
        "hold": HOLD,
        "command_topics": "/<spacecraft>/wrench,/<spacecraft>/wheels/torque,/locked/wrench,/shape/wrench",
        "command_stamp": "a command sample stamped at a control tick t_k is the command computed from the state at t_k, "
                         "held over [t_k, t_k + control_period_s]; /<spacecraft>/wrench/delivered is the base wrench "
                         "delivered over the plant step ending at t",
        "state_stamp": "state topics stamped at t hold the plant state at t",
        "replayable": "no",
        "not_replayable_because": "a two-spacecraft recording holds the commanded base wrenches, not all that acted "
                                  "within the plant steps (the internal shape pair is reflected on the master at every "
                                  "integrator stage, thrusters switch within steps, the capture interface and the arm "
                                  "hold act continuously)",
    }


class RecordedLinks:
    """The links of both spacecraft as the recording's transform tree: names ``<spacecraft>/<link>`` (as in
    ``sms_cli.formation.urdf_pair``), each one's parent link (the bases' is ``world``), and their world poses."""

    def __init__(self, plant):
        from sms_cli.formation.plant import prefixed

        self.plant = plant
        self.names, self.parents, self.frame_ids = [], [], []
        for body in plant.bodies:
            sm = body.system
            for link, parent in sm.link_parents.items():
                self.names.append(prefixed(link, body.name))
                self.parents.append("world" if parent == "world" else prefixed(parent, body.name))
                self.frame_ids.append(body.frames[sm.model.frames[sm.link_frames[link]].name])
        self._data = plant.model.createData()

    def world_poses(self, q: np.ndarray) -> np.ndarray:
        """(n_links, 7) world poses [x y z qx qy qz qw]."""
        import pinocchio as pin

        pin.framesForwardKinematics(self.plant.model, self._data, q)
        return np.array([pin.SE3ToXYZQUAT(self._data.oMf[f]) for f in self.frame_ids])
