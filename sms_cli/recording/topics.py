"""The numeric MCAP topics of a simulation sample, one definition for both engines.

Every argument is one sample (q (nq,), v (nv,), …) or a stack of samples with a leading axis
(q (n, nq), …); the values come back with the same leading axis, which is what
``McapRecorder.write_step`` (one sample) and ``McapRecorder.write_block`` (a stack) take.
Units: SI, angles in degrees where the field name says ``_deg``; frames as in the recorder's
docstring (attitude = base → world quaternion xyzw, rates in the base frame, positions world).
"""

from __future__ import annotations

import numpy as np

from sms_cli.model.conventions import euler_zyx_from_quaternions


def numeric_topics(sm, *, q, v, wheel_torque, ref_quat, err_vec, momentum_p, momentum_k, ee, joint_torque=None,
                   joint_ref=None, eta=None, base_reaction=None, base_wrench=None, locked=None) -> dict[str, dict]:
    """topic → {field: value}: attitude (+ roll/pitch/yaw), its error and reference, base rate and
    position, end-effector position, momentum (p; k about the CoM), wheels, joints, modes, and the
    base reaction when the base is held (``base_reaction`` not None), and the wrench applied to the base
    by thrusters and disturbances (``base_wrench`` not None: a mission that has them), like the torques
    the one applied over the plant step ending at the sample's time (``sms_cli.sim.timing``); with wheels,
    the locked velocity μ (``locked`` (3,), rad/s, base frame) and |μ| on ``/momentum/locked``."""
    rpy = np.degrees(euler_zyx_from_quaternions(q[..., 3:7]))
    out = {
        "/attitude": {"qx": q[..., 3], "qy": q[..., 4], "qz": q[..., 5], "qw": q[..., 6],
                      "roll_deg": rpy[..., 0], "pitch_deg": rpy[..., 1], "yaw_deg": rpy[..., 2]},
        "/attitude/error": {"angle_deg": np.degrees(np.linalg.norm(err_vec, axis=-1)), "rotvec": err_vec},
        "/attitude/reference": {"qx": ref_quat[..., 0], "qy": ref_quat[..., 1], "qz": ref_quat[..., 2],
                                "qw": ref_quat[..., 3]},
        "/base/rate": {"x": v[..., 3], "y": v[..., 4], "z": v[..., 5]},
        "/base/position": {"x": q[..., 0], "y": q[..., 1], "z": q[..., 2]},
        "/ee/position": {"x": ee[..., 0], "y": ee[..., 1], "z": ee[..., 2]},
        "/momentum": {"px": momentum_p[..., 0], "py": momentum_p[..., 1], "pz": momentum_p[..., 2],
                      "kx": momentum_k[..., 0], "ky": momentum_k[..., 1], "kz": momentum_k[..., 2]},
    }
    if sm.wheels:
        vi = sm.idx.wheels
        out["/wheels/speed"] = {w.name: v[..., j] for w, j in zip(sm.wheels, vi)}
        out["/wheels/torque"] = {w.name: wheel_torque[..., i] for i, w in enumerate(sm.wheels)}
        if locked is not None:  # μ = ω + Λθ̇ (rad/s, base frame; sms_cli.dynamics.locked, Vicariotto 2023 (4.5))
            out["/momentum/locked"] = {"x": locked[..., 0], "y": locked[..., 1], "z": locked[..., 2],
                                       "norm": np.linalg.norm(locked, axis=-1)}
    if sm.arm:
        out["/joints/position"] = {a.name: q[..., a.q_index] for a in sm.arm}
        out["/joints/rate"] = {a.name: v[..., j] for a, j in zip(sm.arm, sm.idx.arm)}
        out["/joints/torque"] = {a.name: joint_torque[..., i] for i, a in enumerate(sm.arm)}
        out["/joints/reference"] = {a.name: joint_ref[..., i] for i, a in enumerate(sm.arm)}
    if sm.n_modes:
        out["/modes/eta"] = {"eta": eta}
    if base_reaction is not None:
        w = base_reaction
        out["/base/reaction"] = {"fx": w[..., 0], "fy": w[..., 1], "fz": w[..., 2],
                                 "nx": w[..., 3], "ny": w[..., 4], "nz": w[..., 5]}
    if base_wrench is not None:  # base frame, [f; n] about the base origin: Pinocchio's tau[:6]
        w = base_wrench
        out["/base/wrench"] = {"fx": w[..., 0], "fy": w[..., 1], "fz": w[..., 2],
                               "nx": w[..., 3], "ny": w[..., 4], "nz": w[..., 5]}
    return out
