"""The compiled kernels a simulation calls, as warm-up calls (``warmup.KernelCall``), built from
the objects that call them: the compiled loop's tree (``SampleKinematics.tree``), the compiled plant
(``CompiledPlant.warm_calls``) and the recording's kinematics and encoding. ``Simulation.warm_up``
passes what it chose, so the engine is decided and the tree flattened once. The calls depend on the
model's array types only, not on gains or on the law's values.
"""

from __future__ import annotations

import numpy as np

from sms_cli.sim.compiled.warmup import KernelCall

# the attitude-law arguments of run_ticks when no law is configured (code, parameters, J, G, Js, body
# code, difference step of J̇); a configured law's have the same types (CompiledSimulation._law_args)
NO_LAW = (0, np.zeros(8), np.eye(3), np.zeros((3, 0)), np.zeros(0), 0, 1e-6)
# run_ticks's momentum-law arguments without one (code 0, the model tuple of momentum_control, gains, state, last W);
# a momentum law's have the same types (CompiledSimulation._momentum_args)
NO_MOMENTUM_MODEL = (np.zeros(0, dtype=np.int64), 0.0, np.zeros(3), np.zeros((3, 0)), np.zeros((3, 3)), np.zeros((3, 0)),
                     np.zeros(0), np.zeros((3, 0)), np.zeros((0, 0)))
NO_MOMENTUM_LAW = (0, None, np.zeros(16), np.zeros(5), np.zeros(1))  # model None: run_ticks compiles without the laws


def kernel_groups(sm, *, loop_tree: tuple | None = None, plant=None, stops: bool = False, recording=None,
                  law=None, arm_law=None, loop=None, rr=None, disturbed=False) -> list[list[KernelCall]]:
    """Groups of kernel calls (``warmup.warm``) of the SystemModel ``sm``'s simulation: the compiled
    loop's on ``loop_tree`` (the 12 arrays of ``SampleKinematics.tree``), else ``plant``'s (a ``CompiledPlant``; ``stops``: with the joint-stop
    kernels) and the Python loop's attitude ``law``'s (its ``warm_calls``, when it has kernels);
    ``recording``: the ``SampleKinematics`` a recording samples with, False for one recorded
    without compiled kinematics, None for no recording; ``rr``: the Python loop's resolved rate; ``disturbed``:
    the Python loop adds disturbance wrenches."""
    from sms_cli.dynamics.locked import shape_invariant
    from sms_cli.recording.encoding import warm_call

    groups: list[list[KernelCall]] = []
    if loop_tree is not None:
        groups += [loop_calls(sm, loop_tree, loop), loop_callee_calls(sm, loop_tree)]
        if hasattr(getattr(loop, "law", None), "actuate"):  # a momentum law (momentum_control)
            groups.append(momentum_calls())
        if getattr(loop, "thr", None) is not None:  # real thrusters: their step and the runner's own kernel calls
            groups.append(loop.thr.warm_calls())
        if loop is not None and sm.n_modes:  # the final state's momenta, modes included (every run)
            groups.append([modal_momenta_call(sm, loop_tree, loop.modal)])
    else:
        if plant is not None:
            groups += plant.warm_calls(stops=stops)
        if hasattr(law, "warm_calls"):
            groups.append(law.warm_calls())
        groups.append(python_arm_calls(sm, arm_law) + python_reference_calls(sm, rr, disturbed))
    if recording is not None:
        groups.append(([recording.warm_call()] if recording else []) + [warm_call()])
        if loop_tree is not None and recording and sm.wheels and not shape_invariant(sm):
            groups[-1].append(recording.locked_warm_call())  # μ of the compiled loop's samples (RecordBuffer.write)
        if loop_tree is not None and recording and sm.wheels and sm.n_modes:  # μ with modes (runner._modal_record_momenta)
            groups[-1].append(KernelCall("sms_cli.sim.compiled.momentum_control:locked_velocities_of", (
                np.eye(sm.nx)[None].copy(), np.zeros((1, sm.nx)), np.empty((1, 3))), cost=1.0))
        if loop is not None and recording and any(p.base_mode == "fixed" for p in loop.spec.phases):
            groups[-1].append(held_reactions_call(sm, loop_tree))  # /base/reaction of the compiled loop's samples
        if loop is not None and recording and loop.spec.disturbances:  # their /base/wrench
            groups[-1].append(KernelCall("sms_cli.sim.compiled.disturbances:disturbance_wrenches", (
                np.zeros((1, 10)), np.zeros(1), sm.q0.astype(float)[None].copy(), np.empty((1, 6))), cost=0.3))
    return groups


