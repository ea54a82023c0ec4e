"""Joint-limit stops: the URDF limits of the arm joints as unilateral constraints of the plant.

A stop is a rigid, unilateral constraint on one generalized coordinate (not a stiff penalty):

- **Arrival** (impulse). When, after a plant step, joint i is at or beyond a limit and moving outward,
  a generalized impulse λ on coordinate i alone changes the augmented velocity x = [v; η̇] by
  Δx = M⁻¹ e_i λ, with λ such that the joint's rate after the impact is −e × its rate before
  (restitution e, 0 = inelastic). The impulse acts between the joint's two bodies: the base rows of
  M Δx (the system's momentum, base frame) are zero, so the world linear and angular momentum are
  unchanged. An inelastic stop of joint i alone dissipates ½ v_i² / (M⁻¹)_ii.
- **Contact** (constraint force). A joint that arrived inelastically is locked: during each plant step
  the forward dynamics adds a generalized force on it that keeps its acceleration at zero
  (a = a_free + M⁻¹ e_L λ with (M⁻¹)_LL λ = −(a_free)_L), at all four RKMK4 stages. The locked set
  of a step is decided at the step's start state: a locked joint is released when its contact force
  would pull it onto the stop (its free acceleration points away from the stop). The contact force
  is a generalized force, internal like the impulse: momentum is conserved as in a free step.
- Several joints at once (arrivals, or contacts) are solved together as a linear complementarity
  problem over the joints involved (``complementarity``): a joint gets a push only if it needs one,
  and a push never pulls.

The position is never projected back onto the limit (that would change the momentum): a joint
penetrates by at most what it travels in the step it arrives, |v| dt, then stays put while locked.
A joint that arrives again before it has come back inside its range after a bounce arrives
inelastically (a rebound too small to leave the stop within a step is a rest, not a bounce).

This module holds the law once for both plant engines: ``JointStops`` decides arrivals, impulses,
releases and keeps the time on stop; the engine supplies a plant object with ``accel(s, tau)``,
``inverse_mass_columns(q, v_idx)`` and ``step(s, tau, dt, locked)`` — ``PinocchioPlant`` here
(SystemModel dynamics, the reference) or ``sms_cli.sim.compiled.plant.CompiledPlant`` (numba kernels,
the lock in ``sms_cli.sim.compiled.dynamics.lock_joints``).

Units: joint positions rad (revolute) or m (prismatic), rates rad/s or m/s, times s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sms_cli.dynamics.integrator import State, rkmk4_step
from sms_cli.model.system import SystemModel

UPPER, LOWER = 1, -1  # side of a stop = its outward direction (+1: the upper limit, −1: the lower limit)


@dataclass(frozen=True)
class StopTable:
    """The arm joints that have a stop: index ``k`` here is joint ``arm_index[k]`` of ``SystemModel.arm``.
    Limits are −inf / +inf on a side the URDF leaves open."""

    names: list[str]
    arm_index: np.ndarray
    v_index: np.ndarray
    q_index: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @property
    def n(self) -> int:
        return len(self.names)


def stop_table(sm: SystemModel) -> StopTable:
    """Arm joints (revolute or prismatic, one coordinate) with at least one finite URDF limit;
    wheels, passive joints and continuous joints have none."""
    rows = [(k, a) for k, a in enumerate(sm.arm)
            if a.kind in ("revolute", "prismatic") and sm.model.joints[a.joint_id].nq == 1
            and (np.isfinite(a.lower) or np.isfinite(a.upper))]
    return StopTable([a.name for _, a in rows], np.array([k for k, _ in rows], dtype=int),
                     np.array([a.v_index for _, a in rows], dtype=int), np.array([a.q_index for _, a in rows], dtype=int),
                     np.array([a.lower for _, a in rows], float), np.array([a.upper for _, a in rows], float))


def penetration(table: StopTable, q: np.ndarray) -> np.ndarray:
    """How far each stop joint of ``table`` is beyond its range at configuration q (≥ 0; rad or m)."""
    x = q[table.q_index]
    return np.maximum(0.0, np.maximum(x - table.upper, table.lower - x))


def arm_penetration(table: StopTable, n_arm: int, q: np.ndarray) -> np.ndarray:
    """``penetration`` per arm joint (n_arm; 0 for the joints without a stop)."""
    out = np.zeros(n_arm)
    out[table.arm_index] = penetration(table, q)
    return out


def complementarity(W: np.ndarray, b: np.ndarray) -> np.ndarray:
    """μ ≥ 0 with r = W μ − b ≥ 0 and μᵀ r = 0 (W symmetric positive definite, k×k).

    In outward coordinates: b_j is how much joint j's outward rate (or acceleration) must drop to meet
    its target, μ_j ≥ 0 the magnitude of its push, W = diag(o) M⁻¹_SS diag(o). Murty's least-index
    principal pivoting: finite for P-matrices, exact (no iteration tolerance) for the small sets here."""
    k = b.size
    active = b > 0
    scale = max(float(np.max(np.abs(b))) if k else 0.0, 1e-300)
    tol = 1e-13 * scale
    for _ in range(4 * 2**min(k, 10) + 10):
        mu = np.zeros(k)
        if np.any(active):
            mu[active] = np.linalg.solve(W[np.ix_(active, active)], b[active])
        r = W @ mu - b
        bad = np.nonzero((active & (mu < -tol)) | (~active & (r < -tol)))[0]
        if bad.size == 0:
            return np.maximum(mu, 0.0)
        active[bad[0]] = ~active[bad[0]]
    raise RuntimeError("joint stops: the complementarity pivoting did not terminate")


def lock_accelerations(vdot: np.ndarray, etaddot: np.ndarray, G: np.ndarray, locked: np.ndarray):
    """The contact law: accelerations with the joints ``locked`` (velocity indices) held at zero
    acceleration. G = M⁻¹[:, locked] (nx×k, augmented: rows nv.. are the modal part)."""
    nv = vdot.size
    lam = np.linalg.solve(G[locked], -vdot[locked])
    dx = G @ lam
    return vdot + dx[:nv], etaddot + dx[nv:]


class PinocchioPlant:
    """The reference plant for the stops: RKMK4 (``integrator.rkmk4_step``) on
    ``SystemModel.forward_dynamics`` (``fixed``: ``forward_dynamics_fixed_base``, the base held),
    with the contact law on the locked joints at every stage."""

    def __init__(self, sm: SystemModel, fixed: bool = False):
        self.sm, self.fixed = sm, fixed
        self._fd = sm.forward_dynamics_fixed_base if fixed else sm.forward_dynamics

    def accel(self, s: State, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Free accelerations (v̇, η̈) at s under tau (nv)."""
        return self._fd(s.q, s.v, s.eta, s.etadot, tau)

    def inverse_mass_columns(self, q: np.ndarray, v_idx: np.ndarray) -> np.ndarray:
        """Columns v_idx of the inverse augmented mass matrix (nx×k); with the base held, of the
        inverse of its free block (zero base rows)."""
        sm = self.sm
        M = sm.mass_matrix(q)
        E = np.zeros((sm.nx, len(v_idx)))
        E[v_idx, np.arange(len(v_idx))] = 1.0
        if not self.fixed:
            return np.linalg.solve(M, E)
        G = np.zeros_like(E)
        G[6:] = np.linalg.solve(M[6:, 6:], E[6:])
        return G

    def step(self, s: State, tau: np.ndarray, dt: float, locked: np.ndarray | None = None) -> State:
        """One RKMK4 step of dt (s) under the held tau, the joints ``locked`` (velocity indices) held."""
        fd = self._fd
        if locked is None or len(locked) == 0:
            return rkmk4_step(self.sm.model, s, dt, lambda q, v, e, ed: fd(q, v, e, ed, tau))

        def accel(q, v, e, ed):
            vd, edd = fd(q, v, e, ed, tau)
            return lock_accelerations(vd, edd, self.inverse_mass_columns(q, locked), locked)

        return rkmk4_step(self.sm.model, s, dt, accel)


