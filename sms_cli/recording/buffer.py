"""Samples of the Python loop held and written to MCAP in blocks (``McapRecorder.write_block``).

The loop reserves a sample with ``recorder.take(t)`` and ``add``s its raw state here (a few
array copies); every ``capacity`` samples, at each event and at the end, the block's link poses
come from one compiled call (``SampleKinematics``; per-sample Pinocchio forward kinematics when
the model does not fit the compiled kernels) and one compiled pass encodes the messages.
Topics and values are those of ``sms_cli.recording.topics.numeric_topics``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from sms_cli.model.system import SystemModel
from sms_cli.recording.topics import numeric_topics


class RecordBuffer:
    """Pending samples of one recording (see the module docstring)."""

    def __init__(self, sm: SystemModel, recorder, capacity: int = 512, kinematics=None):
        from sms_cli.sim.compiled.tree import unsupported_reason

        self.sm = sm
        self.rec = recorder
        self.capacity = capacity
        self.kinematics = kinematics  # a SampleKinematics, or None: Pinocchio per sample
        if kinematics is None and unsupported_reason(sm.model) is None:
            from sms_cli.sim.compiled.kinematics import SampleKinematics

            self.kinematics = SampleKinematics(sm)
        self.link_fids = [sm.link_frames[n] for n in sm.link_parents]
        self._rows: list[tuple] = []
        from sms_cli.dynamics.locked import shape_invariant

        self._shape_invariant = shape_invariant(sm)

    def warm_calls(self) -> list:
        """The recording's kernel calls (one group), for ``sms_cli.sim.compiled.warmup.warm``: the
        block kinematics (when compiled) and the message encoding."""
        from sms_cli.recording.encoding import warm_call

        return [([self.kinematics.warm_call()] if self.kinematics is not None else []) + [warm_call()]]

    def __len__(self) -> int:
        return len(self._rows)

    def add(self, t: float, q, v, eta, wheel_torque, joint_torque, ref_quat, joint_ref, err_vec, p, k,
            reaction=None, wrench=None, extra=None, locked=None) -> None:
        """One sample (copies of the arrays; ``reaction`` only while the base is held; ``wrench``, the
        wrench applied to the base, in every sample of a run that records it or in none; ``extra``, more
        topics {topic: {field: value}} (the thrusters', ``sms_cli.thrusters.topics``), likewise; ``locked``, the
        locked velocity μ (3,) at the sample for a model with wheels, computed then: payloads as attached at its time)."""
        poses = None if self.kinematics is not None else self._pinocchio_poses(q)
        self._rows.append((t, q.copy(), v.copy(), eta.copy(), np.array(wheel_torque, float), np.array(joint_torque, float),
                           np.array(ref_quat, float), np.array(joint_ref, float), np.array(err_vec, float),
                           np.array(p, float), np.array(k, float), None if reaction is None else np.array(reaction, float),
                           poses, None if wrench is None else np.array(wrench, float), extra,
                           None if locked is None else np.array(locked, float)))
        if len(self._rows) >= self.capacity:
            self.flush()

    def _pinocchio_poses(self, q) -> np.ndarray:
        """World poses of the links and the end effector at q (the fallback of the compiled kernels)."""
        m, d = self.sm.model, self.sm.data
        pin.framesForwardKinematics(m, d, q)
        out = np.empty((len(self.link_fids) + 1, 7))
        for i, fid in enumerate(self.link_fids + [self.sm.ee_frame_id]):
            out[i] = pin.SE3ToXYZQUAT(d.oMf[fid])
        return out

    def flush(self) -> None:
        """Write the pending samples (runs of equal shape: a held base adds /base/reaction)."""
        rows, self._rows = self._rows, []
        start = 0
        for i in range(1, len(rows) + 1):
            if i == len(rows) or (rows[i][11] is None) != (rows[start][11] is None):
                self._write(rows[start:i])
                start = i

    def _write(self, rows: list[tuple]) -> None:
        if not rows:
            return
        cols = list(zip(*rows))
        t, q, v, eta, tw, tm, ref, jref, err, p, k = (np.array(c) for c in cols[:11])
        reaction = None if cols[11][0] is None else np.array(cols[11])
        world = None if self.kinematics is not None else np.array(cols[12])
        wrench = None if cols[13][0] is None else np.array(cols[13])
        extra = None if cols[14][0] is None else {topic: {f: np.array([e[topic][f] for e in cols[14]]) for f in fields}
                                                  for topic, fields in cols[14][0].items()}
        locked = None if cols[15][0] is None else np.array(cols[15])
        self.write(t, q, v, eta, tw, tm, ref, jref, err, p, k, reaction, world, wrench, extra, locked)

    def write(self, t, q, v, eta, wheel_torque, joint_torque, ref_quat, joint_ref, err_vec, p=None, k=None,
              reaction=None, world=None, wrench=None, extra=None, locked=None) -> None:
        """Write n samples given as stacks (leading axis n) at once, bypassing the queue: the
        block path of both engines. p, k None: the rigid tree's momenta (compiled kinematics);
        ``world`` (n, n_links + 1, 7): world poses of the links and end effector when there are
        no compiled kinematics; ``wrench`` (n, 6): the wrench applied to the base (``/base/wrench``);
        ``locked`` (n, 3): μ on ``/momentum/locked`` (models with wheels), None: from the rigid (q, v) samples
        (the compiled loop's: ``SampleKinematics.locked``, else ``sms_cli.dynamics.locked.locked_velocities``)."""
        if self.kinematics is not None:
            world, rel, mom = self.kinematics(q, v)
            transforms, relative = rel[:, :-1], True
            if p is None:
                p, k = mom[:, 0:3], mom[:, 3:6]
        else:
            transforms, relative = world[:, :-1], False
        if self.sm.wheels and locked is None:
            if self.kinematics is not None and not self._shape_invariant:
                locked = self.kinematics.locked(q, v)
            else:  # one mass matrix for the whole block when it does not depend on q (wheels only on the base)
                from sms_cli.dynamics.locked import locked_velocities

                locked = locked_velocities(self.sm, q, v)
        scalars = numeric_topics(self.sm, q=q, v=v, wheel_torque=wheel_torque, ref_quat=ref_quat, err_vec=err_vec,
                                 momentum_p=p, momentum_k=k, ee=world[:, -1, :3], joint_torque=joint_torque,
                                 joint_ref=joint_ref, eta=eta, base_reaction=reaction, base_wrench=wrench,
                                 locked=locked if self.sm.wheels else None)
        if extra:
            scalars.update(extra)
        self.rec.write_block(t, transforms=transforms, scalars=scalars, relative=relative)