def modal_momenta_call(sm, tree: tuple, modal: tuple) -> KernelCall:
    """``modal.modal_sample_momenta`` on one throw-away sample, as ``CompiledSimulation._modal_momenta`` calls it
    (the final state's momenta of a run with modes, and its recorded samples'); ``modal``: the loop's
    (B, Bᵀ, BᵀB, −ω², −2ζω)."""
    q, ne = sm.q0.astype(float)[None].copy(), sm.n_modes
    return KernelCall("sms_cli.sim.compiled.modal:modal_sample_momenta", (
        tree[0], tree[1], tree[2], tree[5], tree[7], tree[8], tree[9], tree[3], tree[4], tree[10], tree[11], modal[0],
        modal[3], q, np.zeros((1, sm.nv)), np.zeros((1, ne)), np.zeros((1, ne)), np.empty((1, 10)),
        np.empty((0, sm.nx, sm.nx))), cost=3.0)


def held_reactions_call(sm, tree: tuple) -> KernelCall:
    """``held_base.held_base_reactions`` on one throw-away sample, as ``CompiledSimulation._held_reactions`` calls it."""
    i64 = lambda x: np.asarray(x, dtype=np.int64)  # noqa: E731
    nw, na = len(sm.idx.wheels), len(sm.arm)
    return KernelCall("sms_cli.sim.compiled.held_base:held_base_reactions", (
        *tree[:6], tree[9], tree[10], tree[11], i64(sm.idx.wheels), i64([a.v_index for a in sm.arm]),
        sm.q0.astype(float)[None].copy(), np.zeros((1, sm.nv)), np.zeros((1, nw)), np.zeros((1, na)), np.empty((1, 6))), cost=2.0)


def python_arm_calls(sm, arm_law) -> list[KernelCall]:
    """The Python loop's arm kernels: the joint reference (``references.JointProfile.at``, every tick, also
    without an arm) and the arm law's (``sms_cli.sim.laws.arm``: its torque and its model's reduction)."""
    n = len(sm.arm)
    z = np.zeros(n)
    calls = [KernelCall("sms_cli.sim.compiled.arm_laws:joint_reference",
                        (np.zeros(2), np.zeros((2, n)), False, 0.0, z, z.copy(), z.copy()), cost=0.3)]
    if hasattr(arm_law, "warm_calls"):
        calls += arm_law.warm_calls(n)
    return calls


def python_reference_calls(sm, rr=None, disturbed=False) -> list[KernelCall]:
    """The Python loop's reference kernels: the attitude profile (``references.AttitudeProfile.at``), the
    reference rates (``laws.attitude.TrackingError``), with a resolved rate ``rr`` its joint rates, and when
    ``disturbed`` the disturbance wrench (``Simulation._disturbance``)."""
    from sms_cli.sim.compiled.profiles import PROF_N

    w3, qe = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    mod = "sms_cli.sim.compiled"
    calls = [KernelCall(f"{mod}.profiles:attitude_reference", (np.zeros(PROF_N), 0.0, np.empty(4), np.empty(3), np.empty(3)),
                        cost=0.3),
             KernelCall(f"{mod}.profiles:reference_rates", (qe, w3, w3.copy(), np.empty(3), np.empty(3)), cost=0.2)]
    if rr is not None:
        n, nw = len(sm.arm), len(sm.wheels)
        calls.append(KernelCall(f"{mod}.resolved_rate:joint_rates", (np.zeros((6, n)), np.zeros((6, nw)), np.zeros(6), 3,
                                                                     np.zeros(nw), 0.05, 0.05, np.ones(n), np.empty(n)),
                                cost=1.5))
    if disturbed:
        calls.append(KernelCall(f"{mod}.disturbances:disturbance_wrench", (np.zeros((1, 10)), 0.0, sm.q0.astype(float),
                                                                           np.empty(6)), cost=0.3))
    return calls


