"""Real thrusters in the compiled engine (``runner.CompiledSimulation``): the compiled loop runs one control tick
per call; at each tick a probe call (``loop.run_ticks`` with thr_probe) gives the wrench the law asks for, the
ONE allocation of the Python loop turns it into a firing pattern (``ThrusterDrive.command``: the minimum-thrust
LP by HiGHS, then the on/off modulation), and the tick's call steps the plant through the firings
(``thrusters.thruster_step``). The LP runs once per firing cycle (the control period is a whole number of them,
here one), so it stays in Python: a numba solver would have to reproduce HiGHS's choice among the LP's many
equal-cost optima (the cube's opposed pairs) to give the same firings.

This object holds the drive, the loop's copies of the tree's inertia arrays (the base body loses the propellant
spent; the recording's kinematics keep the loaded ones, they only need poses), the thrusters' tuple for the loop,
and what the trace, the recording and the metrics need per tick and per step.
"""

from __future__ import annotations

import numpy as np

from sms_cli.thrusters.topics import _W


class ThrusterRun:
    """The thrusters of one compiled run (see the module docstring)."""

    def __init__(self, sm, tree: tuple):
        from sms_cli.sim.compiled.tree import spatial_inertia
        from sms_cli.thrusters.drive import ThrusterDrive

        self.sm = sm
        self.drive = d = ThrusterDrive(sm, sm.thrusters)  # command only: its step (which edits the model) is not used
        ts = d.ts
        tree = list(tree)
        for i in (5, 7, 8):  # inertia, mass, com: the loop's own, changed in place as propellant is spent
            tree[i] = tree[i].copy()
        self.tree = tuple(tree)
        inertia, mass, com = tree[5], tree[7], tree[8]
        p = np.asarray(ts.tank_position, float)
        self.B = np.ascontiguousarray(d.B)
        self.thr = (self.B, ts.max_force.astype(float), np.ascontiguousarray(d.mdot, dtype=float), float(ts.firing_cycle),
                    float(ts.propellant), inertia[0].copy(), float(mass[0]), com[0].copy(),
                    spatial_inertia(1.0, p, np.zeros((3, 3))), p.copy())
        self.state = np.zeros(2)  # thrusters.USED, REMOVED
        self.cmd = np.zeros(6)
        self.n = ts.n
        self.sat = False
        self.ticks: list[tuple] = []  # per tick: (commanded, pattern wrench, total thrust, propellant used)

    @property
    def used(self) -> float:
        return float(self.state[0])

    def args(self, probe: bool) -> tuple:
        """run_ticks's thruster arguments for a probe or a stepping call (the current pattern)."""
        return True, probe, self.thr, float(self.drive.t0), np.ascontiguousarray(self.drive.on, dtype=float), self.state, self.cmd

    def command(self, t: float) -> None:
        """Allocate and modulate the probed wrench for the tick at t (``ThrusterDrive.command``)."""
        d = self.drive
        self.sat = bool(d.command(t, self.cmd.copy()))
        self.ticks.append((d.commanded.copy(), d.pattern_wrench, float(d.pattern_thrust.sum()), self.used))

    def trace(self, final: bool = False) -> dict:
        """The trace's thruster arrays (``Trace.thruster_*``): per tick, and the final row (the last pattern)."""
        rows = self.ticks + ([self.ticks[-1][:3] + (self.used,)] if final and self.ticks else [])
        c, w, f, u = zip(*rows) if rows else ((), (), (), ())
        return {"thruster_commanded": np.array(c).reshape(-1, 6), "thruster_delivered": np.array(w).reshape(-1, 6),
                "thrust_total": np.array(f, float), "propellant_used": np.array(u, float)}

    def step_arrays(self, ms: int) -> tuple[np.ndarray, np.ndarray]:
        """(st_thr, st_mom) of a slice of ms plant steps."""
        return np.empty((ms, self.n + 1)), np.empty((ms, 9))

    def topics(self, st_thr: np.ndarray, commanded: np.ndarray) -> tuple[np.ndarray, dict]:
        """(the delivered wrench per step, for /base/wrench; the thrusters' topics per step: ``thruster_topics``)."""
        thrust, used = st_thr[:, :self.n], st_thr[:, self.n]
        delivered = thrust @ self.B.T
        names = self.drive.ts.names
        return delivered, {"/thrusters/commanded": {k: commanded[:, i] for i, k in enumerate(_W)},
                           "/thrusters/delivered": {k: delivered[:, i] for i, k in enumerate(_W)},
                           "/thrusters/thrust": {n: thrust[:, i] for i, n in enumerate(names)},
                           "/thrusters/propellant": {"used_kg": used, "left_kg": self.drive.ts.propellant - used}}

    def initial_topics(self) -> dict:
        z = np.zeros((1, 6))
        return self.topics(np.concatenate([np.zeros((1, self.n)), [[0.0]]], axis=1), z)[1]

    def warm_calls(self) -> list:
        """The kernels this object calls from Python (``law_model``, ``momenta``), with their argument types; the loop
        links them into run_ticks, which does not make them callable from Python (``warmup.warm``)."""
        from sms_cli.sim.compiled.dynamics import workspace
        from sms_cli.sim.compiled.warmup import KernelCall

        parent, kind, axis, place_R, place_p, inertia, _, mass, com, armature, idx_q, idx_v = self.tree
        n, nv = parent.shape[0], self.sm.nv
        q, v = self.sm.q0.astype(float).copy(), np.zeros(nv)
        R, p = np.empty((n, 3, 3)), np.empty((n, 3))
        d = "sms_cli.sim.compiled.dynamics"
        tr = "sms_cli.sim.compiled.thrusters"
        return [KernelCall(f"{tr}:thruster_step", (self.tree, self.thr, 0.0, np.zeros(self.n), q, v, np.zeros(nv), 0.0, 0.01,
                                                   q.copy(), v.copy(), np.zeros(self.n), np.zeros(2),
                                                   workspace(n, self.sm.nq, nv, 0)), cost=6.0),
                KernelCall(f"{d}:joint_transforms", (kind, axis, place_R, place_p, idx_q, q, R, p), cost=0.5),
                KernelCall(f"{d}:mass_matrix", (parent, kind, axis, inertia, armature, idx_v, R, p, np.empty((nv, nv))),
                           cost=1.5),
                KernelCall(f"{d}:momenta_energy", (parent, kind, axis, inertia, mass, com, armature, idx_v, R, p, v,
                                                   np.empty(10), workspace(n, self.sm.nq, nv, 0)), cost=1.5)]

    def law_model(self, q: np.ndarray) -> tuple:
        """The momentum law's model tuple at q and the current mass (``momentum_control.locked_model``)."""
        from sms_cli.sim.compiled.dynamics import joint_transforms, mass_matrix
        from sms_cli.sim.compiled.momentum_control import locked_model

        parent, kind, axis, place_R, place_p, inertia, _, _, _, armature, idx_q, idx_v = self.tree
        n = parent.shape[0]
        R, p = np.empty((n, 3, 3)), np.empty((n, 3))
        joint_transforms(kind, axis, place_R, place_p, idx_q, q, R, p)
        M = np.empty((self.sm.nv, self.sm.nv))
        mass_matrix(parent, kind, axis, inertia, armature, idx_v, R, p, M)
        return locked_model(M, np.asarray(self.sm.idx.wheels, dtype=np.int64))

    def momenta(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """[p, k about the CoM, k about the origin, energy] (10,) at the current mass (``dynamics.momenta_energy``)."""
        from sms_cli.sim.compiled.dynamics import joint_transforms, momenta_energy, workspace

        parent, kind, axis, place_R, place_p, inertia, _, mass, com, armature, idx_q, idx_v = self.tree
        n = parent.shape[0]
        R, p = np.empty((n, 3, 3)), np.empty((n, 3))
        joint_transforms(kind, axis, place_R, place_p, idx_q, q, R, p)
        out = np.empty(10)
        momenta_energy(parent, kind, axis, inertia, mass, com, armature, idx_v, R, p, v, out,
                       workspace(n, self.sm.nq, self.sm.nv, 0))
        return out


# run_ticks's thruster arguments without real thrusters (types of ThrusterRun.args)
# (the set's tuple None: run_ticks compiles without the thrusters' step)
NO_THRUSTERS = (False, False, None, 0.0, np.zeros(0), np.zeros(2), np.zeros(6))
