"""The simulation loop: sense → control (ZOH at the control rate) → actuators → plant sub-steps
(RKMK4) → metrics and recording. Divergence stops the run cleanly and keeps what was recorded."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.dynamics.joint_stops import arm_penetration
from sms_cli.model.system import SystemModel
from sms_cli.sim.actuators import WheelArray, clip_joint_torque
from sms_cli.sim.attitude_math import attitude_error
from sms_cli.sim.interfaces import ArmRef, EndEffectorRef
from sms_cli.sim.metrics import Trace, conservation, summarize
from sms_cli.recording.recorder import RecordingInterrupted
from sms_cli.sim.references import AttitudeProfile, JointProfile
from sms_cli.sim.schema import PhaseSpec, SimulationSpec
from sms_cli.sim.sensors import Sensors


def attitude_from_gains(results_dir) -> object:
    """The attitude-law spec `sms synthesize` wrote into <results>/gains.yaml (pd, lqr, smc laws)."""
    from pathlib import Path

    from pydantic import TypeAdapter, ValidationError

    from sms_cli.errors import InputError, Problem
    from sms_cli.sim.laws.schema import AttitudeLawSpec
    from sms_cli.synthesis.gains_io import read_gains

    path = Path(results_dir) / "gains.yaml" if results_dir else None
    if path is None or not path.exists():
        raise InputError(problems=[Problem(f"simulation.attitude is 'from_gains' but there is no {path or 'gains.yaml'}",
                                           field="simulation.attitude",
                                           hint="run `sms synthesize` on this mission first with the same --out (sms run does)")])
    block = read_gains(path).simulation.get("attitude")
    if not block:
        raise InputError(problems=[Problem(f"{path} has no attitude law (its law is not pd, lqr or smc)",
                                           field="simulation.attitude", hint="set synthesis.law to pd, lqr or smc")])
    try:
        return TypeAdapter(AttitudeLawSpec).validate_python(block)
    except ValidationError as exc:
        raise InputError(problems=[Problem(f"{path}: its attitude law does not validate: {exc.errors()[0]['msg']}")]) from None


class Diverged(Exception):
    """The plant state became non-finite or exceeded the divergence limits."""


@dataclass
class SimResult:
    status: str  # completed | diverged | interrupted (SIGINT/SIGTERM: the metrics of what ran)
    t_end: float
    steps: int
    phases: list[dict]
    overall: dict
    conservation: dict
    divergence: str = ""
    timing: dict = field(default_factory=dict)
    trace: dict = field(default_factory=dict)


class Progress:
    """A one-line progress display on stderr (only when stderr is a terminal).

    The simulated time is a sum of steps, so it ends a few ulps short of the total: the percentage
    allows for that, ``finish`` shows a completed run as 100 % (also one whose last phase settled
    early) and ``close`` leaves the last time reached on the line."""

    def __init__(self, total: float, enabled: bool | None = None):
        self.total = total
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.last = -1
        self.t = 0.0
        self._shown = None  # the (t, %) on the line

    def percent(self, t: float) -> int:
        if self.total <= 0:
            return 100
        return max(0, min(100, int(100 * t / self.total + 1e-6)))  # 1e-6 %: round-off of the summed steps

    def update(self, t: float) -> None:
        self.t = t
        if not self.enabled:
            return
        pct = self.percent(t)
        if pct != self.last:
            self._draw(t, pct)

    def finish(self, t: float) -> None:
        """The run completed at ``t``: 100 %."""
        self.t = t
        if self.enabled:
            self._draw(t, 100)

    def _draw(self, t: float, pct: int) -> None:
        self.last, self._shown = pct, (t, pct)
        sys.stderr.write(f"\r  simulating {t:9.2f} / {self.total:.2f} s  [{'#' * (pct // 4):<25}] {pct:3d}%")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            if self._shown is None or self._shown[0] != self.t:
                self._draw(self.t, self.percent(self.t))
            sys.stderr.write("\n")


class Simulation:
    """One mission simulation on a compiled SystemModel. ``any_gains``: an NDI mission whose gains are
    not synthesized yet gets gains of the right shapes (for ``kernel_groups`` only: the kernels compile
    for argument types; ``sms warmup``), not an error."""

    def __init__(self, sm: SystemModel, spec: SimulationSpec, recorder=None, progress: bool | None = None,
                 results_dir=None, mission_dir=None, any_gains: bool = False):
        from sms_cli.sim.laws import build_arm_law, build_attitude_law, build_resolved_rate

        self.sm = sm
        self.spec = spec
        self.rec = recorder
        self._progress_flag = progress
        self.sensors = Sensors(sm, spec.sensors)
        self.wheels = WheelArray(sm, spec.allocation, spec.wheel_friction)
        att_spec = self.att_spec = attitude_from_gains(results_dir) if spec.attitude == "from_gains" else spec.attitude
        self.att_law = build_attitude_law(att_spec, sm) if att_spec else None
        self.arm_law = build_arm_law(spec.arm, sm) if spec.arm else None
        self.rr = build_resolved_rate(spec.resolved_rate, sm) if spec.resolved_rate else None
        # the compiled loop runs the mission when it fits it; otherwise the Python loop below, with
        # the compiled plant step when the model allows it and recording in blocks
        self.compiled_loop = spec.engine != "python" and self.compiled_unsupported() is None
        self._compiled = None  # the CompiledSimulation, made by warm_up
        self.plant = None
        if not self.compiled_loop and spec.engine != "python":
            from sms_cli.sim.compiled.plant import CompiledPlant, unsupported_reason

            if unsupported_reason(sm) is None:
                self.plant = CompiledPlant(sm)
        if recorder is not None and not self.compiled_loop:
            from sms_cli.recording.buffer import RecordBuffer

            from sms_cli.sim.timing import records_base_wrench

            self._buffer = RecordBuffer(sm, recorder)
            self._record_wrench = records_base_wrench(spec)  # thrusters or disturbances: /base/wrench
        self.ndi = None
        if spec.ndi is not None:
            from sms_cli.sim.laws.ndi import build_ndi

            self.ndi = build_ndi(spec.ndi, sm, 1.0 / spec.control_rate, results_dir, mission_dir, any_gains)
        self.dt = spec.dt
        self.n_sub = int(round(1.0 / spec.control_rate / spec.dt))
        self.total_time = sum(p.duration for p in spec.phases)
        self.progress = Progress(self.total_time, progress)
        self.arm_names = [a.name for a in sm.arm]
        self._fixed = False
        self._segment = 0
        self._base_torque = np.zeros(3)
        self._mom_t, self._mom = None, None
        self._init_stops()
        self.thr = None  # real thrusters (sms_cli.thrusters.drive) instead of the ideal torque source
        if sm.thrusters is not None:
            from sms_cli.sim.timing import uses_thrusters
            from sms_cli.thrusters.drive import ThrusterDrive

            if uses_thrusters(spec):
                on_change = (lambda: self.plant.refresh_body(sm.base_joint_id)) if self.plant is not None else None
                self.thr = ThrusterDrive(sm, sm.thrusters, on_change=on_change)
        self._propellant: dict[int, list[float]] = {}  # phase index -> [used at its start, used at its end] (kg)
        # momentum laws' Lyapunov function W (sms_cli.sim.laws.momentum): evaluated on the state after every
        # plant step, recorded on /control/lyapunov, summarised in the metrics
        self._lyap_on = hasattr(self.att_law, "lyapunov_terms")
        self.lyapunov_series: list[tuple[int, float, dict]] = []  # (phase index, t, {W, terms})
        if getattr(self.att_law, "uses_wrench", False):
            from sms_cli.errors import InputError, Problem

            bad = [p.name for p in spec.phases if p.base_mode == "rotation-free-floating" and spec.attitude_actuator != "thrusters"]
            if bad:
                raise InputError(problems=[Problem(f"attitude law {att_spec.law!r} commands a base wrench (thrusters) but "
                                                   f"phase(s) {bad} drive the attitude with the wheels", field="simulation.phases",
                                                   hint="use base_mode: free-flying (or attitude_actuator: thrusters)")])

    # ------------------------------------------------------------------ helpers
    def _init_stops(self) -> None:
        """Joint stops (simulation.joint_stops): the law, and the Pinocchio plants it steps when the
        compiled plant does not (the Python engine, a held base). The stop table is kept without the law
        too: the trace then shows how far the joints run past their limits."""
        from sms_cli.dynamics.joint_stops import JointStops, PinocchioPlant, stop_table

        self._stop_table = stop_table(self.sm)
        enabled = self.spec.joint_stops.enabled and self._stop_table.n > 0
        self.stops = JointStops(self.sm, self.spec.joint_stops.restitution) if enabled else None
        self._pin_plants = {False: PinocchioPlant(self.sm), True: PinocchioPlant(self.sm, fixed=True)}

    def _stop_step(self, s: State, tau: np.ndarray, t: float, fixed: bool, dt: float | None = None) -> State:
        """One plant step (of dt, default the plant step) under the stop law; its arrivals and releases go to /events."""
        plant = self.plant if self.plant is not None and not fixed else self._pin_plants[fixed]
        s = self.stops.step(plant, s, tau, self.dt if dt is None else dt, t)
        if self.stops.events:
            if self.rec is not None:
                for ev in self.stops.events:
                    self._event(*ev)
            self.stops.events.clear()
        return s

    def _advance(self, s: State, tau: np.ndarray, h: float, t: float, fixed: bool) -> State:
        """One plant step of length h (s) from time t under tau: the thrusters' pieces of a plant step."""
        if self.stops is not None:
            return self._stop_step(s, tau, t, fixed, h)
        if self.plant is not None and not fixed:
            return self.plant.step(s, tau, h)
        fd = self.sm.forward_dynamics_fixed_base if fixed else self.sm.forward_dynamics
        return rkmk4_step(self.sm.model, s, h, lambda q, v, e, ed: fd(q, v, e, ed, tau))

    def _accel(self, tau: np.ndarray, fixed: bool = False):
        fd = self.sm.forward_dynamics_fixed_base if fixed else self.sm.forward_dynamics
        return lambda q, v, e, ed: fd(q, v, e, ed, tau)

    def _disturbance(self, t: float, q: np.ndarray) -> np.ndarray:
        """The disturbances' wrench [f; n] on the base (base frame) at t and q: the compiled loop's kernel
        (``sms_cli.sim.compiled.disturbances.disturbance_wrench``)."""
        from sms_cli.sim.compiled.disturbances import disturbance_table, disturbance_wrench

        if getattr(self, "_dist_table", None) is None:
            self._dist_table = disturbance_table(self.spec.disturbances)
        w = np.empty(6)
        disturbance_wrench(self._dist_table, float(t), np.ascontiguousarray(q, dtype=float), w)
        return w

    def _check(self, s: State) -> None:
        lim = self.spec.divergence
        if not (np.all(np.isfinite(s.v)) and np.all(np.isfinite(s.q)) and np.all(np.isfinite(s.eta))):
            raise Diverged("the state became non-finite")
        vmax = float(np.max(np.abs(s.v)))
        if vmax > lim.max_rate:
            raise Diverged(f"a generalized velocity reached {vmax:.4g} (limit {lim.max_rate:g})")
        if s.eta.size and float(np.max(np.abs(s.eta))) > lim.max_modal_amplitude:
            raise Diverged(f"a modal amplitude exceeded {lim.max_modal_amplitude:g}")

    def _momentum(self, t: float, s: State):
        """(p, k about the CoM, k about the world origin), world frame, once per time (recording and metrics share it)."""
        if self._mom_t != t:
            self._mom_t = t
            self._mom = self.sm.momenta(s.q, s.v, s.etadot)
        return self._mom

    def _ee_position(self, q: np.ndarray) -> np.ndarray:
        return self.sm.frame_pose(q, self.sm.ee_frame_id).translation

    # ------------------------------------------------------------------ recording
    def _record(self, t: float, s: State, att_ref, arm_ref, tau_w, tau_m, att_err_vec, base_wrench, initial=False) -> None:
        """Queue the sample at t (reserved with ``recorder.take``); written in blocks by the buffer. The
        torques and ``base_wrench`` are those applied over the plant step ending at t (``sms_cli.sim.timing``)."""
        p, k, _ = self._momentum(t, s)
        reaction = self._held_base_reaction(s, tau_w, tau_m) if self._fixed else None
        locked = None
        if self.sm.wheels:  # /momentum/locked: μ at the sample's time (a payload may attach before the flush)
            from sms_cli.dynamics.locked import locked_velocity

            locked = locked_velocity(self.sm, s.q, s.v, s.etadot)
        extra = None
        if self.thr is not None:
            from sms_cli.thrusters.topics import thruster_topics

            extra = thruster_topics(self.thr, zero=initial)
        if self._lyap_on:  # W and its terms at the sample's time (Vicariotto 2023 (4.9), (4.17), L768, L818, L830)
            d = self.lyapunov_series[-1][2] if self.lyapunov_series and self.lyapunov_series[-1][1] == t else \
                self.att_law.lyapunov_terms(s.q, s.v, att_ref.quat)
            extra = dict(extra or {})
            extra["/control/lyapunov"] = {k: float(d[k]) for k in sorted(d)}
        self._buffer.add(t, s.q, s.v, s.eta, tau_w, tau_m, att_ref.quat, arm_ref.q, att_err_vec, p, k, reaction,
                         base_wrench if self._record_wrench else None, extra, locked=locked)

    def _lyapunov(self, ip: int, t: float, s: State, att_ref) -> None:
        self.lyapunov_series.append((ip, t, self.att_law.lyapunov_terms(s.q, s.v, att_ref.quat)))

    def _lyapunov_metrics(self, result) -> None:
        """W's figures per phase and overall (``sms_cli.sim.laws.momentum.lyapunov_metrics``) from the series."""
        from sms_cli.sim.laws.momentum import lyapunov_metrics

        rows = [d for _, _, d in self.lyapunov_series]
        col = lambda k: np.array([d[k] for d in rows]) if rows and k in rows[0] else None  # noqa: E731
        lyapunov_metrics(result, self._spans, np.array([i for i, _, _ in self.lyapunov_series], dtype=int),
                         np.array([d["W"] for d in rows]), col("stage"), col("position_error"))

    def _held_base_reaction(self, s: State, tau_w, tau_m) -> np.ndarray:
        """Wrench [f; n] (base frame) the support applies to hold the base while the wheels and the arm
        apply ``tau_w`` and ``tau_m`` at state ``s``."""
        sm = self.sm
        tau = np.zeros(sm.nv)
        if sm.wheels:
            tau[sm.idx.wheels] = tau_w
        if sm.arm:
            tau[sm.idx.arm] = tau_m
        vd, ed = sm.forward_dynamics_fixed_base(s.q, s.v, s.eta, s.etadot, tau)
        return sm.base_reaction(s.q, s.v, s.eta, s.etadot, vd, ed)

    def _event(self, t: float, name: str, detail: dict, level: str = "info") -> None:
        """An /events record, after the samples queued before it."""
        self._buffer.flush()
        self.rec.write_event(t, name, detail, level=level)

    # ------------------------------------------------------------------ engines
    def compiled_unsupported(self) -> str | None:
        """Why the compiled engine cannot run this mission (None: it can)."""
        from sms_cli.sim.compiled.runner import unsupported_reason

        return unsupported_reason(self.sm, self.spec, self.att_spec)

    def check_engine(self) -> None:
        """InputError (exit 2) when ``engine: compiled`` is asked for a mission the compiled loop cannot run."""
        from sms_cli.errors import InputError, Problem

        if not self.compiled_loop and self.spec.engine == "compiled":
            why = self.compiled_unsupported()
            raise InputError(problems=[Problem(f"the compiled engine cannot run this mission: {why}",
                                               field="simulation.engine",
                                               hint="write engine: auto (the Python loop runs it) or python")])

    def run(self) -> SimResult:
        """Run the mission with the engine ``simulation.engine`` asks for (see SimulationSpec)."""
        self.check_engine()
        self.warm_up()  # the first run after an install compiles the kernels (cached afterwards)
        if self.compiled_loop:
            return self._compiled.run()
        return self.run_python()

    def warm_up(self) -> None:
        """Load (on a cold cache: compile, in parallel) the kernels of ``kernel_groups``."""
        from sms_cli.sim.compiled.warmup import warm

        warm(self.kernel_groups())

    def kernel_groups(self) -> list:
        """The kernel calls the chosen loop makes (``sms_cli.sim.compiled.warmup``), from the objects
        that make them (``sms_cli.sim.compiled.kernels``): the compiled loop, or the compiled plant (and
        its joint-stop kernels) and the attitude law's, and the recording's."""
        from sms_cli.sim.compiled.kernels import kernel_groups

        if self.compiled_loop and self.ndi is not None:  # the NDI loop (sms_cli.sim.compiled.ndi_runner)
            if self._compiled is None:
                from sms_cli.sim.compiled.ndi_runner import NdiCompiledSimulation

                self._compiled = NdiCompiledSimulation(self.sm, self.spec, self.rec, self._progress_flag, self.ndi)
            groups = self._compiled.warm_groups()
        elif self.compiled_loop:
            if self._compiled is None:
                from sms_cli.sim.compiled.runner import CompiledSimulation

                self._compiled = CompiledSimulation(self.sm, self.spec, self.rec, self._progress_flag, self.att_law,
                                                    arm_law=self.arm_law, rr=self.rr, att_spec=self.att_spec)
            kin = self._compiled.kinematics
            groups = kernel_groups(self.sm, loop_tree=kin.tree, recording=kin if self.rec is not None else None,
                                   loop=self._compiled)
        else:
            buffer = getattr(self, "_buffer", None)
            groups = kernel_groups(self.sm, plant=self.plant, stops=self.stops is not None,
                                   recording=(buffer.kinematics or False) if buffer is not None else None, law=self.att_law,
                                   arm_law=self.arm_law, rr=self.rr, disturbed=bool(self.spec.disturbances))
            if self.ndi is not None:  # the NDI law's kernels (sms_cli.sim.compiled.ndi_law)
                groups.append(self.ndi.warm_calls())
            if self.sensors.noisy:  # the measurement's kernel (Sensors.measure)
                groups.append([self.sensors.warm_call()])
        return groups

    # ------------------------------------------------------------------ main loop
    def run_python(self) -> SimResult:
        """The reference loop in Python (every feature)."""
        sm, spec = self.sm, self.spec
        s = State(sm.q0.copy(), sm.v0.copy(), sm.eta0.copy(), sm.etadot0.copy())
        trace = Trace()
        t = 0.0
        steps = 0
        q_att_ref = s.q[3:7].copy()
        q_arm_idx = [a.q_index for a in sm.arm]
        q_arm_ref = s.q[q_arm_idx].copy() if sm.arm else np.zeros(0)
        status, why = "completed", ""
        phase_spans: list[tuple[int, float, float]] = []
        wall0 = time.perf_counter()
        if self.rec is not None and self.rec.take(t):  # the initial state is part of the recording
            n_arm = len(q_arm_ref)
            self._record(t, s, AttitudeProfile(q_att_ref, None, "step", None).at(0.0),
                         ArmRef(q_arm_ref.copy(), np.zeros(n_arm), np.zeros(n_arm)), np.zeros(self.wheels.n),
                         np.zeros(n_arm), np.zeros(3), np.zeros(6), initial=True)
        try:
            for ip, phase in enumerate(spec.phases):
                t_phase0 = t
                if self.thr is not None:
                    self._propellant[ip] = [self.thr.used, self.thr.used]
                self._begin_phase(phase, t)
                att = AttitudeProfile(q_att_ref, phase.attitude, phase.attitude_profile, phase.slew_time)
                joints = JointProfile(q_arm_ref, self.arm_names, phase.waypoints, phase.joint_profile)
                ee_start = self._ee_position(s.q)
                q_track = q_arm_ref.copy()
                n_ticks = int(round(phase.duration * spec.control_rate))
                fixed = self._fixed = phase.base_mode == "fixed"
                if fixed:
                    s.v[:6] = 0.0  # the support takes the base's momentum at the phase start
                settled_since = None
                if self._lyap_on:
                    self._lyapunov(ip, t, s, att.at(0.0))
                for tick in range(n_ticks):
                    tau_ph = t - t_phase0
                    sensed = self.sensors.measure(t, s.q, s.v, s.eta, s.etadot)
                    att_ref = att.at(tau_ph)
                    ee_err = float("nan")
                    if phase.end_effector is not None and self.rr is not None:
                        target = np.asarray(phase.end_effector.position, float) + (ee_start if phase.end_effector.relative_to_start else 0.0)
                        vel = np.asarray(phase.end_effector.velocity, float)
                        ee_ref = EndEffectorRef(target + vel * tau_ph, vel)
                        qd_cmd = self.rr.joint_rates(sensed, ee_ref)
                        q_track = q_track + qd_cmd / spec.control_rate
                        arm_ref = ArmRef(q_track.copy(), qd_cmd, np.zeros_like(qd_cmd))
                        ee_err = float(np.linalg.norm(self._ee_position(s.q) - ee_ref.position))
                    else:
                        arm_ref = joints.at(tau_ph)
                    tau_w, tau_m, base_wrench, sat = self._control(phase, sensed, att_ref, arm_ref)
                    if self.thr is not None:  # the law's wrench through allocation + modulation, not the ideal source
                        sat = self.thr.command(t, base_wrench) or sat
                        base_wrench = np.zeros(6)
                    err_vec = attitude_error(att_ref.quat, s.q[3:7])
                    self._trace(trace, t, ip, err_vec, arm_ref, s, tau_w, tau_m, sat, ee_err)
                    if self.wheels.n and (tick % 10 == 0):
                        self.wheels.update_effective_inertia(s.q)
                    tau_tick = np.zeros(sm.nv)
                    tau_tick[:6] = base_wrench
                    if sm.arm:
                        tau_tick[sm.idx.arm] = tau_m
                    wheels_live = self.wheels.n and (self.wheels.may_reach_limit(s.v[sm.idx.wheels], tau_w, self.n_sub * self.dt)
                                                      or self.wheels.has_friction)
                    if self.wheels.n and not wheels_live:
                        tau_tick[sm.idx.wheels] = tau_w
                    fd = self.sm.forward_dynamics_fixed_base if fixed else self.sm.forward_dynamics
                    rec_take = self.rec.take if self.rec is not None else None
                    for _ in range(self.n_sub):
                        if wheels_live or spec.disturbances:
                            tau = tau_tick.copy()
                            if spec.disturbances:
                                tau[:6] += self._disturbance(t, s.q)
                            if wheels_live:
                                ws = s.v[sm.idx.wheels]
                                tau[sm.idx.wheels] = self.wheels.speed_limited(tau_w, ws, self.dt) + self.wheels.friction_torque(ws)
                        else:
                            tau = tau_tick
                        if self.thr is not None:
                            s = self.thr.step(s, t, self.dt, tau, lambda s_, tau_, h, t_, _f=fixed: self._advance(s_, tau_, h, t_, _f))
                        elif self.stops is not None:
                            s = self._stop_step(s, tau, t, fixed)
                        elif self.plant is not None and not fixed:
                            s = self.plant.step(s, tau, self.dt)
                        else:
                            s = rkmk4_step(sm.model, s, self.dt, lambda q, v, e, ed, _tau=tau: fd(q, v, e, ed, _tau))
                        t += self.dt
                        steps += 1
                        if self._lyap_on:
                            self._lyapunov(ip, t, s, att_ref)
                        if rec_take is not None and rec_take(t):
                            self._record(t, s, att_ref, arm_ref, tau[sm.idx.wheels], tau_m, attitude_error(att_ref.quat, s.q[3:7]),
                                         tau[:6] + self.thr.delivered if self.thr is not None else tau[:6])
                    if self.stops is not None:  # this tick's time on stop and deepest penetration
                        trace.joint_stop_time[-1], trace.joint_stop_penetration[-1] = self.stops.interval(s)
                    self._check(s)
                    self.progress.update(t)
                    if phase.until_settled is not None:
                        if np.linalg.norm(attitude_error(att_ref.quat, s.q[3:7])) < phase.until_settled:
                            settled_since = t if settled_since is None else settled_since
                            if t - settled_since >= phase.settle_time:
                                break
                        else:
                            settled_since = None
                phase_spans.append((ip, t_phase0, t))
                if self.thr is not None:
                    self._propellant[ip][1] = self.thr.used
                q_att_ref = att.at(phase.duration).quat if phase.attitude is not None else q_att_ref
                q_arm_ref = q_track if phase.end_effector is not None else joints.final
            self.progress.finish(t)
        except Diverged as exc:
            status, why = "diverged", str(exc)
            if self.rec is not None:
                self._event(t, "diverged", {"reason": why}, level="error")
        except RecordingInterrupted:  # SIGINT/SIGTERM at a recorder call: the trace is whole up to t
            status = "interrupted"
            if not phase_spans or phase_spans[-1][0] != ip:
                phase_spans.append((ip, t_phase0, t))
            self._event(t, "interrupted", {"t": t}, level="warning")
        finally:
            self.progress.close()
            if self.rec is not None:
                self._buffer.flush()
            if self.thr is not None and self._propellant:
                self._propellant[max(self._propellant)][1] = self.thr.used
        wall = time.perf_counter() - wall0
        sensed = self.sensors.measure(t, s.q, s.v, s.eta, s.etadot) if status == "completed" else None
        if sensed is not None and trace.t:
            last_ref = AttitudeProfile(q_att_ref, None, "step", None).at(0.0)
            self._trace(trace, t, len(spec.phases) - 1, attitude_error(last_ref.quat, s.q[3:7]),
                        ArmRef(q_arm_ref, np.zeros_like(q_arm_ref), np.zeros_like(q_arm_ref)), s,
                        trace.wheel_torque[-1] if trace.wheel_torque else np.zeros(0),
                        trace.joint_torque[-1] if trace.joint_torque else np.zeros(0), False, float("nan"))
        return self._result(status, why, t, steps, trace, phase_spans, wall)

    def _begin_phase(self, phase: PhaseSpec, t: float) -> None:
        self._mom_t = None  # attaching or releasing a payload changes the momentum at the same t
        if phase.attach or phase.detach or phase.base_mode == "fixed" or self._fixed:
            self._segment += 1
        for name in phase.detach:
            self.sm.detach_payload(name)
        for name in phase.attach:
            self.sm.attach_payload(name)
        if self.plant is not None and (phase.attach or phase.detach):
            self.plant.refresh()
        if self.ndi is not None and (phase.attach or phase.detach):
            self.ndi.model_changed(self.sm)
        if self.rec is not None:
            self._event(t, "phase", phase_event(phase))

    def _control(self, phase: PhaseSpec, s, att_ref, arm_ref):
        """Controller outputs held over the control period: wheel torques, joint torques, base wrench."""
        sm = self.sm
        base_wrench = np.zeros(6)
        tau_w = np.zeros(self.wheels.n)
        sat = False
        self._base_torque = np.zeros(3)
        if phase.base_mode not in ("free-floating", "fixed") and hasattr(self.att_law, "actuate"):
            # momentum laws (sms_cli.sim.laws.momentum): wheel torques and base wrench directly, no allocation
            tw, wrench = self.att_law.actuate(s, att_ref)
            if tw is not None:
                tau_w, flags = self.wheels.clip_torque(np.asarray(tw, float))
                sat = bool(np.any(flags))
            if wrench is not None:
                base_wrench[:] = wrench
                self._base_torque = base_wrench[3:6].copy()
        elif phase.base_mode not in ("free-floating", "fixed") and self.att_law is not None:
            T = np.asarray(self.att_law.torque(s, att_ref), float)
            self._base_torque = T
            if phase.base_mode == "free-flying" or self.spec.attitude_actuator == "thrusters":
                lim = self.spec.attitude_torque_limit
                if lim is not None:  # the ideal source's per-axis limit (the compiled loop: clip_attitude_torque)
                    sat = bool(np.any(np.abs(T) > lim * (1 + 1e-12)))
                    T = self._base_torque = np.clip(T, -lim, lim)
                base_wrench[3:6] = T
            else:
                tau_w, flags = self.wheels.clip_torque(self.wheels.allocate(T, s.wheel_speed))
                sat = bool(np.any(flags))
        tau_m = np.zeros(len(sm.arm))
        if self.ndi is not None and phase.base_mode not in ("free-floating", "fixed"):
            tau_a = self.ndi.torques(s, att_ref, arm_ref)
            tau_w, fw = self.wheels.clip_torque(tau_a[: self.wheels.n])
            tau_m, fm = clip_joint_torque(sm, tau_a[self.wheels.n:])
            self.ndi.observe(np.concatenate([tau_w, tau_m]))
            return tau_w, tau_m, base_wrench, bool(self.ndi.saturated or np.any(fw) or np.any(fm))
        if self.arm_law is not None and sm.arm:
            tau_m, flags = clip_joint_torque(sm, np.asarray(self.arm_law.torque(s, arm_ref), float))
            sat = sat or bool(np.any(flags))
        return tau_w, tau_m, base_wrench, sat

    def _trace(self, tr: Trace, t, ip, err_vec, arm_ref, s: State, tau_w, tau_m, sat, ee_err) -> None:
        sm = self.sm
        tr.t.append(t)
        tr.phase.append(ip)
        tr.segment.append(self._segment)
        tr.att_err.append(float(np.linalg.norm(err_vec)))
        tr.joint_err.append(arm_ref.q - s.q[[a.q_index for a in sm.arm]] if sm.arm else np.zeros(0))
        tr.ee_err.append(ee_err)
        tr.wheel_speed.append(s.v[sm.idx.wheels].copy())
        tr.wheel_torque.append(np.asarray(tau_w, float).copy())
        tr.joint_torque.append(np.asarray(tau_m, float).copy())
        tr.saturated.append(sat)
        tr.base_torque.append(self._base_torque.copy())
        if sm.arm and not self._fixed:  # the arm's push on the free base: displacement, force (base_motion.py)
            from sms_cli.sim.base_motion import base_kinematics

            tr.base_motion.append(base_kinematics(sm, s.q, s.v))
        if sm.arm:  # Kraiem 2022 (3.67) rate tracking
            tr.joint_rate_ref.append(np.array(arm_ref.qd, float))
            tr.joint_rate.append(s.v[sm.idx.arm].copy())
            if self.ndi is not None and sm.wheels:  # the law's desired wheel rates (attitude hold included)
                tr.wheel_rate_ref.append(self.ndi.wheel_rate_ref.copy())
        if self.ndi is not None:  # the command's feedback, linearising and disturbance parts (zero where the law is off)
            on = self.spec.phases[ip].base_mode not in ("free-floating", "fixed")
            tr.ndi_torque_split.append(self.ndi.split.ravel().copy() if on else np.zeros(self.ndi.split.size))
        tr.modal_peak.append(float(np.max(np.abs(s.eta))) if s.eta.size else 0.0)
        tr.joint_stop_time.append(np.zeros(len(sm.arm)))  # the tick's time on stop: set after its plant steps
        tr.joint_stop_penetration.append(arm_penetration(self._stop_table, len(sm.arm), s.q))
        p, _, k_origin = self._momentum(t, s)
        tr.momentum.append(np.concatenate([p, k_origin]))
        tr.energy.append(sm.energy(s.q, s.v, s.eta, s.etadot))
        if self._fixed:
            tr.base_reaction.append(self._held_base_reaction(s, tau_w, tau_m))
        else:
            tr.base_reaction.append(np.full(6, np.nan))
        if self.thr is not None:
            tr.thruster_commanded.append(self.thr.commanded.copy())
            tr.thruster_delivered.append(self.thr.pattern_wrench)
            tr.thrust_total.append(float(self.thr.pattern_thrust.sum()))
            tr.propellant_used.append(float(self.thr.used))
        if self._lyap_on:  # the momentum laws' own quantities: mu (Vicariotto 2023 (4.8)) and W
            tr.locked.append(self.att_law.locked_velocity(s.q, s.v))
            # W at the end of the last plant step, i.e. at this tick (the series has one entry per step)
            tr.lyapunov.append(float(self.lyapunov_series[-1][2]["W"]) if self.lyapunov_series else float("nan"))

    def _result(self, status, why, t, steps, trace: Trace, spans, wall) -> SimResult:
        engine = "python" if self.plant is None else "python, compiled plant"
        result = build_result(self.spec, self.sm, status, why, t, steps, trace.arrays(), spans, wall, engine)
        if self._lyap_on:
            self._spans = spans
            self._lyapunov_metrics(result)
        if self.thr is not None:  # propellant per phase, per attitude law and overall (kg)
            law = getattr(self.att_spec, "law", "attitude")
            for summary, (ip, _, _) in zip(result.phases, spans):
                used = self._propellant.get(ip, [0.0, 0.0])
                summary["propellant_used_kg"] = used[1] - used[0]
            result.overall["propellant_used_kg"] = self.thr.used
            result.overall["propellant_used_by_law_kg"] = {law: self.thr.used}
        return result