def loop_calls(sm, tree: tuple, loop=None) -> list[KernelCall]:
    """The compiled loop's calls on throw-away data, callees first (ABA through the effective wheel
    inertia, the plant step), then ``run_ticks`` itself (the argument types of ``CompiledSimulation.run``;
    its arm and joint-stop arguments from ``loop``, the ``CompiledSimulation``, when given)."""
    from sms_cli.sim.compiled.dynamics import workspace
    from sms_cli.sim.compiled.loop import RR_N, X_N
    from sms_cli.sim.compiled.profiles import PROF_N
    from sms_cli.sim.compiled.thruster_run import NO_THRUSTERS
    from sms_cli.sim.schema import SensorsSpec
    from sms_cli.sim.sensors import Sensors

    plant_tree = tree[:7] + tree[9:]  # without mass and com
    nw = len(sm.idx.wheels)
    q, v = sm.q0.astype(float).copy(), np.zeros(sm.nv)
    wheel_v = np.asarray(sm.idx.wheels, dtype=np.int64)
    ws = workspace(tree[0].shape[0], sm.nq, sm.nv, 0)
    none_f, none_i = np.zeros(0), np.zeros(0, dtype=np.int64)
    rigid = (np.zeros((6, 0)), np.zeros((6, 6)), none_f, none_f, none_i, none_i, none_f, none_f, none_f)  # no modes, springs
    e1, e2 = np.empty(1), np.empty((1, nw))
    mod = "sms_cli.sim.compiled"
    n_arm = len(sm.arm)
    mom_args, thr_args = NO_MOMENTUM_LAW, NO_THRUSTERS  # the run's own types (None: those blocks pruned)
    sensors = loop.sensors if loop is not None else Sensors(sm, SensorsSpec())  # noiseless without a loop
    sens_args = (sensors.noisy, sensors.par.copy(), np.zeros((0, sensors.width)))
    ne = sm.n_modes
    modal = loop.modal if loop is not None else (np.zeros((0, 6)), np.zeros((6, 0)), np.zeros((6, 6)), none_f, none_f)
    if loop is not None:
        arm_args, stop_args = loop._arm_args(), loop._stop_args()
        mom_args = loop._momentum_args()
        mom_args = (mom_args[0], mom_args[1], mom_args[2].copy(), mom_args[3].copy(), mom_args[4].copy())
        if loop.thr is not None:
            thr_args = loop.thr.args(False)
            thr_args = thr_args[:5] + (thr_args[5].copy(), thr_args[6].copy())
    else:
        i0 = np.zeros(0, dtype=np.int64)
        arm_args = (i0, i0, -1, np.zeros((6, 0)), np.zeros(0, dtype=np.bool_), i0, i0, none_f)
        stop_args = (False, i0, i0, i0, none_f, none_f, 0.0, i0, np.zeros(0, dtype=np.bool_), none_f)
    ns = stop_args[1].shape[0]
    ref = (np.zeros(2), np.zeros((2, n_arm)), False, 0.0)
    stops = []
    if stop_args[0]:  # the stop law's plant step (the loop calls it instead of rkmk4_step)
        ev = np.empty((2 * ns, 10))
        stops = [KernelCall(f"{mod}.stops:stop_step", (plant_tree, *stop_args[2:], q, v, np.zeros(sm.nv), 0.01, 0.0, q.copy(),
                                                       v.copy(), np.zeros(ns), np.zeros(ns), ev, np.zeros(1, dtype=np.int64),
                                                       ws, rigid[:4], none_f, none_f, none_f, none_f, False), cost=6.0)]
    return stops + [
        sensors.warm_call(),
        KernelCall(f"{mod}.loop:effective_wheel_inertia", (*plant_tree, q, wheel_v, np.ones(nw), ws), cost=5.5),
        KernelCall(f"{mod}.dynamics:rkmk4_step", (*plant_tree, *rigid, q, v, none_f, none_f, np.zeros(sm.nv), 0.01, q.copy(),
                                                  v.copy(), none_f.copy(), none_f.copy(), ws, none_i), cost=4.5),
        KernelCall(f"{mod}.loop:run_ticks", (
            *tree, *modal, wheel_v, np.zeros((nw, 3)), np.zeros((nw, nw)), np.zeros(nw), 0.0, 0.0, np.ones(nw), np.ones(nw), 0.0, 0.0,
            False, False, np.inf, *NO_LAW, np.zeros(PROF_N), -1.0, 0.0, *mom_args, *arm_args, *ref, *stop_args,
            False, False, np.zeros(RR_N), np.ones(n_arm), 0, np.eye(3), np.zeros(3), np.zeros(n_arm), np.zeros((0, 10)),
            *thr_args, *sens_args, 0.0, 1.0, 1, 0, 0, 1e9, 1e9,
            q.copy(), v.copy(), np.zeros(ne), np.zeros(ne), np.zeros(4), np.ones(nw), np.array([np.nan]), e1, e1, e2, e2,
            np.empty(1, dtype=np.bool_), np.empty((1, 3)), np.empty((1, 6)), e1, np.empty((1, 7 * n_arm + 6)), np.empty((1, X_N)),
            np.empty((0, 3)), np.empty(0), np.zeros((0, 6)), e1.copy(), e1, np.empty((1, sm.nq)), np.empty((1, sm.nv)),
            np.empty((1, ne)), np.empty((1, ne)), e2, np.empty((0, 0)),
            np.empty((0, 1)), np.empty((0, 9)), np.empty((2 * ns, 10)), np.zeros(1, dtype=np.int64)), cost=6.0),
    ]