@dataclass
class JointStops:
    """The stop law over a run (see the module docstring). ``step`` replaces the plant step;
    ``events`` collects (t, name, detail) for /events; ``interval()`` gives and resets, per arm joint,
    the time on stop and the largest penetration since the previous call (for the per-tick trace)."""

    sm: SystemModel
    restitution: float = 0.0
    table: StopTable = field(init=False)

    def __post_init__(self) -> None:
        self.table = stop_table(self.sm)
        n = self.table.n
        self.side = np.zeros(n, dtype=int)  # 0: free; UPPER / LOWER: locked on that stop
        self.rebound = np.zeros(n, dtype=bool)  # bounced and not back inside the range yet
        self.since = np.zeros(n)  # time the current contact began
        self.total_time = np.zeros(n)  # s on stop over the run
        self.max_penetration = np.zeros(n)
        self._time = np.zeros(n)
        self._pen = np.zeros(n)
        self.events: list[tuple[float, str, dict]] = []

    def interval(self, s: State) -> tuple[np.ndarray, np.ndarray]:
        """(time on stop, largest penetration) per arm joint since the previous call (the penetration
        includes the state s), then reset."""
        n_arm = len(self.sm.arm)
        time, pen = np.zeros(n_arm), np.zeros(n_arm)
        idx = self.table.arm_index
        time[idx] = self._time
        pen[idx] = np.maximum(self._pen, penetration(self.table, s.q))
        self._time[:] = 0.0
        self._pen[:] = 0.0
        return time, pen

    # ------------------------------------------------------------------ the step
    def step(self, plant, s: State, tau: np.ndarray, dt: float, t: float) -> State:
        """The state after one plant step of dt from time t: contacts decided at s, the step with the
        locked joints held, then the impulses of the joints that arrived during it."""
        T = self.table
        locked = np.nonzero(self.side)[0]
        if locked.size:
            locked = self._contacts(plant, s, tau, locked, t)
        s1 = plant.step(s, tau, dt, T.v_index[locked] if locked.size else None)
        t1 = t + dt
        self._time[locked] += dt
        self.total_time[locked] += dt
        self._arrivals(plant, s1, t1)
        pen = penetration(T, s1.q)
        self._pen = np.maximum(self._pen, pen)
        self.max_penetration = np.maximum(self.max_penetration, pen)
        self.rebound &= pen > 0.0
        return s1

    def _contacts(self, plant, s: State, tau: np.ndarray, locked: np.ndarray, t: float) -> np.ndarray:
        """The locked joints whose contact force pushes at s (complementarity on the free accelerations);
        the others are released."""
        T = self.table
        o = self.side[locked].astype(float)
        vd, _ = plant.accel(s, tau)
        cols = T.v_index[locked]
        G = plant.inverse_mass_columns(s.q, cols)[cols]
        mu = complementarity(o[:, None] * G * o[None, :], o * vd[cols])
        for j in locked[mu <= 0.0]:
            self._release(j, t)
        return locked[mu > 0.0]

    def _arrivals(self, plant, s: State, t: float) -> None:
        """Impulses when a joint arrives (at or beyond a limit, moving outward, not locked); s is changed
        in place (v, η̇). Every joint at or beyond a limit takes part: an arriving joint's rate goes to
        −e × its rate (0 after a rebound), a locked one stays at rest, one already moving back stays free
        unless the others' impulses would throw it outward (then it is stopped and locked)."""
        T = self.table
        q, v = s.q[T.q_index], s.v[T.v_index]
        beyond = np.where(q >= T.upper, UPPER, np.where(q <= T.lower, LOWER, 0))
        side = np.where(self.side != 0, self.side, beyond)
        arriving = (self.side == 0) & (beyond != 0) & (beyond * v > 0.0)
        if not np.any(arriving):
            return
        S = np.nonzero(side != 0)[0]
        o = side[S].astype(float)
        u0 = o * v[S]  # outward rates before the impact
        arr = arriving[S]
        bounce = arr & ~self.rebound[S] & (self.restitution > 0.0)
        target = np.where(bounce, -self.restitution * u0, 0.0)
        cols = T.v_index[S]
        G = plant.inverse_mass_columns(s.q, cols)
        mu = complementarity(o[:, None] * G[cols] * o[None, :], u0 - target)
        dx = G @ (-o * mu)  # generalized impulses −o μ: pushes toward the inside of the range
        nv = s.v.size
        s.v += dx[:nv]
        s.etadot += dx[nv:]
        u1 = o * s.v[cols]
        tol = 1e-9 * float(np.max(np.abs(u0)))  # an inward rate below this is the round-off of the impulse
        for k, j in enumerate(S):
            if self.side[j] != 0:
                if u1[k] < -tol:  # the others' impulses take a locked joint off its stop
                    self._release(j, t)
                continue
            if mu[k] <= 0.0:
                continue
            limit = float(T.upper[j] if o[k] == UPPER else T.lower[j])
            self.events.append((t, "joint_stop", {
                "joint": T.names[j], "side": "upper" if o[k] == UPPER else "lower", "limit": limit,
                "rate": float(v[j]), "rate_after": float(s.v[T.v_index[j]]), "penetration": abs(float(q[j]) - limit),
                "impulse": float(-o[k] * mu[k])}))
            if bounce[k]:
                self.rebound[j] = True
            else:
                self.side[j], self.since[j] = int(o[k]), t

    def _release(self, j: int, t: float) -> None:
        T = self.table
        self.events.append((t, "joint_stop_release", {
            "joint": T.names[j], "side": "upper" if self.side[j] == UPPER else "lower", "time_on_stop_s": float(t - self.since[j])}))
        self.side[j] = 0
