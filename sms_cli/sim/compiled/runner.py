"""The compiled engine: the whole simulation loop in numba (``loop.run_ticks``), metrics from its
arrays and the MCAP recording written in blocks. Same results as the Python engine
(``sms_cli.sim.engine.Simulation``) for the missions it accepts; ``unsupported_reason`` says why
it does not accept the others (the Python engine then runs them).

The loop runs in slices of at most ``chunk_steps`` plant steps, so memory stays bounded, the
progress bar moves and Ctrl-C is honoured between slices (numba code cannot be interrupted).
"""

from __future__ import annotations

import time

import numpy as np

from sms_cli.model.system import SystemModel
from sms_cli.sim.attitude_math import attitude_error
from sms_cli.sim.compiled.kinematics import SampleKinematics
from sms_cli.recording.buffer import RecordBuffer
from sms_cli.recording.recorder import RecordingInterrupted
from sms_cli.sim.schema import SimulationSpec
from sms_cli.sim.timing import records_base_wrench

CHUNK_STEPS = 20_000


def unsupported_reason(sm: SystemModel, spec: SimulationSpec, att_spec) -> str | None:
    """Why the compiled engine cannot run this mission (None when it can)."""
    from sms_cli.sim.compiled.tree import unsupported_reason as tree_reason
    from sms_cli.sim.timing import uses_thrusters

    ndi = spec.ndi is not None  # the NDI loop (ndi_runner) takes base-mounted modes and payload changes
    real_thrusters = getattr(sm, "thrusters", None) is not None and uses_thrusters(spec)
    momentum = isinstance(att_spec, _momentum_laws())
    modes = sm.n_modes > 0
    changes = any(p.attach or p.detach for p in spec.phases)
    checks = [
        (modes and sm.base_modal_coupling is None, "an appendage is not mounted on the base"),
        (modes and any(p.base_mode == "fixed" for p in spec.phases), "a phase holds the base fixed on a model with flexible modes"),
        (modes and momentum, "the mission combines a momentum law with flexible modes"),
        (modes and real_thrusters, "the mission combines real thrusters with flexible modes"),
        (modes and spec.resolved_rate is not None and any(p.end_effector is not None for p in spec.phases),
         "the mission combines end-effector tracking with flexible modes"),
        (bool(sm.springs), "the model has spring joints"),
        (ndi and (att_spec is not None or spec.arm is not None), "the mission combines NDI with an attitude or arm law"),
        (ndi and spec.resolved_rate is not None, "the mission combines NDI with resolved-rate control"),
        (ndi and bool(spec.disturbances), "the mission combines NDI with disturbances"),
        (att_spec is not None and not isinstance(att_spec, _compiled_laws()),
         f"the attitude law is {getattr(att_spec, 'law', att_spec)!r} (compiled: {', '.join(COMPILED_LAW_NAMES)})"),
        (bool(sm.arm) and real_thrusters, "the mission has real thrusters (thrusters:) and an arm"),
        (real_thrusters and bool(spec.disturbances), "the mission combines real thrusters with disturbances"),
        (momentum and bool(spec.disturbances), "the mission combines a momentum law with disturbances"),
        ((real_thrusters or momentum) and any(p.base_mode == "fixed" for p in spec.phases),
         "a phase holds the base fixed on a mission with real thrusters or a momentum law"),
        (momentum and any(p.attitude_profile != "step" for p in spec.phases),
         "a momentum law follows a smooth attitude profile"),
        (changes and (momentum or real_thrusters), "a phase attaches or releases a payload on a mission with real thrusters or a momentum law"),
        (ndi and any(p.base_mode == "fixed" for p in spec.phases), "a phase of an NDI mission holds the base fixed"),
        (ndi and any(p.attitude_profile != "step" for p in spec.phases), "an NDI mission has a smooth attitude profile"),
        (ndi and any(p.end_effector is not None for p in spec.phases), "an NDI mission tracks an end-effector target"),
    ]
    for bad, why in checks:
        if bad:
            return why
    why = tree_reason(sm.model)
    return why


def _momentum_laws():
    from sms_cli.sim.laws.schema import (FreeFlyingSpec, HierarchicalSpec, QuaternionLyapunovSpec, Se3PdSpec,
                                         WheelsFreeFloatingSpec)

    return (WheelsFreeFloatingSpec, FreeFlyingSpec, HierarchicalSpec, Se3PdSpec, QuaternionLyapunovSpec)


def _compiled_laws():
    from sms_cli.sim.laws.schema import (BacksteppingSpec, FreeFlyingSpec, HierarchicalSpec, MrpFeedbackSpec,
                                         QuaternionLyapunovSpec, QuaternionPdSpec, Se3PdSpec, SmcAttitudeSpec,
                                         TwistingSpec, WheelsFreeFloatingSpec)

    return (MrpFeedbackSpec, QuaternionPdSpec, SmcAttitudeSpec, TwistingSpec, BacksteppingSpec,
            WheelsFreeFloatingSpec, FreeFlyingSpec, HierarchicalSpec, Se3PdSpec, QuaternionLyapunovSpec)


COMPILED_LAW_NAMES = ("mrp_feedback", "quaternion_pd", "smc", "twisting_smc", "backstepping", "wheels_free_floating",
                      "free_flying", "hierarchical", "se3_pd", "quaternion_lyapunov")