def loop_callee_calls(sm, tree: tuple) -> list[KernelCall]:
    """The loop's callees that do not need ABA (law, wheel model, scratch arrays), with the
    argument types of their calls in ``run_ticks``: a group of their own, so that another lane compiles
    them while this one compiles ABA and the plant step, and ``run_ticks`` finds them cached."""
    n, nw = tree[0].shape[0], len(sm.idx.wheels)
    q = sm.q0.astype(float).copy()
    w3, w = np.zeros(3), np.zeros(nw)
    ones = np.ones(nw)
    code, par, I, G, Js, _, _ = NO_LAW
    qe = np.array([0.0, 0.0, 0.0, 1.0])
    ctl, dyn, att = "sms_cli.sim.compiled.control", "sms_cli.sim.compiled.dynamics", "sms_cli.sim.compiled.attitude_laws"
    # the laws as attitude_law calls them (its callees first), each with the same arguments
    law_args = (qe, w3, w3, w3.copy(), I, np.zeros((3, 3)), w3.copy(), par, np.zeros(8), 0.0, np.empty(3))
    return tracking_calls(sm, tree) + [
        KernelCall(f"{dyn}:workspace", (n, sm.nq, sm.nv, 0), cost=1.3),
        KernelCall(f"{ctl}:error_quaternion", (q[3:7], q[3:7].copy(), np.empty(4)), cost=0.2),
        KernelCall(f"{ctl}:error_angle", (q[3:7], q[3:7].copy()), cost=0.2),
        KernelCall(f"{ctl}:mrp_feedback", (qe, w3, w3, w3.copy(), w, I, G, Js, 0.0, 0.0, -1.0, np.inf, 0, np.zeros(3),
                                           np.zeros(4), 0.0, np.empty(3)), cost=0.9),
        *(KernelCall(f"{att}:{name}", law_args, cost=0.6) for name in ("quaternion_pd", "smc", "twisting_smc", "backstepping")),
        KernelCall(f"{att}:attitude_law", (code, qe, w3, w3, w3.copy(), w, I, np.zeros((3, 3)), w3.copy(), G, Js, par,
                                           np.zeros(8), 0.0, np.empty(3)), cost=0.6),
        KernelCall(f"{att}:wheel_momentum", (G, Js, w3, w, np.empty(3)), cost=0.2),
        KernelCall(f"{att}:system_momentum", (q[3:7], np.zeros(10)[3:6], I, w3, np.empty(3)), cost=0.2),
        KernelCall(f"{ctl}:clip_attitude_torque", (np.zeros(3), np.inf), cost=0.1),
        KernelCall(f"{ctl}:allocate_and_clip", (np.zeros(3), w, np.zeros((nw, 3)), np.zeros((nw, nw)), w, 0.0, 0.0, ones,
                                                np.empty(nw)), cost=0.3),
        KernelCall(f"{ctl}:may_reach_limit", (w, w, ones, ones, 0.1), cost=0.1),
        KernelCall(f"{ctl}:limited_torque", (w, w, ones, ones, 0.1, 0.0, 0.0, np.empty(nw)), cost=0.2),
    ]


