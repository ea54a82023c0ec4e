"""One RKMK4 plant step of a SystemModel in a single compiled call, for the Python loop.

The Python loop keeps its controllers, sensors and recording, and hands the plant step to
``dynamics.rkmk4_step`` (ABA with the base-mounted modal appendages as a constant root-inertia
term and a root bias force, joint springs as generalized forces): one call instead of four
forward dynamics and the stage arithmetic in Python. Supported: what ``tree.flatten`` accepts,
with appendages (if any) all on the base; a held base (phase mode ``fixed``) stays in Python.
Same results as ``sms_cli.dynamics.integrator.rkmk4_step`` with ``SystemModel.forward_dynamics``
(tests/test_compiled_engine.py). It is also the compiled counterpart of
``sms_cli.dynamics.joint_stops.PinocchioPlant`` for the joint stops (``accel``,
``inverse_mass_columns``, ``step`` with locked joints; tests/test_joint_stops.py).
"""

from __future__ import annotations

import numpy as np

from sms_cli.dynamics.integrator import State
from sms_cli.model.system import SystemModel


def unsupported_reason(sm: SystemModel) -> str | None:
    """Why the compiled plant cannot step this model (None when it can)."""
    from sms_cli.sim.compiled.tree import unsupported_reason as tree_reason

    why = tree_reason(sm.model)
    if why:
        return why
    if sm.n_modes and sm.base_modal_coupling is None:
        return "an appendage is not mounted on the base"
    return None


def modal_arrays(sm: SystemModel) -> tuple:
    """The base-mounted modes as the compiled steps take them: B (n_η×6, ``SystemModel.base_modal_coupling``),
    Bᵀ, BᵀB, −Ω² and −2ζΩ (rad/s); empty arrays (n_η = 0) for a rigid model."""
    ne = sm.n_modes
    B = sm.base_modal_coupling if ne else np.zeros((0, 6))
    omega = np.concatenate([a.omega for a in sm.appendages]) if ne else np.zeros(0)
    zeta = np.concatenate([a.zeta for a in sm.appendages]) if ne else np.zeros(0)
    return (np.ascontiguousarray(B, dtype=float), np.ascontiguousarray(B.T, dtype=float),
            np.ascontiguousarray(B.T @ B, dtype=float), -(omega**2), -2.0 * zeta * omega)


class CompiledPlant:
    """RKMK4 steps of ``sm`` (see the module docstring). Call ``refresh()`` after a payload is
    attached or released (the body inertias change)."""

    def __init__(self, sm: SystemModel):
        from sms_cli.sim.compiled.dynamics import workspace

        self.sm = sm
        self._modal = modal_arrays(sm)[1:]
        sp = sm.springs
        self._springs = (np.array([x.v_index for x in sp], dtype=np.int64), np.array([x.q_index for x in sp], dtype=np.int64),
                         np.array([x.stiffness for x in sp], float), np.array([x.damping for x in sp], float),
                         np.array([x.rest for x in sp], float))
        self.refresh()
        self._ws = workspace(self._tree[0].size, sm.nq, sm.nv, sm.n_modes)

    def refresh(self) -> None:
        """Re-read the model (body inertias change when payloads are attached or released)."""
        from sms_cli.sim.compiled.tree import flatten

        T = flatten(self.sm.model)
        self._tree = (T.parent, T.kind, T.axis, T.place_R, T.place_p, T.inertia, T.leaf_IA, T.armature, T.idx_q, T.idx_v)

    def refresh_body(self, joint_id: int) -> None:
        """Re-read the inertia of one body (Pinocchio joint ``joint_id``; the base losing propellant) in
        place: what ``refresh`` does for that body, without re-flattening the tree (a body whose inertia
        ABA precomputes, a constant leaf, gets the full ``refresh``)."""
        from sms_cli.sim.compiled.tree import spatial_inertia

        i = joint_id - 1
        if not np.isnan(self._tree[6][i, 0, 0]):
            self.refresh()
            return
        Y = self.sm.model.inertias[joint_id]
        self._tree[5][i] = spatial_inertia(Y.mass, Y.lever, Y.inertia)

    def step(self, s: State, tau: np.ndarray, dt: float, locked: np.ndarray | None = None) -> State:
        """The state after one RKMK4 step of dt (s) under the held generalized forces tau (nv), the
        joints ``locked`` (velocity indices; joint stops) held at zero acceleration."""
        from sms_cli.sim.compiled.dynamics import rkmk4_step

        out = State(np.empty_like(s.q), np.empty_like(s.v), np.empty_like(s.eta), np.empty_like(s.etadot))
        rkmk4_step(*self._tree, *self._modal, *self._springs, s.q, s.v, s.eta, s.etadot,
                   np.ascontiguousarray(tau, dtype=float), float(dt), out.q, out.v, out.eta, out.etadot, self._ws,
                   _indices(locked))
        return out

    def accel(self, s: State, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Free accelerations (v̇, η̈) at s under tau (nv): ``SystemModel.forward_dynamics``."""
        from sms_cli.sim.compiled.dynamics import accelerations

        vdot, etadd = np.empty(self.sm.nv), np.empty(self.sm.n_modes)
        accelerations(*self._tree, *self._modal, *self._springs, s.q, s.v, s.eta, s.etadot,
                      np.ascontiguousarray(tau, dtype=float), vdot, etadd, self._ws)
        return vdot, etadd

    def inverse_mass_columns(self, q: np.ndarray, v_idx: np.ndarray) -> np.ndarray:
        """Columns v_idx of the inverse augmented mass matrix at q (nx×k; rows nv..: the modes)."""
        from sms_cli.sim.compiled.dynamics import inverse_mass_columns

        cols = _indices(v_idx)
        G = np.empty((self.sm.nx, cols.size))
        inverse_mass_columns(*self._tree, self._modal[0], np.ascontiguousarray(q, dtype=float), cols, G, self._ws)
        return G

    def warm_calls(self, stops: bool = False) -> list:
        """This plant's kernel calls on throw-away states, for ``sms_cli.sim.compiled.warmup.warm``:
        the step (its locked-joint form has the same types) and, with joint stops, the free
        accelerations and the M⁻¹ columns. One group: they share ABA, compiled once."""
        from sms_cli.sim.compiled.warmup import KernelCall

        sm = self.sm
        q, v, eta, ed = sm.q0.astype(float).copy(), np.zeros(sm.nv), np.zeros(sm.n_modes), np.zeros(sm.n_modes)
        tau = np.zeros(sm.nv)
        mod = "sms_cli.sim.compiled.dynamics"
        calls = [KernelCall(f"{mod}:rkmk4_step", (*self._tree, *self._modal, *self._springs, q, v, eta, ed, tau, 0.01,
                                                  q.copy(), v.copy(), eta.copy(), ed.copy(), self._ws, _NONE), cost=9.0)]
        if stops:
            calls += [KernelCall(f"{mod}:accelerations", (*self._tree, *self._modal, *self._springs, q, v, eta, ed, tau,
                                                          np.empty(sm.nv), np.empty(sm.n_modes), self._ws), cost=1.5),
                      KernelCall(f"{mod}:inverse_mass_columns", (*self._tree, self._modal[0], q, _indices([0]),
                                                                 np.empty((sm.nx, 1)), self._ws), cost=2.0)]
        return [calls]


_NONE = np.zeros(0, dtype=np.int64)


def _indices(idx) -> np.ndarray:
    """An int64 index array for the kernels (empty for None)."""
    return _NONE if idx is None else np.ascontiguousarray(idx, dtype=np.int64)