class CompiledSimulation:
    """One mission simulation by the compiled loop (see the module docstring)."""

    def __init__(self, sm: SystemModel, spec: SimulationSpec, recorder, progress, att_law,
                 chunk_steps: int = CHUNK_STEPS, arm_law=None, rr=None, att_spec=None):
        from sms_cli.sim.actuators import WheelArray
        from sms_cli.sim.engine import Progress
        from sms_cli.sim.sensors import Sensors

        self.sm, self.spec, self.rec = sm, spec, recorder
        self.law = att_law
        self.arm_law = arm_law
        self.rr = rr  # the resolved rate (laws.resolved_rate.ResolvedRate) of the end-effector phases
        self.wheels = WheelArray(sm, spec.allocation, spec.wheel_friction)
        self.sensors = Sensors(sm, spec.sensors)  # noise and bias: the normals of each slice's ticks (sensors.measure_state)
        self.n_sub = int(round(1.0 / spec.control_rate / spec.dt))
        self.chunk_ticks = max(1, chunk_steps // self.n_sub)
        self.kinematics = SampleKinematics(sm)
        from sms_cli.sim.compiled.plant import modal_arrays

        self.modal = modal_arrays(sm)  # the base-mounted modes: B, Bᵀ, BᵀB, −Ω², −2ζΩ
        self.buffer = RecordBuffer(sm, recorder, kinematics=self.kinematics) if recorder is not None else None
        self.record_wrench = records_base_wrench(spec)  # thrusters, disturbances: /base/wrench (sms_cli.sim.timing)
        from sms_cli.sim.compiled.disturbances import disturbance_table

        self.dist = disturbance_table(spec.disturbances)
        self.progress = Progress(sum(p.duration for p in spec.phases), progress)
        self.law_name = getattr(att_spec, "law", "attitude")  # the propellant's key per law (real thrusters)
        self.thr = None  # real thrusters (thruster_run), the allocation at each tick
        if getattr(sm, "thrusters", None) is not None:
            from sms_cli.sim.timing import uses_thrusters

            if uses_thrusters(spec):
                from sms_cli.sim.compiled.thruster_run import ThrusterRun

                self.thr = ThrusterRun(sm, self.kinematics.tree)

    # ------------------------------------------------------------------ pieces
    def _tree_args(self):
        return self.kinematics.tree if self.thr is None else self.thr.tree

    def _samples(self, qs: np.ndarray, vs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.kinematics(qs, vs)

    def _record(self, times, qs, vs, tau_w, ref_quat, err_vec=None, wrench=None, tau_m=None, joint_ref=None,
                held=False, extra=None, mom=None, etas=None, etadots=None) -> None:
        """Offer the plant-step states to the recorder and write the samples it picks (``ref_quat``: one
        reference or one per step; ``wrench``: the thrusters' wrench on the base per step, for
        ``/base/wrench``; ``tau_m``, ``joint_ref``: the arm's torques and joint reference per step; ``held``:
        the base is held, its support's wrench on ``/base/reaction``; ``extra``: more topics, {topic: {field:
        values per step}}; ``mom``: [p, k about the CoM, μ] per step at the mass of each step, with real thrusters;
        ``etas``, ``etadots``: the modal coordinates and rates per step, models with modes: the momenta with their
        terms, μ from the augmented mass matrix at (q, v, η̇), as ``Simulation._record``)."""
        idx = self.rec.select(times)
        if idx.size == 0:
            return
        qs = qs[idx]
        n = idx.size
        refs = np.broadcast_to(ref_quat if np.ndim(ref_quat) == 1 else ref_quat[idx], (n, 4))
        err = attitude_error(refs, qs[:, 3:7]) if err_vec is None else err_vec
        eta = np.zeros((n, 0)) if etas is None else etas[idx]
        n_arm = len(self.sm.arm)
        tau_m = np.zeros((n, n_arm)) if tau_m is None else tau_m[idx]
        joint_ref = np.zeros((n, n_arm)) if joint_ref is None else joint_ref[idx]
        reaction = self._held_reactions(qs, vs[idx], tau_w[idx], tau_m) if held else None
        extra = None if extra is None else {k: {f: x[idx] for f, x in d.items()} for k, d in extra.items()}
        p, k, locked = (None, None, None) if mom is None else (mom[idx, 0:3], mom[idx, 3:6], mom[idx, 6:9])
        if self.sm.n_modes:
            p, k, locked = self._modal_record_momenta(qs, vs[idx], eta, etadots[idx])
        self.buffer.write(times[idx], qs, vs[idx], eta, tau_w[idx], tau_m, refs, joint_ref, err, p, k, reaction=reaction,
                          wrench=None if wrench is None else wrench[idx], extra=extra,
                          locked=locked if self.sm.wheels else None)

    def _modal_momenta(self, qs, vs, etas, etadots, mass_matrices: bool = False):
        """[p, k about the CoM, k about the origin, energy] per sample, modes included (``modal.modal_sample_momenta``);
        with ``mass_matrices`` also (that, the augmented mass matrices)."""
        from sms_cli.sim.compiled.modal import modal_sample_momenta

        tr = self.kinematics.tree
        n = qs.shape[0]
        out = np.empty((n, 10))
        Ms = np.empty((n if mass_matrices else 0, self.sm.nx, self.sm.nx))
        f = lambda x: np.ascontiguousarray(x, dtype=float)  # noqa: E731
        modal_sample_momenta(tr[0], tr[1], tr[2], tr[5], tr[7], tr[8], tr[9], tr[3], tr[4], tr[10], tr[11], self.modal[0],
                             self.modal[3], f(qs), f(vs), f(etas), f(etadots), out, Ms)
        return (out, Ms) if mass_matrices else out

    def _modal_record_momenta(self, qs, vs, etas, etadots):
        """(p, k about the CoM, μ or None without wheels) of recorded samples with modes: μ at (q, v, η̇) from the
        augmented mass matrices (``momentum_control.locked_velocities_of``)."""
        from sms_cli.sim.compiled.momentum_control import locked_velocities_of

        mom, Ms = self._modal_momenta(qs, vs, etas, etadots, mass_matrices=bool(self.sm.wheels))
        locked = None
        if self.sm.wheels:
            locked = np.empty((qs.shape[0], 3))
            locked_velocities_of(Ms, np.concatenate([vs, etadots], axis=1), locked)
        return mom[:, 0:3], mom[:, 3:6], locked

    def _begin_phase(self, phase) -> bool:
        """The phase's payload changes on the SystemModel (as ``Simulation._begin_phase``); True when the body
        inertias changed (the tree arrays, of the loop and the recording, are re-read)."""
        sm = self.sm
        for name in phase.detach:
            sm.detach_payload(name)
        for name in phase.attach:
            sm.attach_payload(name)
        if phase.attach or phase.detach:
            self.kinematics.refresh()
            return True
        return False

    def _disturbances(self, ts, qs) -> np.ndarray:
        """The disturbances' wrench [f; n] (base frame) at each time and configuration (``disturbances``)."""
        from sms_cli.sim.compiled.disturbances import disturbance_wrenches

        out = np.empty((ts.size, 6))
        disturbance_wrenches(self.dist, np.ascontiguousarray(ts, dtype=float), np.ascontiguousarray(qs, dtype=float), out)
        return out

    def _held_reactions(self, qs, vs, tau_w, tau_m) -> np.ndarray:
        """The held base's support wrench [f; n] (base frame) at each state under its wheel and arm torques
        (``held_base.held_base_reactions``)."""
        from sms_cli.sim.compiled.held_base import held_base_reactions

        T, sm = self.kinematics.tree, self.sm
        out = np.empty((qs.shape[0], 6))
        i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
        f64 = lambda x: np.ascontiguousarray(x, dtype=float)  # noqa: E731
        held_base_reactions(*T[:6], T[9], T[10], T[11], i64(sm.idx.wheels), i64([a.v_index for a in sm.arm]), f64(qs), f64(vs),
                            f64(tau_w), f64(tau_m), out)
        return out

    def _law_args(self):
        """run_ticks's law arguments: (code, parameters, J, G, Js, body code, J̇ step), from the law object (its
        ``code``, ``par``) and its body model: a ``RigidBody``'s constant J and wheels (body code 0), a
        ``SystemBody``'s inertia at q0 with h from the system's momentum (body code 1), or its online J(q)
        and J̇ by the same central difference (body code 2), or none."""
        from sms_cli.sim.compiled.kernels import NO_LAW
        from sms_cli.sim.laws.plant_models import SystemBody

        law = self.law
        if law is None or hasattr(law, "actuate"):  # none, or a momentum law (_momentum_args)
            return NO_LAW
        b = law.body
        _, _, J, G, Js, body_code, step = NO_LAW
        if isinstance(b, SystemBody):
            J, body_code = b.initial_inertia, 2 if b.online else 1
            step = float(b.h)
        elif b is not None:
            J, G, Js = b.J, b.G, b.Js
        f = lambda x: np.ascontiguousarray(x, dtype=float)  # noqa: E731
        return int(law.code), f(law.par), f(J), f(G), f(Js), body_code, step

    def _momentum_args(self):
        """run_ticks's momentum-law arguments (``momentum_control``): code (0: none), the model tuple, gains, state
        (the law's own ``mem``, so its ``lyapunov_terms`` reads what the loop wrote) and the last W (1,)."""
        from sms_cli.sim.compiled.kernels import NO_MOMENTUM_LAW

        law = self.law
        if not hasattr(law, "actuate"):
            return NO_MOMENTUM_LAW
        model = law.model_args(self.sm.q0)  # with real thrusters the loop recomputes it at each tick (locked_model)
        return int(law.code), model, law.par, law.mem, np.zeros(1)

    def _arm_args(self):
        """run_ticks's arm arguments: coordinates, law (its ``code``, parameter rows, wrap mask; −1: none),
        the model's (arm, free) indices for the laws with a model, the effort limits."""
        sm = self.sm
        n = len(sm.arm)
        i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
        arm_q, arm_v = i64([a.q_index for a in sm.arm]), i64([a.v_index for a in sm.arm])
        law = self.arm_law
        code, par, wrap = -1, np.zeros((6, n)), np.zeros(n, dtype=np.bool_)
        a_idx, p_idx = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        if law is not None and n:
            code, par, wrap = int(law.code), np.ascontiguousarray(law._params(n)), law.wrap_mask(n)
            if law.dyn is not None:
                a_idx, p_idx = law.dyn.indices
        effort = np.array([a.max_effort for a in sm.arm], dtype=float)
        return arm_q, arm_v, code, par, wrap, a_idx, p_idx, effort

    def _tracking_args(self, phase, q, q_arm_ref, held):
        """run_ticks's held-base and tracking arguments for ``phase`` (loop.RR_* for ``rr_par``): held, on, the
        parameters with the target at the phase start (its end-effector position added when relative), the
        joint rate limits, the end-effector frame, and the tracked reference (from ``q_arm_ref``; in/out)."""
        from sms_cli.sim.compiled.loop import RR_DAMPING, RR_GAIN, RR_GENERALIZED, RR_N, RR_RATE, RR_TARGET, RR_THRESHOLD, RR_VEL

        n = len(self.sm.arm)
        f_joint, f_R, f_p, _ = self.kinematics.frames
        rr, ee = self.rr, phase.end_effector
        on = ee is not None and rr is not None
        par, rate = np.zeros(RR_N), np.ones(n)
        if on:
            target = np.asarray(ee.position, float)
            if ee.relative_to_start:  # Simulation.run_python's ee_start
                target = target + self._samples(q[None], np.zeros((1, self.sm.nv)))[0][0, -1, :3]
            par[RR_GAIN:RR_GAIN + 3] = np.broadcast_to(rr.K, (3,))
            par[RR_DAMPING], par[RR_THRESHOLD], par[RR_RATE] = rr.damping, rr.threshold, float(self.spec.control_rate)
            par[RR_GENERALIZED] = float(rr.jacobian == "generalized")
            par[RR_TARGET:RR_TARGET + 3], par[RR_VEL:RR_VEL + 3] = target, np.asarray(ee.velocity, float)
            rate = np.ascontiguousarray(rr.max_rate, dtype=float)
        return (held, on, par, rate, int(f_joint[-1]), np.ascontiguousarray(f_R[-1]), np.ascontiguousarray(f_p[-1]),
                np.array(q_arm_ref, dtype=float))

    def _stop_args(self):
        """run_ticks's joint-stop arguments: on, the table's arrays, restitution, and the state arrays."""
        from sms_cli.dynamics.joint_stops import stop_table

        T = self.stop_table = stop_table(self.sm)
        on = bool(self.spec.joint_stops.enabled and T.n > 0)
        i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
        return (on, i64(T.arm_index), i64(T.v_index), i64(T.q_index), T.lower.astype(float), T.upper.astype(float),
                float(self.spec.joint_stops.restitution), np.zeros(T.n, dtype=np.int64), np.zeros(T.n, dtype=np.bool_),
                np.zeros(T.n))

    def _write_events(self, ev: np.ndarray) -> None:
        """The joint-stop events (stops.py rows) as ``JointStops`` writes them to /events."""
        from sms_cli.sim.compiled.stops import EV_ARRIVAL, UPPER

        T = self.stop_table
        for row in ev:
            j = int(row[2])
            side = "upper" if int(row[3]) == UPPER else "lower"
            if int(row[1]) == EV_ARRIVAL:
                self.rec.write_event(float(row[0]), "joint_stop", {
                    "joint": T.names[j], "side": side, "limit": float(row[4]), "rate": float(row[5]),
                    "rate_after": float(row[6]), "penetration": float(row[7]), "impulse": float(row[8])})
            else:
                self.rec.write_event(float(row[0]), "joint_stop_release", {
                    "joint": T.names[j], "side": side, "time_on_stop_s": float(row[9])})

    # ------------------------------------------------------------------ main loop
    def run(self):
        from sms_cli.sim.compiled.loop import ARM_BLOCKS, MODAL_LIMIT, RUNNING, SETTLED, X_N, X_REF, run_ticks
        from sms_cli.sim.compiled.momentum_control import locked_velocity
        from sms_cli.sim.compiled.thruster_run import NO_THRUSTERS
        from sms_cli.sim.compiled.stops import EV_COLS
        from sms_cli.sim.engine import build_result, phase_event
        from sms_cli.sim.references import AttitudeProfile, JointProfile

        sm, spec, wh = self.sm, self.spec, self.wheels
        q, v = sm.q0.astype(float).copy(), sm.v0.astype(float).copy()
        eta, etadot = sm.eta0.astype(float).copy(), sm.etadot0.astype(float).copy()
        ne = eta.size
        nw = wh.n
        wheel_v = np.asarray(sm.idx.wheels, dtype=np.int64)
        memory = self.law.memory if hasattr(self.law, "memory") else np.zeros(4)  # the attitude law's state
        eff = wh.spin.astype(float).copy()
        fr = spec.wheel_friction
        wheel_args = (wheel_v, np.ascontiguousarray(wh.A_pinv), np.ascontiguousarray(wh.null), wh.spin.astype(float),
                      float(spec.allocation.null_space_gain), float(spec.allocation.target_speed),
                      wh.max_torque.astype(float), wh.max_speed.astype(float), float(fr.coulomb), float(fr.viscous))
        law_args = self._law_args()
        mom_args = self._momentum_args()
        mlaw = mom_args[0] > 0
        thr = self.thr
        lyap = LyapunovSeries(self.law, (lambda _q: self.law.model_args()) if thr is None else thr.law_model) if mlaw else None
        thr_args = NO_THRUSTERS if thr is None else thr.args(False)
        arm_args = self._arm_args()
        stop_args = self._stop_args()
        n_arm, ns, stop_on = len(sm.arm), self.stop_table.n, stop_args[0]
        arm_q, arm_v = arm_args[0], arm_args[1]
        q_arm_ref = q[arm_q].copy()
        q_att_ref = q[3:7].copy()
        t, steps = 0.0, 0
        segment, held = 0, False  # Simulation._begin_phase's segment count; whether the base is held
        status, why = "completed", ""
        spans: list[tuple[int, float, float]] = []
        pieces: list[dict] = []
        propellant: dict[int, tuple[float, float]] = {}  # phase index -> propellant used at its start, at its end (kg)
        last_T = np.zeros(3)
        if self.rec is not None:  # the initial state is part of the recording
            self._record(np.array([0.0]), q[None], v[None], np.zeros((1, nw)), q_att_ref, np.zeros((1, 3)),
                         np.zeros((1, 6)) if self.record_wrench else None, joint_ref=q_arm_ref[None], etas=eta[None],
                         etadots=etadot[None],
                         extra={**(thr.initial_topics() if thr else {}),
                                **(lyap.topic(lyap.terms(q, v, q_att_ref)[None]) if mlaw else {})} or None)
        wall0 = time.perf_counter()
        try:
            for ip, phase in enumerate(spec.phases):
                t_phase0 = t
                used0 = thr.used if thr else 0.0
                if self.rec is not None:
                    self.rec.write_event(t, "phase", phase_event(phase))
                if phase.attach or phase.detach or phase.base_mode == "fixed" or held:
                    segment += 1
                self._begin_phase(phase)
                held = phase.base_mode == "fixed"
                if held:
                    v[:6] = 0.0  # the support takes the base's momentum at the phase start
                att = AttitudeProfile(q_att_ref, phase.attitude, phase.attitude_profile, phase.slew_time)
                law_on = phase.base_mode not in ("free-floating", "fixed") and self.law is not None
                rr_args = self._tracking_args(phase, q, q_arm_ref, held)
                thrusters = phase.base_mode == "free-flying" or spec.attitude_actuator == "thrusters"
                torque_limit = np.inf if spec.attitude_torque_limit is None else float(spec.attitude_torque_limit)
                settle_tol = float(phase.until_settled) if phase.until_settled is not None else -1.0
                settled = np.array([np.nan])
                if mlaw:  # W at the phase start (the Python loop's _lyapunov before the first tick)
                    mom_args[4][0] = lyap.phase_start(ip, q, v, att.at(0.0).quat)
                joints = JointProfile(q_arm_ref, [a.name for a in sm.arm], phase.waypoints, phase.joint_profile)
                ref_times, ref_points = joints.arrays
                n_ticks = int(round(phase.duration * spec.control_rate))
                tick0 = 0
                while tick0 < n_ticks:
                    m = min(self.chunk_ticks, n_ticks - tick0)
                    ms = m * self.n_sub
                    tr = {"t": np.empty(m), "att_err": np.empty(m), "wheel_speed": np.empty((m, nw)),
                          "wheel_torque": np.empty((m, nw)), "saturated": np.empty(m, dtype=np.bool_),
                          "base_torque": np.empty((m, 3)), "momentum": np.empty((m, 6)), "energy": np.empty(m),
                          "arm": np.empty((m, ARM_BLOCKS * n_arm + 6)), "x": np.empty((m, X_N)),
                          "locked": np.empty((m if mlaw else 0, 3)), "lyapunov": np.empty(m if mlaw else 0),
                          "wrench": np.zeros((m if mlaw else 0, 6)), "modal_peak": np.empty(m)}
                    st_t, st_q, st_v, st_tw = np.empty(ms), np.empty((ms, sm.nq)), np.empty((ms, sm.nv)), np.empty((ms, nw))
                    st_eta, st_etadot = np.empty((ms, ne)), np.empty((ms, ne))
                    st_lyap = np.empty((ms if mlaw else 0, lyap.width if mlaw else 0))
                    st_thr, st_mom = thr.step_arrays(ms) if thr else (np.empty((0, 1)), np.empty((0, 9)))
                    ev, ev_n = np.empty((2 * ns * ms if stop_on else 0, EV_COLS)), np.zeros(1, dtype=np.int64)
                    t_start, q_start = t, q.copy()  # the slice's first step starts here (its disturbances)
                    noise = self.sensors.draw(m)
                    tr_rows = [tr[k] for k in ("t", "att_err", "wheel_speed", "wheel_torque", "saturated", "base_torque",
                                               "momentum", "energy", "arm", "x", "locked", "lyapunov", "wrench", "modal_peak")]

                    def call(k0, mk, s0, t0, thr_args, _tr=tr_rows, _st=(st_t, st_q, st_v, st_eta, st_etadot, st_tw, st_lyap),
                             _s2=(st_thr, st_mom),
                             _noise=noise,
                             _phase=(law_on, thrusters, att.params, settle_tol, phase, ref_times, ref_points, joints, t_phase0, tick0,
                                     rr_args)):
                        """run_ticks on the slice's ticks k0.. (mk of them) and steps s0.., from time t0."""
                        (law_on_, thrusters_, att_prof_, settle_tol_, phase_, ref_times_, ref_points_, joints_, t_phase0_, tick0_,
                         rr_args_) = _phase
                        return run_ticks(
                            *self._tree_args(), *self.modal, *wheel_args, law_on_, thrusters_, torque_limit, *law_args, att_prof_, settle_tol_,
                            float(phase_.settle_time), *mom_args, *arm_args, ref_times_, ref_points_, joints_.step, t_phase0_,
                            *stop_args, *rr_args_, self.dist, *thr_args, self.sensors.noisy, self.sensors.par, _noise[k0:k0 + mk],
                            t0, float(spec.dt), self.n_sub, tick0_ + k0, mk,
                            float(spec.divergence.max_rate), float(spec.divergence.max_modal_amplitude), q, v, eta, etadot,
                            memory, eff, settled, *(a[k0:k0 + mk] for a in _tr),
                            *(a[s0:] for a in _st), *(a[s0:] for a in _s2), ev, ev_n)

                    if thr is None:
                        ticks, n_steps, code = call(0, m, 0, t, thr_args)
                    else:  # one tick per call: probe the law's wrench, allocate it (the LP), step through the firings
                        ticks, n_steps, code, t_now = 0, 0, RUNNING, t
                        while ticks < m and code == RUNNING:
                            saved = memory.copy(), mom_args[3].copy()
                            call(ticks, 1, n_steps, t_now, thr.args(True))
                            memory[:], mom_args[3][:] = saved  # the probe's control ran on the laws' state: undo
                            thr.command(t_now)
                            k1, s1, code = call(ticks, 1, n_steps, t_now, thr.args(False))
                            tr["saturated"][ticks] |= thr.sat
                            if k1 == 0:
                                break
                            ticks, n_steps = ticks + k1, n_steps + s1
                            t_now = float(st_t[n_steps - 1]) if n_steps else t_now
                    self.sensors.rewind(ticks, m)  # a settled phase: the next phase's ticks draw on from here
                    piece = {k: a[:ticks] for k, a in tr.items() if mlaw or k not in ("locked", "lyapunov", "wrench")}
                    piece["phase"] = np.full(ticks, ip)
                    piece["segment"] = np.full(ticks, segment)
                    pieces.append(piece)
                    if ticks:
                        last_T = piece["base_torque"][-1].copy()
                    if n_steps:
                        t = float(st_t[n_steps - 1])
                        steps += n_steps
                        if mlaw:
                            lyap.add(ip, st_lyap[:n_steps])
                        if self.rec is not None:
                            wrench = None
                            extra, st_m = {}, None
                            if thr is not None:  # the firings' wrench per step, the thrusters' topics, the momenta
                                held_cmd = np.array([c for c, _, _, _ in thr.ticks[-ticks:]]) if ticks else np.zeros((0, 6))
                                delivered, extra = thr.topics(st_thr[:n_steps],
                                                              np.repeat(held_cmd, self.n_sub, axis=0)[:n_steps])
                                st_m = st_mom[:n_steps]
                            if mlaw:
                                extra.update(lyap.topic(st_lyap[:n_steps]))
                            if self.record_wrench and thr is not None:
                                wrench = delivered
                            elif self.record_wrench:  # the law's torque of each tick, held over its plant steps
                                wrench = np.zeros((n_steps, 6))
                                if law_on and mlaw:  # a momentum law's whole wrench (ideal source)
                                    wrench[:] = np.repeat(piece["wrench"], self.n_sub, axis=0)[:n_steps]
                                elif law_on and thrusters:
                                    wrench[:, 3:6] = np.repeat(piece["base_torque"], self.n_sub, axis=0)[:n_steps]
                                if self.dist.shape[0]:  # plus the disturbances at each step's start
                                    wrench += self._disturbances(np.concatenate([[t_start], st_t[:n_steps - 1]]),
                                                                 np.concatenate([q_start[None], st_q[:n_steps - 1]]))
                            hold = lambda block: np.repeat(piece["arm"][:, block * n_arm:(block + 1) * n_arm],  # noqa: E731
                                                           self.n_sub, axis=0)[:n_steps]
                            self._record_slice(st_t[:n_steps], st_q[:n_steps], st_v[:n_steps], st_tw[:n_steps],
                                               np.repeat(piece["x"][:, X_REF:X_REF + 4], self.n_sub, axis=0)[:n_steps],
                                               wrench, hold(4), hold(1), ev[:ev_n[0]], held, extra or None, st_m,
                                               st_eta[:n_steps] if ne else None, st_etadot[:n_steps] if ne else None)
                    self.progress.update(t)
                    raise_on_failure(code, v, spec, MODAL_LIMIT)
                    if code == SETTLED:
                        break
                    tick0 += ticks
                spans.append((ip, t_phase0, t))
                propellant[ip] = (used0, thr.used if thr else 0.0)
                q_att_ref = att.at(phase.duration).quat if phase.attitude is not None else q_att_ref
                q_arm_ref = rr_args[-1].copy() if phase.end_effector is not None else joints.final
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
        if spans and spans[-1][0] not in propellant:  # a phase ended by an interruption
            propellant[spans[-1][0]] = (used0, thr.used if thr else 0.0)
        wall = time.perf_counter() - wall0
        filled = [p for p in pieces if p["t"].size]
        if status == "completed" and filled:  # the final state, as the Python loop adds it
            if ne:
                mom = self._modal_momenta(q[None], v[None], eta[None], etadot[None])
            else:
                _, _, mom = self._samples(q[None], v[None]) if thr is None else (None, None, thr.momenta(q, v)[None])
            pieces.append({"t": np.array([t]), "att_err": np.array([np.linalg.norm(attitude_error(q_att_ref, q[3:7]))]),
                           "wheel_speed": v[wheel_v][None], "wheel_torque": filled[-1]["wheel_torque"][-1:],
                           "saturated": np.array([False]), "base_torque": last_T[None],
                           "momentum": np.concatenate([mom[0, 0:3], mom[0, 6:9]])[None], "energy": mom[0, 9:10],
                           "phase": np.array([len(spec.phases) - 1]), "arm": self._final_arm_row(q, v, q_arm_ref, filled),
                           "segment": np.array([segment]), "x": self._final_x_row(q, v, q_att_ref, held, filled),
                           "modal_peak": np.array([float(np.max(np.abs(eta))) if ne else 0.0])})
            if mlaw:  # μ at the final state and the last step's W (the Python loop's last _trace)
                mu = np.empty((1, 3))
                locked_velocity(v, mom_args[1] if thr is None else thr.law_model(q), mu[0])
                pieces[-1].update({"locked": mu, "lyapunov": mom_args[4].copy()})
        trace = self._trace_arrays(pieces, nw, n_arm)
        if mlaw:
            trace["locked"], trace["lyapunov"] = (np.concatenate([p[k] for p in pieces]) for k in ("locked", "lyapunov"))
        if thr is not None and trace["t"].size:
            trace.update(thr.trace(final=trace["t"].size > len(thr.ticks)))
        result = build_result(spec, sm, status, why, t, steps, trace, spans, wall, engine="compiled")
        if mlaw:
            lyap.metrics(result, spans)
        if thr is not None:  # propellant per phase, per attitude law and overall (kg)
            for summary, (ip, _, _) in zip(result.phases, spans):
                used = propellant.get(ip, (0.0, 0.0))
                summary["propellant_used_kg"] = used[1] - used[0]
            result.overall["propellant_used_kg"] = thr.used
            result.overall["propellant_used_by_law_kg"] = {self.law_name: thr.used}
        return result

    def _record_slice(self, times, qs, vs, tau_w, refs, wrench, tau_m, joint_ref, events, held=False, extra=None,
                      mom=None, etas=None, etadots=None) -> None:
        """``_record`` of a slice's steps (``refs``: the attitude reference per step; ``held``: the base held;
        ``extra``, ``mom``, ``etas``, ``etadots``: ``_record``'s, per step) with its joint-stop events in time order (an event before
        the samples at and after its time)."""
        def part(sl):  # the extra topics, momenta and modal states of the steps sl
            ex = None if extra is None else {k: {f: x[sl] for f, x in d.items()} for k, d in extra.items()}
            return ex, None if mom is None else mom[sl], {} if etas is None else {"etas": etas[sl], "etadots": etadots[sl]}

        start = 0
        for row in events:
            stop = int(np.searchsorted(times, row[0], side="left"))
            if stop > start:
                sl = slice(start, stop)
                ex, mo, md = part(sl)
                self._record(times[sl], qs[sl], vs[sl], tau_w[sl], refs[sl], wrench=None if wrench is None else wrench[sl],
                             tau_m=tau_m[sl], joint_ref=joint_ref[sl], held=held, extra=ex, mom=mo, **md)
                start = stop
            self._write_events(row[None])
        if start < times.size:
            sl = slice(start, None)
            ex, mo, md = part(sl)
            self._record(times[sl], qs[sl], vs[sl], tau_w[sl], refs[sl], wrench=None if wrench is None else wrench[sl],
                         tau_m=tau_m[sl], joint_ref=joint_ref[sl], held=held, extra=ex, mom=mo, **md)

    def _final_x_row(self, q, v, q_att_ref, held, filled) -> np.ndarray:
        """The loop.X_* row of the final state: the last reference, no end-effector error, the held base's
        reaction under the last torques (the Python loop's last ``_trace``)."""
        from sms_cli.sim.compiled.loop import ARM_TORQUE, X_N, X_REACTION, X_REF

        row = np.full((1, X_N), np.nan)
        row[0, X_REF:X_REF + 4] = q_att_ref
        if held:
            n = len(self.sm.arm)
            tau_m = filled[-1]["arm"][-1:, ARM_TORQUE * n:(ARM_TORQUE + 1) * n]
            row[0, X_REACTION:X_REACTION + 6] = self._held_reactions(q[None], v[None], filled[-1]["wheel_torque"][-1:], tau_m)[0]
        return row

    def _final_arm_row(self, q, v, q_arm_ref, filled) -> np.ndarray:
        """The arm trace row of the final state (the Python loop's last ``_trace``): error to the last
        phase's final reference, the last torque, q̇_d = 0, no time on stop."""
        from sms_cli.dynamics.joint_stops import arm_penetration
        from sms_cli.sim.base_motion import base_kinematics
        from sms_cli.sim.compiled.loop import ARM_BLOCKS

        sm = self.sm
        n = len(sm.arm)
        row = np.zeros((1, ARM_BLOCKS * n + 6))
        if n:
            q_arm = q[[a.q_index for a in sm.arm]]
            row[0, 0:n] = q_arm_ref - q_arm
            row[0, n:2 * n] = q_arm_ref
            row[0, 3 * n:4 * n] = v[sm.idx.arm]
            row[0, 4 * n:5 * n] = filled[-1]["arm"][-1, 4 * n:5 * n]
            row[0, 6 * n:7 * n] = arm_penetration(self.stop_table, n, q)
            row[0, 7 * n:] = base_kinematics(sm, q, v)
        return row

    @staticmethod
    def _trace_arrays(pieces: list[dict], nw: int, n_arm: int = 0) -> dict[str, np.ndarray]:
        """The Trace.arrays() dict of the Python engine, from the loop's slices."""
        def cat(key, width=None):
            parts = [p[key] for p in pieces if key in p]
            if parts:
                return np.concatenate(parts)
            return np.zeros((0,) if width is None else (0, width))

        a = {k: cat(k) for k in ("t", "att_err", "energy")}
        a["phase"] = cat("phase").astype(int)
        a["wheel_speed"], a["wheel_torque"] = cat("wheel_speed", nw), cat("wheel_torque", nw)
        a["saturated"] = cat("saturated").astype(bool)
        a["base_torque"], a["momentum"] = cat("base_torque", 3), cat("momentum", 6)
        n = a["t"].size
        from sms_cli.sim.compiled.loop import X_EE_ERR, X_N, X_REACTION

        # the extra columns (EE error, held base's reaction); NaN, as in the Python loop, where a loop has none (NDI)
        x = cat("x", X_N) if any("x" in p for p in pieces) else np.full((n, X_N), np.nan)
        peak = cat("modal_peak") if any("modal_peak" in p for p in pieces) else np.zeros(n)  # max |η| per tick
        a.update({"ee_err": x[:, X_EE_ERR], "modal_peak": peak, "base_reaction": x[:, X_REACTION:X_REACTION + 6],
                  "segment": cat("segment").astype(int)})
        arm = cat("arm", 7 * n_arm + 6)
        block = lambda b: arm[:, b * n_arm:(b + 1) * n_arm]  # noqa: E731  (loop.ARM_* blocks)
        a.update({"joint_err": block(0), "joint_torque": block(4), "joint_stop_time": block(5),
                  "joint_stop_penetration": block(6)})
        if n_arm and n:
            a.update({"joint_rate_ref": block(2), "joint_rate": block(3)})
            if not np.isfinite(a["base_reaction"]).all(axis=1).any():  # the Python loop has none while the base is held
                a["base_motion"] = arm[:, 7 * n_arm:]
        return a


class LyapunovSeries:
    """A momentum law's W and its terms as the Python loop keeps them (``Simulation._lyapunov``): evaluated at each
    phase start and after every plant step, recorded on ``/control/lyapunov`` (the law's ``terms``, in name order)
    and summarised per phase (``sms_cli.sim.laws.momentum.lyapunov_metrics``)."""

    def __init__(self, law, model):
        from sms_cli.sim.compiled import momentum_laws as K

        self.law = law
        self.model = model  # q -> the law's model tuple at q and the current mass (momentum_control)
        self.width = K.T_N
        self.names = sorted(law.terms)
        self.cols = [K.TERM_NAMES.index(n) for n in self.names]
        self._W, self._stage, self._pos, self._phase = K.T_W, K.T_STAGE, K.T_POSITION_ERROR, []
        self.rows: list[np.ndarray] = []

    def terms(self, q, v, ref) -> np.ndarray:
        """The law's W terms (T_N,) on (q, v) for the reference ``ref``, with its current state."""
        from sms_cli.sim.compiled import momentum_laws as K

        out = np.empty(self.width)
        K.momentum_lyapunov(int(self.law.code), np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(v, dtype=float),
                            np.ascontiguousarray(ref, dtype=float), *self.model(np.ascontiguousarray(q, dtype=float)), self.law.par, self.law.mem, out)
        return out

    def phase_start(self, ip: int, q, v, ref) -> float:
        """W at phase ``ip``'s start (added to the series); returned for the loop's first ticks."""
        row = self.terms(q, v, ref)
        self.add(ip, row[None])
        return float(row[self._W])

    def add(self, ip: int, rows: np.ndarray) -> None:
        self.rows.append(rows.copy())
        self._phase.append(np.full(rows.shape[0], ip))

    def topic(self, rows: np.ndarray) -> dict:
        """``/control/lyapunov`` of these rows: {field: values}."""
        return {"/control/lyapunov": {n: rows[:, c] for n, c in zip(self.names, self.cols)}}

    def metrics(self, result, spans) -> None:
        from sms_cli.sim.laws.momentum import lyapunov_metrics

        if not self.rows:
            return lyapunov_metrics(result, spans, np.zeros(0, dtype=int), np.zeros(0))
        a, phase = np.concatenate(self.rows), np.concatenate(self._phase)
        lyapunov_metrics(result, spans, phase, a[:, self._W], a[:, self._stage] if "stage" in self.names else None,
                         a[:, self._pos] if "position_error" in self.names else None)


class _Stop(Exception):
    """The compiled loop diverged (message = reason)."""


def raise_on_failure(code: int, v: np.ndarray, spec: SimulationSpec, modal_limit: int | None = None) -> None:
    """A slice's end code as the Python loop reports it: ``_Stop`` (the run diverged) for NON_FINITE,
    RATE_LIMIT (v: the velocities at the last tick) and ``modal_limit`` (the NDI loop's MODAL_LIMIT);
    RuntimeError for STOP_FAILED. Other codes (running, settled) pass."""
    from sms_cli.sim.compiled.loop import NON_FINITE, RATE_LIMIT, STOP_FAILED

    if code == NON_FINITE:
        raise _Stop("the state became non-finite")
    if code == RATE_LIMIT:
        vmax = float(np.max(np.abs(v)))
        raise _Stop(f"a generalized velocity reached {vmax:.4g} (limit {spec.divergence.max_rate:g})")
    if modal_limit is not None and code == modal_limit:
        raise _Stop(f"a modal amplitude exceeded {spec.divergence.max_modal_amplitude:g}")
    if code == STOP_FAILED:
        raise RuntimeError("joint stops: the complementarity pivoting did not terminate")