def tracking_calls(sm, tree: tuple) -> list[KernelCall]:
    """The loop's reference, held-base and end-effector tracking kernels (``profiles``, ``held_base``,
    ``resolved_rate``) with the argument types of their calls in ``run_ticks``, callees first."""
    from sms_cli.sim.compiled.loop import RR_N
    from sms_cli.sim.compiled.profiles import PROF_N

    parent, kind, axis, idx_v = tree[0], tree[1], tree[2], tree[11]
    n, nv, nw, na = parent.shape[0], sm.nv, len(sm.idx.wheels), max(len(sm.arm), 1)  # one joint: a valid SVD without an arm
    mod = "sms_cli.sim.compiled"
    w3, qe = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    i64 = lambda x: np.asarray(x, dtype=np.int64)  # noqa: E731
    arm_v, wheel_v = i64([a.v_index for a in sm.arm] or [0]), i64(sm.idx.wheels)
    oR, op = np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3))
    par = np.zeros(RR_N)
    jac = (np.empty((6, nv)), np.empty((6, na)), np.empty((6, nw)))
    return [
        KernelCall(f"{mod}.profiles:attitude_reference", (np.zeros(PROF_N), 0.0, np.empty(4), np.empty(3), np.empty(3)), cost=0.3),
        KernelCall(f"{mod}.profiles:reference_rates", (qe, w3, w3.copy(), np.empty(3), np.empty(3)), cost=0.2),
        KernelCall(f"{mod}.disturbances:disturbance_wrench", (np.zeros((1, 10)), 0.0, sm.q0.astype(float), np.empty(6)),
                   cost=0.3),
        KernelCall(f"{mod}.held_base:held_base_reaction", (np.eye(nv), np.zeros(nv), np.zeros(nv), np.empty(6)), cost=0.4),
        KernelCall(f"{mod}.resolved_rate:frame_jacobian", (parent, kind, axis, idx_v, oR, op, 0, np.eye(3), w3, np.empty(3),
                                                           jac[0]), cost=0.5),
        KernelCall(f"{mod}.resolved_rate:generalized_jacobians", (np.eye(nv), jac[0], arm_v, wheel_v, jac[1], jac[2]), cost=0.5),
        KernelCall(f"{mod}.resolved_rate:joint_rates", (jac[1], jac[2], np.zeros(6), 3, np.zeros(nw), 0.05, 0.05, np.ones(na),
                                                        np.empty(na)), cost=1.5),
        KernelCall(f"{mod}.resolved_rate:track_end_effector", (
            parent, kind, axis, idx_v, oR, op, 0, np.eye(3), w3, np.eye(nv), arm_v, wheel_v, np.zeros(nv), np.zeros(3),
            par[10:13], par[0:3], 0.05, 0.05, np.ones(na), True, *jac, np.empty(na), np.empty(3)), cost=0.6),
    ]


def momentum_calls() -> list[KernelCall]:
    """The momentum laws' kernels as run_ticks calls them (``momentum_control``; the law dispatch and the W
    dispatch compile with them), on the types of ``NO_MOMENTUM_LAW``; also the W dispatch the runner calls at
    each phase start (``runner.LyapunovSeries``)."""
    from sms_cli.sim.compiled.momentum_laws import T_N

    _, _, par, mem, _ = NO_MOMENTUM_LAW
    model = NO_MOMENTUM_MODEL
    q, v, ref = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]), np.zeros(6), np.array([0.0, 0.0, 0.0, 1.0])
    mc, ml = "sms_cli.sim.compiled.momentum_control", "sms_cli.sim.compiled.momentum_laws"
    return [
        KernelCall(f"{ml}:momentum_lyapunov", (0, q, v, ref, *model, par, mem, np.empty(T_N)), cost=3.0),
        KernelCall(f"{mc}:lyapunov_terms", (0, q, v, ref, model, par, mem, np.empty(T_N)), cost=0.5),
        KernelCall(f"{mc}:locked_velocity", (v, model, np.empty(3)), cost=0.2),
        KernelCall(f"{mc}:momentum_control", (0, q, v, ref, model, par, mem, np.zeros(0), np.empty(0), np.empty(6)),
                   cost=10.0),
        KernelCall(f"{mc}:locked_model", (np.eye(7), np.array([6], dtype=np.int64)), cost=2.0),
    ]
