"""The compiled kernels a mission's simulation calls, as warm-up calls (``warmup.KernelCall``).

One list for both loops, decided as ``Simulation`` decides its engine: the compiled loop
(``runner.unsupported_reason`` is None) calls its loop kernel and the loop's callees; the Python
loop calls the compiled plant step (when ``plant.unsupported_reason`` allows it) and, with joint
stops, their kernels; a recording adds the block kinematics and the message encoding. The calls
depend on the model's array types only, not on gains or on the law's values.
"""

from __future__ import annotations

import numpy as np

from sms_cli.model.system import SystemModel
from sms_cli.sim.compiled.warmup import KernelCall
from sms_cli.sim.schema import SimulationSpec

# the attitude-law arguments of run_ticks when no law is configured; a configured law's have the same
# types (CompiledSimulation._law_args)
NO_LAW = (np.eye(3), np.zeros((3, 0)), np.zeros(0), 0.0, 0.0, -1.0, np.inf, 0, np.zeros(3))


def kernel_groups(sm: SystemModel, spec: SimulationSpec, att_spec, record: bool) -> list[list[KernelCall]]:
    """Groups of kernel calls (``warmup.warm``) of this mission's simulation: compiled loop or
    Python loop with the compiled plant, plus the recording's when ``record``."""
    from sms_cli.sim.compiled.plant import CompiledPlant
    from sms_cli.sim.compiled.plant import unsupported_reason as plant_reason
    from sms_cli.sim.compiled.runner import unsupported_reason as loop_reason
    from sms_cli.sim.compiled.tree import unsupported_reason as tree_reason

    groups: list[list[KernelCall]] = []
    compiled_loop = spec.engine != "python" and loop_reason(sm, spec, att_spec) is None
    if compiled_loop:
        groups += [loop_calls(sm), loop_callee_calls(sm)]
    elif spec.engine != "python" and plant_reason(sm) is None:
        from sms_cli.dynamics.joint_stops import stop_table

        stops = spec.joint_stops.enabled and stop_table(sm).n > 0
        groups += CompiledPlant(sm).warm_calls(stops=stops)
    if record and tree_reason(sm.model) is None:
        from sms_cli.sim.compiled.kinematics import SampleKinematics
        from sms_cli.sim.mcap_block import warm_call

        groups.append([SampleKinematics(sm).warm_call(), warm_call()])
    elif record:
        from sms_cli.sim.mcap_block import warm_call

        groups.append([warm_call()])
    return groups


def loop_calls(sm: SystemModel) -> list[KernelCall]:
    """The compiled loop's calls on throw-away data, callees first (ABA through the effective wheel
    inertia, the plant step), then ``run_ticks`` itself (the argument types of ``CompiledSimulation.run``)."""
    from sms_cli.sim.compiled.dynamics import workspace
    from sms_cli.sim.compiled.tree import flatten

    T = flatten(sm.model)
    tree = (T.parent, T.kind, T.axis, T.place_R, T.place_p, T.inertia, T.leaf_IA, T.mass, T.com, T.armature, T.idx_q,
            T.idx_v)
    plant_tree = tree[:7] + tree[9:]  # without mass and com
    nw = len(sm.idx.wheels)
    q, v = sm.q0.astype(float).copy(), np.zeros(sm.nv)
    wheel_v = np.asarray(sm.idx.wheels, dtype=np.int64)
    ws = workspace(T.parent.shape[0], sm.nq, sm.nv, 0)
    none_f, none_i = np.zeros(0), np.zeros(0, dtype=np.int64)
    rigid = (np.zeros((6, 0)), np.zeros((6, 6)), none_f, none_f, none_i, none_i, none_f, none_f, none_f)  # no modes, springs
    e1, e2 = np.empty(1), np.empty((1, nw))
    mod = "sms_cli.sim.compiled"
    return [
        KernelCall(f"{mod}.loop:effective_wheel_inertia", (*plant_tree, q, wheel_v, np.ones(nw), ws), cost=5.5),
        KernelCall(f"{mod}.dynamics:rkmk4_step", (*plant_tree, *rigid, q, v, none_f, none_f, np.zeros(sm.nv), 0.01, q.copy(),
                                                  v.copy(), none_f.copy(), none_f.copy(), ws), cost=4.5),
        KernelCall(f"{mod}.loop:run_ticks", (
            *tree, wheel_v, np.zeros((nw, 3)), np.zeros((nw, nw)), np.zeros(nw), 0.0, 0.0, np.ones(nw), np.ones(nw), 0.0, 0.0,
            False, False, np.inf, *NO_LAW, q[3:7].copy(), -1.0, 0.0, 0.0, 1.0, 1, 0, 0, 1e9, q.copy(), v.copy(), np.zeros(4),
            np.ones(nw), np.array([np.nan]), e1, e1, e2, e2, np.empty(1, dtype=np.bool_), np.empty((1, 3)), np.empty((1, 6)),
            e1, e1, np.empty((1, sm.nq)), np.empty((1, sm.nv)), e2), cost=6.0),
    ]


def loop_callee_calls(sm: SystemModel) -> list[KernelCall]:
    """The loop's callees that do not need ABA (law, wheel model, scratch arrays), with the
    argument types of their calls in ``run_ticks``: a group of their own, so that another lane compiles
    them while this one compiles ABA and the plant step, and ``run_ticks`` finds them cached."""
    from sms_cli.sim.compiled.dynamics import workspace
    from sms_cli.sim.compiled.tree import flatten

    T = flatten(sm.model)
    n, nw = T.parent.shape[0], len(sm.idx.wheels)
    q, v = sm.q0.astype(float).copy(), np.zeros(sm.nv)
    w3, w = np.zeros(3), np.zeros(nw)
    ones = np.ones(nw)
    I, G, Js, K, P, Ki, lim, law_type, L = NO_LAW
    ctl, dyn = "sms_cli.sim.compiled.control", "sms_cli.sim.compiled.dynamics"
    return [
        KernelCall(f"{dyn}:workspace", (n, sm.nq, sm.nv, 0), cost=1.3),
        KernelCall(f"{ctl}:error_quaternion", (q[3:7], q[3:7].copy(), np.empty(4)), cost=0.2),
        KernelCall(f"{ctl}:error_angle", (q[3:7], q[3:7].copy()), cost=0.2),
        KernelCall(f"{ctl}:mrp_feedback", (np.array([0.0, 0.0, 0.0, 1.0]), w3, w3, w3.copy(), w, I, G, Js, K, P, Ki, lim,
                                           law_type, L, np.zeros(4), 0.0, np.empty(3)), cost=0.9),
        KernelCall(f"{ctl}:clip_attitude_torque", (np.zeros(3), np.inf), cost=0.1),
        KernelCall(f"{ctl}:allocate_and_clip", (np.zeros(3), w, np.zeros((nw, 3)), np.zeros((nw, nw)), w, 0.0, 0.0, ones,
                                                np.empty(nw)), cost=0.3),
        KernelCall(f"{ctl}:may_reach_limit", (w, w, ones, ones, 0.1), cost=0.1),
        KernelCall(f"{ctl}:limited_torque", (w, w, ones, ones, 0.1, 0.0, 0.0, np.empty(nw)), cost=0.2),
    ]
