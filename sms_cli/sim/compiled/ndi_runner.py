"""The compiled engine for the missions controlled by Kraiem 2022's NDI + observer (``ndi_loop.run_ticks_ndi``),
flexible modes on the base and payloads attached or released between phases: same results as the Python
engine (``sms_cli.sim.engine.Simulation.run_python``), trace, metrics and recording (tests/test_compiled_ndi.py).

The runner keeps what ``CompiledSimulation`` does (slices, progress, events, interruption, the phases' payload
changes, the recording with the modes) and rebuilds the law's observer when a payload changes the model.
"""

from __future__ import annotations

import time

import numpy as np

from sms_cli.recording.recorder import RecordingInterrupted
from sms_cli.sim.attitude_math import attitude_error
from sms_cli.sim.compiled.runner import CompiledSimulation, _Stop, raise_on_failure


class NdiCompiledSimulation(CompiledSimulation):
    """One NDI mission simulation by the compiled loop (see the module docstring); ``ndi``: the law
    (``sms_cli.sim.laws.ndi.NdiObserver``), whose state the loop updates in place."""

    def __init__(self, sm, spec, recorder, progress, ndi, chunk_steps=None):
        from sms_cli.sim.compiled.runner import CHUNK_STEPS

        super().__init__(sm, spec, recorder, progress, None, chunk_steps or CHUNK_STEPS, None)
        self.ndi = ndi

    def _ndi_args(self, on: bool) -> tuple:
        return (on, *self.ndi.kernel_args())

    def _law_model_args(self, tree) -> tuple:
        """The law's model for ``run_ticks_ndi``: its own arrays with model errors, else the plant's (the tree's body
        inertias, B, −Ω², −2ζΩ)."""
        if self.ndi.has_model_errors:
            return self.ndi.model_arrays()
        return (tree[5], self.modal[0], self.modal[3], self.modal[4])

    def _begin_phase(self, phase) -> bool:
        """The base runner's payload changes; the law's observer is rebuilt when the model changed."""
        changed = super()._begin_phase(phase)
        if changed:
            self.ndi.model_changed(self.sm)
        return changed

    def run(self):
        from sms_cli.sim.compiled.loop import ARM_BLOCKS, SETTLED
        from sms_cli.sim.compiled.ndi_loop import MODAL_LIMIT, run_ticks_ndi
        from sms_cli.sim.compiled.stops import EV_COLS
        from sms_cli.sim.engine import build_result, phase_event
        from sms_cli.sim.references import AttitudeProfile, JointProfile

        sm, spec, wh = self.sm, self.spec, self.wheels
        q, v = sm.q0.astype(float).copy(), sm.v0.astype(float).copy()
        eta, etadot = sm.eta0.astype(float).copy(), sm.etadot0.astype(float).copy()
        ne = eta.size
        nw = wh.n
        wheel_v = np.asarray(sm.idx.wheels, dtype=np.int64)
        eff = wh.spin.astype(float).copy()
        fr = spec.wheel_friction
        wheel_args = (wheel_v, wh.max_torque.astype(float), wh.max_speed.astype(float), float(fr.coulomb), float(fr.viscous))
        arm = self._arm_args()
        arm_q, arm_v, effort = arm[0], arm[1], arm[7]
        stop_args = self._stop_args()
        n_arm, ns, stop_on = len(sm.arm), self.stop_table.n, stop_args[0]
        n_act = nw + n_arm
        q_arm_ref = q[arm_q].copy()
        q_att_ref = q[3:7].copy()
        t, steps, segment = 0.0, 0, 0
        status, why = "completed", ""
        spans: list[tuple[int, float, float]] = []
        pieces: list[dict] = []
        if self.rec is not None:  # the initial state is part of the recording
            self._record(np.array([0.0]), q[None], v[None], np.zeros((1, nw)), q_att_ref,
                         wrench=np.zeros((1, 6)) if self.record_wrench else None, joint_ref=q_arm_ref[None], etas=eta[None],
                         etadots=etadot[None])
        wall0 = time.perf_counter()
        try:
            for ip, phase in enumerate(spec.phases):
                t_phase0 = t
                if phase.attach or phase.detach or phase.base_mode == "fixed":
                    segment += 1
                self._begin_phase(phase)
                if self.rec is not None:
                    self.rec.write_event(t, "phase", phase_event(phase))
                tree = self._tree_args()
                q_ref = AttitudeProfile(q_att_ref, phase.attitude, "step", None).q_target.astype(float)
                ndi_on = phase.base_mode not in ("free-floating", "fixed")
                settle_tol = float(phase.until_settled) if phase.until_settled is not None else -1.0
                settled = np.array([np.nan])
                joints = JointProfile(q_arm_ref, [a.name for a in sm.arm], phase.waypoints, phase.joint_profile)
                ref_times, ref_points = joints.arrays
                n_ticks = int(round(phase.duration * spec.control_rate))
                tick0 = 0
                while tick0 < n_ticks:
                    m = min(self.chunk_ticks, n_ticks - tick0)
                    ms = m * self.n_sub
                    tr = {"t": np.empty(m), "att_err": np.empty(m), "wheel_speed": np.empty((m, nw)),
                          "wheel_torque": np.empty((m, nw)), "saturated": np.empty(m, dtype=np.bool_),
                          "momentum": np.empty((m, 6)), "energy": np.empty(m), "arm": np.empty((m, ARM_BLOCKS * n_arm + 6)),
                          "wheel_rate_ref": np.empty((m, nw)), "modal_peak": np.empty(m),
                          "ndi_torque_split": np.empty((m, 3 * n_act))}
                    st_t, st_q, st_v = np.empty(ms), np.empty((ms, sm.nq)), np.empty((ms, sm.nv))
                    st_eta, st_etadot, st_tw = np.empty((ms, ne)), np.empty((ms, ne)), np.empty((ms, nw))
                    ev, ev_n = np.empty((2 * ns * ms if stop_on else 0, EV_COLS)), np.zeros(1, dtype=np.int64)
                    noise = self.sensors.draw(m)  # the normals of the slice's ticks (sensors.measure_state)
                    ticks, n_steps, code = run_ticks_ndi(
                        *tree, *self.modal, *self._law_model_args(tree), *wheel_args, *self._ndi_args(ndi_on), q_ref, settle_tol, float(phase.settle_time),
                        arm_q, arm_v, effort, ref_times, ref_points, joints.step, t_phase0, *stop_args,
                        self.sensors.noisy, self.sensors.par, noise, t, float(spec.dt), self.n_sub, tick0, m, float(spec.divergence.max_rate),
                        float(spec.divergence.max_modal_amplitude), q, v, eta, etadot, eff, settled,
                        tr["t"], tr["att_err"], tr["wheel_speed"], tr["wheel_torque"], tr["saturated"], tr["momentum"],
                        tr["energy"], tr["arm"], tr["wheel_rate_ref"], tr["modal_peak"], tr["ndi_torque_split"], st_t, st_q, st_v, st_eta, st_etadot,
                        st_tw, ev, ev_n)
                    self.sensors.rewind(ticks, m)  # a settled phase: the next phase's ticks draw on from here
                    piece = {k: a[:ticks] for k, a in tr.items()}
                    piece["phase"] = np.full(ticks, ip)
                    piece["segment"] = np.full(ticks, segment)
                    piece["base_torque"] = np.zeros((ticks, 3))
                    pieces.append(piece)
                    if n_steps:
                        t = float(st_t[n_steps - 1])
                        steps += n_steps
                        if self.rec is not None:
                            held = lambda block: np.repeat(piece["arm"][:, block * n_arm:(block + 1) * n_arm],  # noqa: E731
                                                           self.n_sub, axis=0)[:n_steps]
                            self._record_slice(st_t[:n_steps], st_q[:n_steps], st_v[:n_steps], st_tw[:n_steps],
                                               np.broadcast_to(q_ref, (n_steps, 4)),
                                               np.zeros((n_steps, 6)) if self.record_wrench else None, held(4), held(1),
                                               ev[:ev_n[0]], etas=st_eta[:n_steps], etadots=st_etadot[:n_steps])
                    self.progress.update(t)
                    raise_on_failure(code, v, spec, MODAL_LIMIT)
                    if code == SETTLED:
                        break
                    tick0 += ticks
                spans.append((ip, t_phase0, t))
                q_att_ref = q_ref if phase.attitude is not None else q_att_ref
                q_arm_ref = joints.final
            self.progress.finish(t)
        except _Stop as exc:
            status, why = "diverged", str(exc)
            if self.rec is not None:
                self.rec.write_event(t, "diverged", {"reason": why}, level="error")
        except RecordingInterrupted:  # SIGINT/SIGTERM at a recorder call: the slices are whole up to t
            status = "interrupted"
            if not spans or spans[-1][0] != ip:
                spans.append((ip, t_phase0, t))
            self.rec.write_event(t, "interrupted", {"t": t}, level="warning")
        finally:
            self.progress.close()
        wall = time.perf_counter() - wall0
        filled = [p for p in pieces if p["t"].size]
        if status == "completed" and filled:  # the final state, as the Python loop adds it
            mom = self._modal_momenta(q[None], v[None], eta[None], etadot[None])
            pieces.append({"t": np.array([t]), "att_err": np.array([np.linalg.norm(attitude_error(q_att_ref, q[3:7]))]),
                           "wheel_speed": v[wheel_v][None], "wheel_torque": filled[-1]["wheel_torque"][-1:],
                           "saturated": np.array([False]), "base_torque": np.zeros((1, 3)),
                           "momentum": np.concatenate([mom[0, 0:3], mom[0, 6:9]])[None], "energy": mom[0, 9:10],
                           "phase": np.array([len(spec.phases) - 1]), "arm": self._final_arm_row(q, v, q_arm_ref, filled),
                           "wheel_rate_ref": self.ndi.wheel_rate_ref.copy()[None],
                           "modal_peak": np.array([float(np.max(np.abs(eta))) if ne else 0.0]),
                           "ndi_torque_split": filled[-1]["ndi_torque_split"][-1:],
                           "segment": np.array([segment])})
        trace = self._trace_arrays(pieces, nw, n_arm)
        cat = lambda key: np.concatenate([p[key] for p in pieces]) if pieces else None  # noqa: E731
        if pieces:
            trace["modal_peak"], trace["segment"] = cat("modal_peak"), cat("segment").astype(int)
            trace["ndi_torque_split"] = cat("ndi_torque_split")
            if n_arm and nw and trace["t"].size:  # Kraiem 2022 (3.67): the law's desired wheel rates
                trace["wheel_rate_ref"] = cat("wheel_rate_ref")
        return build_result(spec, sm, status, why, t, steps, trace, spans, wall, engine="compiled")

    def warm_groups(self) -> list:
        """The kernel calls of ``run`` on throw-away data (``sms_cli.sim.compiled.warmup``), callees first: the plant
        step (with the joint stops: the stop law's step), the wheel inertia, then the loop on zero ticks; the NDI
        law's kernels in a group of their own (the loop calls them with the Python loop's argument types, so another
        lane compiles them while this one compiles the plant, and the loop finds them cached); the recording's
        momenta and encoding."""
        from sms_cli.recording.encoding import warm_call
        from sms_cli.sim.compiled.dynamics import workspace
        from sms_cli.sim.compiled.kernels import modal_momenta_call
        from sms_cli.sim.compiled.stops import EV_COLS
        from sms_cli.sim.compiled.warmup import KernelCall
        from sms_cli.sim.laws.ndi import ndi_warm_calls

        sm = self.sm
        tree = self._tree_args()
        plant_tree = tree[:7] + tree[9:]
        nw, n_arm, ne = self.wheels.n, len(sm.arm), sm.n_modes
        q, v = sm.q0.astype(float).copy(), np.zeros(sm.nv)
        eta, ed = np.zeros(ne), np.zeros(ne)
        wheel_v = np.asarray(sm.idx.wheels, dtype=np.int64)
        stop_args = self._stop_args()
        ns = stop_args[1].shape[0]
        arm = self._arm_args()
        ws = workspace(tree[0].shape[0], sm.nq, sm.nv, ne)
        none_i, none_f = np.zeros(0, dtype=np.int64), np.zeros(0)
        B, Bt, BtB, no2, n2z = self.modal
        mod = "sms_cli.sim.compiled"
        law_state = [np.array(a, copy=True) if isinstance(a, np.ndarray) else a for a in self.ndi.kernel_args()]
        step = []
        if stop_args[0]:
            step = [KernelCall(f"{mod}.stops:stop_step", (plant_tree, *stop_args[2:], q, v, np.zeros(sm.nv), 0.01, 0.0, q.copy(),
                                                          v.copy(), np.zeros(ns), np.zeros(ns), np.empty((2 * ns, EV_COLS)),
                                                          np.zeros(1, dtype=np.int64), ws, (Bt, BtB, no2, n2z), eta, ed,
                                                          eta.copy(), ed.copy(), False), cost=7.0)]
        e1 = np.empty(0)
        loop = [
            *step,
            self.sensors.warm_call(),
            KernelCall(f"{mod}.dynamics:rkmk4_step", (*plant_tree, Bt, BtB, no2, n2z, none_i, none_i, none_f, none_f, none_f, q, v,
                                                      eta, ed, np.zeros(sm.nv), 0.01, q.copy(), v.copy(), eta.copy(), ed.copy(),
                                                      ws, none_i), cost=5.0),
            KernelCall(f"{mod}.loop:effective_wheel_inertia", (*plant_tree, q, wheel_v, np.ones(nw), ws), cost=5.5),
            KernelCall(f"{mod}.ndi_loop:run_ticks_ndi", (
                *tree, *self.modal, *self._law_model_args(tree), wheel_v, np.ones(nw), np.ones(nw), 0.0, 0.0, True, *law_state, q[3:7].copy(), -1.0, 0.0,
                arm[0], arm[1], arm[7], np.zeros(2), np.zeros((2, n_arm)), False, 0.0, *stop_args,
                self.sensors.noisy, self.sensors.par.copy(), np.zeros((0, self.sensors.width)), 0.0, 0.01, 1, 0, 0, 1e9, 1e3,
                q.copy(), v.copy(), eta.copy(), ed.copy(), np.ones(nw), np.array([np.nan]), e1, e1, np.empty((0, nw)),
                np.empty((0, nw)), np.empty(0, dtype=np.bool_), np.empty((0, 6)), e1, np.empty((0, 7 * n_arm + 6)),
                np.empty((0, nw)), e1, np.empty((0, 3 * (nw + n_arm))), e1, np.empty((0, sm.nq)), np.empty((0, sm.nv)), np.empty((0, ne)), np.empty((0, ne)),
                np.empty((0, nw)), np.empty((0, EV_COLS)), np.zeros(1, dtype=np.int64)), cost=8.0),
        ]
        momenta = [modal_momenta_call(sm, self.kinematics.tree, self.modal)]  # the final state's and the recording's
        if self.rec is not None:
            momenta += [self.kinematics.warm_call(), warm_call()]
            if sm.wheels:
                momenta.append(KernelCall(f"{mod}.momentum_control:locked_velocities_of", (
                    np.eye(sm.nx)[None].copy(), np.zeros((1, sm.nx)), np.empty((1, 3))), cost=1.0))
        return [loop, ndi_warm_calls(self.ndi), momenta]
