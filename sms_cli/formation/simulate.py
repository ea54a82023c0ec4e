"""The two-spacecraft simulation loop: sense (locked/shape state) → relative law (ZOH at the control rate)
→ pushes → plant step (RKMK4 of both free-flyers) → trace and recording.

Time: the plant advances by ``dt``; the law runs every ``control_period / dt`` steps; a push acts over the
plant steps whose start lies in [at, at + duration). Samples (trace, MCAP, relative_motion.csv) are taken at
t = 0 and every ``1 / record_rate``.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from sms_cli.formation.capture_phase import CaptureMissed
from sms_cli.formation.laws import BodyState, RelativeLaw
from sms_cli.formation.schema import SERVICER

RECORD_BLOCK = 256  # samples per recorded block


@dataclass
class FormationResult:
    """What a run produced: status (completed | diverged | interrupted), time reached, steps, the sampled
    trace (arrays with a leading time axis) and the wall time of the loop (s)."""

    status: str
    t_end: float
    steps: int
    trace: dict[str, np.ndarray]
    wall_s: float
    divergence: str = ""
    capture: dict | None = None
    engine: str = "python"


@dataclass(frozen=True)
class PairInterface:
    """The wrenches between the two bodies at a plant stage: the internal pair's reaction to ``F2`` (6, body 2's base
    frame; None: none) on body 1's base, −Ad_{g12}⁻ᵀ F2 at the stage's relative pose g12 = g1⁻¹ g2 (so that the pair
    stays equal and opposite, total momentum conserved, while the bodies turn), and the engaged ``capture``
    interface (None: none). Called as interface(q, v) it evaluates them with Pinocchio (``TwoBodyPlant.step``, the
    reference); the compiled step (``sms_cli.sim.compiled.pair``) reads the fields and evaluates them itself."""

    plant: object
    F2: np.ndarray | None = None
    capture: object | None = None

    def __call__(self, qs: np.ndarray, vs: np.ndarray) -> list:
        out = []
        if self.F2 is not None:
            p = self.plant
            g12 = p.base_pose(qs, 0).actInv(p.base_pose(qs, 1))
            out.append((p.bodies[0].base_frame_id, -(g12.dualAction @ self.F2)))
        if self.capture is not None:
            out += self.capture.wrenches(qs, vs)
        return out


class FormationSimulation:
    """Simulates a mission's ``formation:`` section. ``servicer`` and ``client`` are the two SystemModels;
    body 1 (the master) is the one ``formation.master`` names."""

    def __init__(self, mission, servicer, client, recorder=None, progress: bool | None = None, locate=None):
        from sms_cli.formation.plant import TwoBodyPlant

        self.spec = spec = mission.formation
        names = (SERVICER, mission.client.name)
        models = {SERVICER: servicer, mission.client.name: client}
        self.names = (spec.master, names[1] if spec.master == names[0] else names[0])
        self.plant = TwoBodyPlant.build(models[self.names[0]], models[self.names[1]], names=self.names)
        self.recorder = recorder
        from sms_cli.formation.capture_phase import CapturePhase
        from sms_cli.formation.recording import RecordedLinks

        locate = locate or (lambda path: None)
        self.capture = (CapturePhase(spec.capture, self.plant, SERVICER, mission.client.name, float(spec.dt), locate)
                        if spec.capture is not None else None)
        self.pair = None  # the compiled plant step (sms_cli.sim.compiled.pair), made by _stepper when it runs
        self.step = self._stepper(spec.integrator)
        self.drives = self._thruster_drives(locate)
        servicer_body = self.plant.body(SERVICER)
        self.arm_v = servicer_body.arm_v
        self.arm_q = np.array([servicer_body.q.start + 7 + (j - servicer_body.joints_v.start)
                               for j in servicer_body.arm_v], dtype=int)
        self.arm_limits = np.array([a.max_effort for a in servicer_body.system.arm], float)

        self.links = RecordedLinks(self.plant)
        self.progress = sys.stderr.isatty() if progress is None else progress
        # poses at t = 0: the servicer's base from the mission's initial state, the client's relative to it
        from sms_cli.formation.client import initial_poses

        g_servicer, g_client = initial_poses(mission, servicer)
        poses = {SERVICER: g_servicer, mission.client.name: g_client}
        self.g0 = (poses[self.names[0]], poses[self.names[1]])
        self.wheel_limits = [np.array([w.max_torque for w in b.system.wheels], float) for b in self.plant.bodies]
        # each body's wheels among its joints: the columns of its connection, the block of its joints' shape inertia
        self._wheel_sel = [(w, np.ix_(w, w)) for w in (b.wheels_v - b.joints_v.start for b in self.plant.bodies)]
        self.q, self.v = self._initial_state()
        self.arm_q0 = self.q[self.arm_q].copy()
        self.law = RelativeLaw(spec, self.g0[0], self.g0[0].actInv(self.g0[1]), self.names)
        # the shape wrench is an internal pair (F_L = 0): free-flying or hierarchical law, locked system free, both
        # bodies acting through ideal sources
        self.internal_pair = ((self.law.free_flying or self.law.hierarchical) and not self.law.locked.controlled
                              and self.law.actuation == "both" and not self.drives)

    # ---------------------------------------------------------------- state
    def _initial_state(self):
        """q, v with the wheels at their initial speeds and the bases moving so that the locked and shape twists
        are ``formation.initial``'s."""
        p = self.plant
        ini = self.spec.initial
        if ini.bodies:  # each base's own twist (its base frame)
            V = [ini.bodies[n].as_array() if n in ini.bodies else np.zeros(6) for n in self.names]
            return p.initial_state(self.g0[0], V[0], self.g0[1], V[1])
        q, v = p.initial_state(self.g0[0], np.zeros(6), self.g0[1], np.zeros(6))
        dec, _, _ = p.decomposition(q, v)
        xi = dec.body_twists(ini.locked.as_array(), ini.shape.as_array())
        for i in range(2):
            body = p.bodies[i]
            connection, _ = p.connection(p.mass_matrix(q), i)
            v[body.base_v] = xi[i] - connection @ v[body.joints_v]  # V_i = ξ_i − Λ_i θ̇_i
        return q, v

    def body_states(self, q, v):
        """(PairDecomposition, BodyState of body 1, of body 2, mass matrix) at (q, v); the BodyStates carry the
        wheels' part of the connection (arm joints, if any, are the arm law's)."""
        p = self.plant
        M = p.mass_matrix(q)
        dec = p.pair_decomposition(q, M)
        out = []
        for i, body in enumerate(p.bodies):
            xi, Lam, Mth = p.locked_state(M, v, i)
            wsel, wblock = self._wheel_sel[i]
            out.append(BodyState(p.base_pose(q, i), p.base_twist(v, i), xi, v[body.wheels_v], Lam[:, wsel], self.wheel_limits[i],
                                 Mth[wblock]))
        return dec, out[0], out[1], M

    def _thruster_drives(self, locate) -> list:
        """(body index, ThrusterDrive) of each spacecraft with a thruster set, its tank on the combined model's base
        body; the control period must be a whole number of its firing cycles (one allocation per tick)."""
        from types import SimpleNamespace

        from sms_cli.errors import InputError, Problem
        from sms_cli.thrusters.drive import ThrusterDrive

        drives = []
        period = 1.0 / float(self.spec.control_rate)
        for i, body in enumerate(self.plant.bodies):
            ts = body.system.thrusters
            if ts is None:
                continue
            k = period / ts.firing_cycle
            if abs(k - round(k)) > 1e-9 * max(k, 1) or round(k) < 1:
                raise InputError(problems=[Problem(
                    f"the control period ({period:g} s) is not a whole number of {body.name}'s firing cycles "
                    f"({ts.firing_cycle:g} s)", locate(("formation", "control_rate")), "formation.control_rate",
                    f"set formation.control_rate to {1 / ts.firing_cycle:g} Hz or a divisor of it")])
            view = SimpleNamespace(model=self.plant.model, base_joint_id=body.base_joint_id)
            on_change = (lambda j=body.base_joint_id: self.pair.refresh_body(j)) if self.pair is not None else None
            drives.append((i, ThrusterDrive(view, ts, on_change=on_change)))
        return drives

    @property
    def engine(self) -> str:
        """Which plant step runs: "python" (Pinocchio's) or "python, compiled plant" (``formation.engine``: auto), as
        the single-spacecraft simulation's ``timing.engine`` says."""
        return "python" if self.pair is None else "python, compiled plant"

    def _stepper(self, integrator: str):
        """step(q, v, dt, tau, base_wrenches, interface) -> (q, v) of the chosen integrator (built after every frame
        is added to the plant): with the plain integrator and ``engine: auto``, the compiled step where both models
        flatten (``sms_cli.sim.compiled.pair``), else ``TwoBodyPlant.step``."""
        if integrator == "plain":
            from sms_cli.sim.compiled.pair import PairPlant, unsupported_reason

            if self.spec.engine == "python" or unsupported_reason(self.plant) is not None:
                return self.plant.step
            self.pair = pair = PairPlant(self.plant)

            def compiled_step(q, v, dt, tau, base_wrenches, interface=None):
                if interface is None:
                    return pair.step(q, v, dt, tau, base_wrenches)
                if not isinstance(interface, PairInterface):  # any other wrenches: the reference step evaluates them
                    return self.plant.step(q, v, dt, tau, base_wrenches, interface)
                cap = interface.capture
                return pair.step(q, v, dt, tau, base_wrenches, interface.F2, None if cap is None else (
                    cap.frame_a, cap.frame_b, cap.target, cap.gains.K, cap.gains.D))

            return compiled_step
        from sms_cli.formation.plant import DecomposedIntegrator

        decomposed = DecomposedIntegrator(self.plant)

        def step(q, v, dt, tau, base_wrenches, interface=None):
            qn, y = decomposed.step(q, decomposed.to_decomposed(q, v), dt, tau, base_wrenches, interface)
            return qn, decomposed.to_plain(qn, y)

        return step

    def _propellant(self, i: int) -> float:
        """Propellant used so far by body i's thrusters (kg; 0 without thrusters)."""
        return next((d.used for j, d in self.drives if j == i), 0.0)

    def _thrusters_step(self, q, v, t: float, dt: float, tau, base, interface):
        """One plant step cut at every thruster switching of either spacecraft (``step_drives``): ``base`` the other
        base wrenches (ideal sources, pushes), the firings added to their bodies."""
        from sms_cli.thrusters.drive import step_drives

        def advance(state, wrenches, h, a):
            W = [base[0], base[1]]
            for (i, _), w in zip(self.drives, wrenches):
                W[i] = W[i] + w
            return self.step(state[0], state[1], h, tau, (W[0], W[1]), interface)

        return step_drives([d for _, d in self.drives], (q, v), t, dt, advance)

    def _delivered(self, cmd) -> tuple[np.ndarray, np.ndarray]:
        """The base wrenches delivered over the last plant step (thrusters: their firings' average; else the
        commanded wrench)."""
        out = [cmd.F1, cmd.F2]
        for i, d in self.drives:
            out[i] = d.delivered.copy()
        return out[0], out[1]

    def _interface(self, F2):
        """The plant step's interface: the internal pair's reaction to F2 (None: none) and the engaged capture
        interface (a ``PairInterface``), or None when neither acts."""
        capture = self.capture if self.capture is not None and self.capture.gains is not None else None
        return None if F2 is None and capture is None else PairInterface(self.plant, F2, capture)

    def _arm_hold(self, q, v) -> np.ndarray:
        """The servicer's arm torques: the joint PD of ``formation.arm_hold`` about the initial configuration,
        clipped to each joint's effort limit (zero without arm_hold)."""
        hold = self.spec.arm_hold
        if hold is None:
            return np.zeros(self.arm_v.size)
        tau = -float(hold.kp) * (q[self.arm_q] - self.arm_q0) - float(hold.kd) * v[self.arm_v]
        return np.clip(tau, -self.arm_limits, self.arm_limits)

    # ---------------------------------------------------------------- pushes
    def _push_wrenches(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The push wrenches on body 1 and body 2 (base frames, [f; p × f]) acting over the step starting at t."""
        F = [np.zeros(6), np.zeros(6)]
        for push in self.spec.pushes:
            if push.at - 1e-9 <= t < push.at + push.duration - 1e-9:
                f = np.asarray(push.force, float)
                F[self.names.index(push.body)] += np.concatenate([f, np.cross(np.asarray(push.point, float), f)])
        return F[0], F[1]

    # ---------------------------------------------------------------- loop
    def kernel_groups(self) -> list:
        """The compiled kernels a run makes, as warm-up calls (``sms_cli.sim.compiled.warmup``, ``sms warmup``): the
        compiled plant step (and the capture monitor's wrench pair), the locked/shape decomposition (and the rate of
        S⁻¹ for the decomposed integrator), the relative law (C*, the pose potentials), the recording's /tf of the world
        link poses and its encoding."""
        from sms_cli.formation.decomposition import warm_calls
        from sms_cli.formation.laws import law_warm_call
        from sms_cli.recording.encoding import warm_call
        from sms_cli.recording.recorder import world_block_warm_call

        groups = [[self.pair.warm_call()]] if self.pair is not None else []
        if self.pair is not None and self.capture is not None:
            groups.append([self.pair.capture_warm_call()])  # the capture monitor's samples
        groups.append([*warm_calls(rates=self.spec.integrator == "decomposed"), law_warm_call()])
        return groups + [[world_block_warm_call(), warm_call()]]

    def run(self) -> FormationResult:
        from sms_cli.sim.compiled.warmup import warm

        warm(self.kernel_groups())  # the first run after an install compiles the kernels (cached afterwards)
        spec, p = self.spec, self.plant
        dt = float(spec.dt)
        n_steps = int(round(spec.duration / dt))
        per_control = int(round((1.0 / spec.control_rate) / dt))
        per_sample = max(1, int(round((1.0 / spec.record_rate) / dt)))
        q, v = self.q, self.v
        rows: dict[str, list] = {}
        self._recorded = 0
        tau = np.zeros(p.model.nv)
        cmd = None
        status, divergence, k = "completed", "", 0
        wall0 = time.perf_counter()
        try:
            for k in range(n_steps + 1):
                t = k * dt
                control, sample = k % per_control == 0, k % per_sample == 0 or k == n_steps
                states = self.body_states(q, v) if control or sample else None
                if control:
                    cmd = self.law(*states[:3])
                    tau[:] = 0.0
                    tau[p.bodies[0].wheels_v] = cmd.tau_w1
                    tau[p.bodies[1].wheels_v] = cmd.tau_w2
                    ideal = [cmd.F1, cmd.F2]
                    for i, drive in self.drives:  # these bodies' wrenches go to their thrusters
                        drive.command(t, ideal[i])
                        ideal[i] = np.zeros(6)
                    # F2 held in frame 2; its reaction on body 1 follows the relative pose at every stage
                    reaction = cmd.F2 if self.internal_pair else None
                    interface = self._interface(reaction)
                if sample:
                    self._sample(rows, t, q, v, cmd, states)
                if k == n_steps:
                    break
                P1, P2 = self._push_wrenches(t)
                if self.capture is not None:
                    if self.capture.due(t):
                        self.capture.engage(t, q, v)
                        interface = self._interface(reaction)
                    self.capture.sample(q, v, self.pair)
                if self.arm_v.size:
                    tau[self.arm_v] = self._arm_hold(q, v)
                if self.internal_pair:
                    q, v = self.step(q, v, dt, tau, (P1, cmd.F2 + P2), interface)
                elif self.drives:
                    q, v = self._thrusters_step(q, v, t, dt, tau, (ideal[0] + P1, ideal[1] + P2), interface)
                else:
                    q, v = self.step(q, v, dt, tau, (cmd.F1 + P1, cmd.F2 + P2), interface)
                if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
                    status, divergence = "diverged", "the state is no longer finite"
                    break
                if self.progress and k % 500 == 0:
                    print(f"\r  simulating: t = {t:8.2f} s of {spec.duration:g} s", end="", file=sys.stderr, flush=True)
            self._flush(rows)
        except KeyboardInterrupt:
            status = "interrupted"
        except CaptureMissed as exc:
            status, divergence = "capture_missed", str(exc)
        if status != "completed":
            try:
                self._flush(rows)
            except KeyboardInterrupt:  # a second signal: the blocks already written stay
                pass
        if self.recorder is not None:
            self.recorder.count_steps(k)  # its run.steps (the samples are picked here, not offered step by step)
        if self.progress:
            print(file=sys.stderr, flush=True)
        wall = time.perf_counter() - wall0
        trace = {key: np.asarray(val) for key, val in rows.items() if key != "_tf"}
        t_end = float(trace["t"][-1]) if "t" in trace else 0.0
        result = FormationResult(status, t_end, k, trace, wall, divergence, engine=self.engine)
        self.final_q, self.final_v = q, v
        if self.capture is not None:
            result.capture = self.capture.metrics(q, v, trace["t"], trace["H2_world"])
        return result

    def _sample(self, rows: dict, t: float, q, v, cmd, states) -> None:
        """Append one sample to the trace and, with a recorder, to the MCAP file; ``states``: ``body_states(q, v)``."""
        p = self.plant
        dec, b1, b2, M = states
        delivered = self._delivered(cmd)
        V_L, V_E = dec.locked_shape(b1.xi, b2.xi)
        T_L, T_E = dec.energies(V_L, V_E)
        g1, g2 = b1.pose, b2.pose
        H_world = p.momentum_world(q, v)
        h2 = M[p.bodies[1].base_v] @ v  # body 2's momentum about its base origin, base frame
        sample = {
            "t": t, "p1": g1.translation.copy(), "q1": pin.Quaternion(g1.rotation).coeffs().copy(),
            "p2": g2.translation.copy(), "q2": pin.Quaternion(g2.rotation).coeffs().copy(),
            "V1": p.base_twist(v, 0), "V2": p.base_twist(v, 1), "V_L": V_L, "V_E": V_E,
            "H_world": H_world, "H2_world": g2.dualAction @ h2, "H_locked": dec.M_L @ V_L, "H_shape": dec.M_E @ V_E,
            "T_L": T_L, "T_E": T_E, "T": p.kinetic_energy(q, v), "W": cmd.lyapunov,
            "shape_position": cmd.shape_error.position if cmd.shape_error else np.full(3, np.nan),
            "shape_angle": cmd.shape_error.angle if cmd.shape_error else math.nan,
            "locked_position": cmd.locked_error.position if cmd.locked_error else np.full(3, np.nan),
            "locked_angle": cmd.locked_error.angle if cmd.locked_error else math.nan,
            "F1": cmd.F1, "F2": cmd.F2, "F_L": cmd.F_L, "F_E": cmd.F_E,
            "D1": delivered[0], "D2": delivered[1],
            "propellant1": self._propellant(0), "propellant2": self._propellant(1),
            "wheels1": b1.wheel_rates, "wheels2": b2.wheel_rates, "tau_w1": cmd.tau_w1, "tau_w2": cmd.tau_w2,
            "saturated": cmd.saturated,
        }
        for key, val in sample.items():
            rows.setdefault(key, []).append(val)
        if self.recorder is not None:
            rows.setdefault("_tf", []).append(self.links.world_poses(q))
            if len(rows["t"]) - self._recorded >= RECORD_BLOCK:
                self._flush(rows)

    def _flush(self, rows: dict) -> None:
        """Record the samples not yet recorded, in one block (a killed run keeps every block written)."""
        from sms_cli.formation.recording import formation_topics

        if self.recorder is None or len(rows.get("t", ())) == self._recorded:
            return
        a, b = self._recorded, len(rows["t"])
        block = {key: np.asarray(val[a:b]) for key, val in rows.items()}
        self._recorded = b
        self.recorder.write_block(block["t"], transforms=block["_tf"], scalars=formation_topics(self.names, block))
