"""Per-sample outputs for the recording, computed for a block of states in one compiled call:
world poses of the URDF links and the end effector, the links' poses in their parent links
(what /tf carries), and momentum and kinetic energy of the rigid tree."""

from __future__ import annotations

import numpy as np

from sms_cli.model.system import SystemModel


class SampleKinematics:
    """``(world poses, parent-relative poses, momenta) = kin(qs, vs)`` for stacks of states.

    Frames: ``links`` (``sm.link_parents`` order, as the recorder's transform tree) then the end
    effector, so ``world[:, -1, :3]`` is the end-effector position. ``momenta[:, :]`` =
    [p, k about the CoM, k about the origin, energy] of the rigid tree (no modal terms). Call
    ``refresh()`` after a payload changes the body inertias (poses do not depend on them)."""

    def __init__(self, sm: SystemModel):
        from sms_cli.sim.compiled.tree import frame_table

        self.sm = sm
        self.links = list(sm.link_parents)
        fids = [sm.link_frames[n] for n in self.links] + [sm.ee_frame_id]
        row = {name: i for i, name in enumerate(self.links)}
        parent_rows = np.array([row.get(sm.link_parents[n], -1) for n in self.links] + [-1], dtype=np.int64)
        self.frames = (*frame_table(sm.model, fids), parent_rows)
        self.refresh()

    def refresh(self) -> None:
        from sms_cli.sim.compiled.tree import flatten

        T = flatten(self.sm.model)
        self.tree = (T.parent, T.kind, T.axis, T.place_R, T.place_p, T.inertia, T.leaf_IA, T.mass, T.com, T.armature, T.idx_q,
                     T.idx_v)

    def __call__(self, qs: np.ndarray, vs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        from sms_cli.sim.compiled.loop import sample_outputs

        n = qs.shape[0]
        world = np.empty((n, len(self.frames[0]), 7))
        rel = np.empty_like(world)
        mom = np.empty((n, 10))
        sample_outputs(*self.tree, *self.frames, np.ascontiguousarray(qs, dtype=float),
                       np.ascontiguousarray(vs, dtype=float), world, rel, mom)
        return world, rel, mom

    def locked(self, qs: np.ndarray, vs: np.ndarray) -> np.ndarray:
        """μ (n, 3) rad/s, base frame, of stacks of rigid states (``momentum_control.sample_locked_velocities``)."""
        from sms_cli.sim.compiled.momentum_control import sample_locked_velocities

        T = self.tree
        out = np.empty((qs.shape[0], 3))
        sample_locked_velocities(*T[:6], T[9], T[10], T[11], np.ascontiguousarray(qs, dtype=float),
                                 np.ascontiguousarray(vs, dtype=float), out)
        return out

    def locked_warm_call(self):
        """``locked``'s kernel call on one throw-away sample (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        T = self.tree
        return KernelCall("sms_cli.sim.compiled.momentum_control:sample_locked_velocities",
                          (*T[:6], T[9], T[10], T[11], self.sm.q0.astype(float)[None].copy(), np.zeros((1, self.sm.nv)),
                           np.empty((1, 3))), cost=3.0)

    def warm_call(self):
        """This object's ``sample_outputs`` call on one throw-away sample (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        n = len(self.frames[0])
        q, v = self.sm.q0.astype(float)[None].copy(), np.zeros((1, self.sm.nv))
        return KernelCall("sms_cli.sim.compiled.loop:sample_outputs",
                          (*self.tree, *self.frames, q, v, np.empty((1, n, 7)), np.empty((1, n, 7)), np.empty((1, 10))),
                          cost=5.0)