def phase_event(phase: PhaseSpec) -> dict:
    """Detail of the /events "phase" event at a phase start."""
    return {"name": phase.name, "kind": phase.kind, "base_mode": phase.base_mode, "attach": phase.attach,
            "detach": phase.detach}


def build_result(spec: SimulationSpec, sm: SystemModel, status, why, t, steps, a: dict, spans, wall,
                 engine: str = "python") -> SimResult:
    """Metrics per phase and overall from the per-tick trace arrays ``a`` (``Trace.arrays()``)."""
    band = spec.settle_tolerance
    dtc = 1.0 / spec.control_rate
    names = [j.name for j in sm.arm]
    phases = []
    for ip, t0, t1 in spans:
        mask = a["phase"] == ip
        summary = summarize(a, mask, band, dtc, names) if np.any(mask) else {}
        summary.update({"name": spec.phases[ip].name, "kind": spec.phases[ip].kind, "duration_s": t1 - t0})
        phases.append(summary)
    overall = summarize(a, np.ones(a["t"].size, dtype=bool), band, dtc, names) if a["t"].size else {}
    timing = {"engine": engine, "wall_s": wall, "sim_s": t, "steps": steps, "us_per_step": 1e6 * wall / max(steps, 1),
              "real_time_factor": t / wall if wall > 0 else None}
    return SimResult(status, t, steps, phases, overall, conservation(a, np.array([w.spin_inertia for w in sm.wheels])),
                     why, timing, a)
