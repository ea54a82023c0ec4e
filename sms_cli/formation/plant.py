"""Two free-flying spacecraft in one Pinocchio model, and two integrators of its motion.

State (DESIGN.md §3, per body, body 1 = master first): ``q = [x y z, qx qy qz qw, joints₁…, x y z, quat, joints₂…]``
(positions in the world frame) and ``v = [v₁ (m/s), ω₁ (rad/s), joint rates₁…, v₂, ω₂, joint rates₂…]`` with each
base twist in its own base frame (the root free-flyer joint frame = the base link frame). Zero gravity. Every
joint and frame of body b is named ``"<name_b>/<its own name>"`` in the combined model; ``BodyMap.frames`` maps the
body's own frame names to combined frame ids.

Wrenches are ``[f (N); τ (N m)]``. A base wrench acts at the base-frame origin in base axes; a frame wrench acts
at the frame's origin in the frame's LOCAL axes.

- ``TwoBodyPlant.step``: RKMK4 (Runge–Kutta–Munthe-Kaas, as ``sms_cli.dynamics.integrator``) on the combined
  configuration, with the dexp⁻¹ bracket correction on each free-flyer's 6-block.
- ``DecomposedIntegrator``: the HIL integrator of Vicariotto 2023 (§6, L1159–L1167): integrates the poses and
  ``y = [V_L (frame 1); V_E (frame 2); joint rates₁; joint rates₂]`` and rebuilds the absolute velocities by
  S⁻¹ at every stage. Same trajectories as ``step`` up to the O(dt⁴) truncation of both.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import pinocchio as pin

from sms_cli.dynamics.integrator import _dexpinv_neg
from sms_cli.errors import InputError, Problem
from sms_cli.formation.decomposition import PairDecomposition, decompose
from sms_cli.model.system import SystemModel, symmetric_from_crba

#: interface(q, v) -> [(combined frame id, wrench (6) in that frame's LOCAL axes at its origin), …]
Interface = Callable[[np.ndarray, np.ndarray], Sequence[tuple[int, np.ndarray]]]
Wrenches = tuple[np.ndarray | None, np.ndarray | None]


@dataclass(frozen=True)
class BodyMap:
    """Where one spacecraft sits in the combined model (all indices are combined ones)."""

    name: str
    system: SystemModel
    q: slice               # its whole configuration
    v: slice               # its whole velocity
    base_v: slice          # its base twist (6)
    joints_q: slice        # its joint positions (after the base's 7)
    joints_v: slice        # its joint rates
    base_joint_id: int
    base_frame_id: int
    ee_frame_id: int
    wheels_v: np.ndarray
    arm_v: np.ndarray
    frames: dict[str, int] = field(default_factory=dict)


def _refusals(sm: SystemModel, name: str) -> list[Problem]:
    problems = []
    if sm.appendages:
        problems.append(Problem(
            f"spacecraft '{name}' ({sm.name}) has flexible appendages ({', '.join(a.name for a in sm.appendages)}): "
            "not supported in two-spacecraft missions yet", field="appendages",
            hint="remove the appendages of this spacecraft's mission for the two-spacecraft study"))
    if sm.springs:
        problems.append(Problem(
            f"spacecraft '{name}' ({sm.name}) has spring joints ({', '.join(s.joint for s in sm.springs)}): "
            "not supported in two-spacecraft missions yet", field="springs",
            hint="model the joints as rigid or as arm joints for the two-spacecraft study"))
    return problems


def prefixed(name: str, body: str) -> str:
    """The name of spacecraft ``body``'s joint, frame or link ``name`` in the combined model, its URDF and its
    recording (``client/bus``)."""
    return f"{body}/{name}"


def _prefixed(model: pin.Model, body: str) -> pin.Model:
    out = model.copy()
    for j in range(1, out.njoints):
        out.names[j] = prefixed(out.names[j], body)
    for k in range(1, out.nframes):
        f = out.frames[k]
        f.name = prefixed(f.name, body)
        out.frames[k] = f
    return out


def _frame_map(model: pin.Model, first: int) -> dict[str, int]:
    """Own frame name -> combined id (the body's frame k ≥ 1 is combined frame first + k − 1). Where a joint
    and a link share a name, the link's BODY frame wins."""
    out: dict[str, int] = {}
    for k in range(1, model.nframes):
        f = model.frames[k]
        if f.name not in out or f.type == pin.FrameType.BODY:
            out[f.name] = first + k - 1
    return out


def joint_forces(model: pin.Model, wrenches: Sequence[tuple[int, np.ndarray]]) -> list:
    """The ``fext`` of ``pin.aba``/``pin.rnea`` (one ``pin.Force`` per joint, in the joint's LOCAL frame) for
    wrenches [f; τ] given at frames (each in the frame's LOCAL axes at its origin)."""
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    for fid, F in wrenches:
        frame = model.frames[fid]
        fext[frame.parentJoint] += frame.placement.act(pin.Force(np.asarray(F, float)))
    return fext


def system_momentum(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Total momentum [p; L_O] (N s, N m s) of every body, world axes, angular part about the world origin."""
    h_g = pin.computeCentroidalMomentum(model, data, q, v)
    return np.concatenate([h_g.linear, h_g.angular + np.cross(data.com[0], h_g.linear)])


def _dexpinv_blocks(theta: np.ndarray, u: np.ndarray, blocks: Sequence[slice]) -> np.ndarray:
    """dexp⁻¹_{−θ}(u) on each free-flyer 6-block (``_dexpinv_neg`` on slices); joints are abelian."""
    out = u.copy()
    for s in blocks:
        out[s] = _dexpinv_neg(theta[s], u[s])
    return out


def rkmk4(model: pin.Model, blocks: Sequence[slice], q0: np.ndarray, y0: np.ndarray, dt: float,
          rhs: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """One RKMK4 step of size dt (s): q moves on the configuration manifold with tangent velocity u and a vector y
    with rate ẏ, ``rhs(q, y) -> (u (nv), ẏ)``; ``blocks`` are the free-flyers' velocity slices.
    With y = v and u = v this is ``sms_cli.dynamics.integrator.rkmk4_step`` for several free-flyers."""
    h = 0.5 * dt
    integrate = pin.integrate
    u1, d1 = rhs(q0, y0)
    th = h * u1
    u2, d2 = rhs(integrate(model, q0, th), y0 + h * d1)
    k2 = _dexpinv_blocks(th, u2, blocks)
    th = h * k2
    u3, d3 = rhs(integrate(model, q0, th), y0 + h * d2)
    k3 = _dexpinv_blocks(th, u3, blocks)
    th = dt * k3
    u4, d4 = rhs(integrate(model, q0, th), y0 + dt * d3)
    k4 = _dexpinv_blocks(th, u4, blocks)
    c = dt / 6.0
    return integrate(model, q0, c * (u1 + 2.0 * (k2 + k3) + k4)), y0 + c * (d1 + 2.0 * (d2 + d3) + d4)


class TwoBodyPlant:
    """Two free-flying spacecraft (each a compiled ``SystemModel``) in one Pinocchio model; see the module docstring."""

    def __init__(self, model: pin.Model, bodies: tuple[BodyMap, BodyMap]):
        self.model = model
        self.data = model.createData()
        self._kin = model.createData()  # for frame_pose (callers' interfaces run between dynamics calls)
        self.bodies = bodies
        self.nq, self.nv = model.nq, model.nv
        self.base_blocks = tuple(b.base_v for b in bodies)

    @classmethod
    def build(cls, master: SystemModel, other: SystemModel, names: tuple[str, str] = ("client", "servicer")) -> "TwoBodyPlant":
        """Combine ``master`` (body 1, the locked system's frame) and ``other`` (body 2). Refuses (InputError)
        flexible appendages and spring joints, equal or empty names, kinematics-only models."""
        problems = []
        if len(names) != 2 or not all(isinstance(n, str) and n for n in names) or names[0] == names[1]:
            problems.append(Problem(f"the two spacecraft need two different non-empty names, got {tuple(names)}",
                                    field="names", hint="name them e.g. 'client' and 'servicer'"))
        for sm, name in zip((master, other), names):
            problems += _refusals(sm, str(name))
            if sm.model.njoints < 2 or sm.model.joints[1].shortname() != "JointModelFreeFlyer":
                problems.append(Problem(f"spacecraft '{name}' ({sm.name}) has no free-flyer root joint", field="robot"))
        if problems:
            raise InputError(problems=problems)
        for sm in (master, other):
            sm.require_dynamics("a two-spacecraft simulation")
        a, b = _prefixed(master.model, names[0]), _prefixed(other.model, names[1])
        model = pin.appendModel(a, b, 0, pin.SE3.Identity())
        model.gravity = pin.Motion.Zero()
        bodies = []
        for sm, name, qo, vo, jo, fo in ((master, names[0], 0, 0, 0, 1),
                                         (other, names[1], a.nq, a.nv, a.njoints - 1, a.nframes)):
            frames = _frame_map(sm.model, fo)
            for own, cid in frames.items():  # appendModel keeps the order of joints and frames
                assert model.frames[cid].name == prefixed(own, name), (own, model.frames[cid].name)
            bodies.append(BodyMap(
                name=name, system=sm, q=slice(qo, qo + sm.nq), v=slice(vo, vo + sm.nv), base_v=slice(vo, vo + 6),
                joints_q=slice(qo + 7, qo + sm.nq), joints_v=slice(vo + 6, vo + sm.nv),
                base_joint_id=jo + sm.base_joint_id, base_frame_id=fo + sm.base_frame_id - 1,
                ee_frame_id=fo + sm.ee_frame_id - 1,
                wheels_v=np.array([vo + w.v_index for w in sm.wheels], dtype=int),
                arm_v=np.array([vo + j.v_index for j in sm.arm], dtype=int), frames=frames))
        return cls(model, (bodies[0], bodies[1]))

    def add_frame(self, name: str, frame_id: int, placement: pin.SE3) -> int:
        """Add a frame at ``placement`` in frame ``frame_id`` (combined ids; e.g. a capture interface); its id."""
        parent = self.model.frames[frame_id]
        fid = self.model.addFrame(pin.Frame(name, parent.parentJoint, frame_id, parent.placement * placement,
                                            pin.FrameType.OP_FRAME))
        self.data, self._kin = self.model.createData(), self.model.createData()
        return fid

    # ------------------------------------------------------------------ state
    def body(self, i: int | str) -> BodyMap:
        """Body 0 (master, body 1 of the thesis) or 1 (other), or by name."""
        if isinstance(i, str):
            for b in self.bodies:
                if b.name == i:
                    return b
            raise KeyError(f"no spacecraft named {i!r}; have {[b.name for b in self.bodies]}")
        return self.bodies[i]

    def initial_state(self, g1_world: pin.SE3, V1: np.ndarray, g2_world: pin.SE3, V2: np.ndarray,
                      joints_q: tuple = (None, None), joints_v: tuple = (None, None)) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) from base poses (world <- base), base twists (6, base frame) and joint states (default: each
        SystemModel's q0/v0 joint entries)."""
        q, v = np.zeros(self.nq), np.zeros(self.nv)
        for b, g, V, jq, jv in zip(self.bodies, (g1_world, g2_world), (V1, V2), joints_q, joints_v):
            q[b.q.start:b.q.start + 7] = pin.SE3ToXYZQUAT(g)
            q[b.joints_q] = b.system.q0[7:] if jq is None else jq
            v[b.base_v] = V
            v[b.joints_v] = b.system.v0[6:] if jv is None else jv
        return q, v

    def base_pose(self, q: np.ndarray, i: int | str) -> pin.SE3:
        """World <- base frame of body i."""
        s = self.body(i).q
        return pin.XYZQUATToSE3(q[s.start:s.start + 7])

    def base_twist(self, v: np.ndarray, i: int | str) -> np.ndarray:
        """Body twist [v; ω] of base i in its base frame (6)."""
        return np.array(v[self.body(i).base_v])

    def frame_pose(self, q: np.ndarray, frame_id: int) -> pin.SE3:
        """World <- frame (combined frame id)."""
        pin.forwardKinematics(self.model, self._kin, q)
        return pin.updateFramePlacement(self.model, self._kin, frame_id).copy()

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Joint-space inertia (nv × nv), block-diagonal per body."""
        return symmetric_from_crba(pin.crba(self.model, self.data, q))

    def locked_inertia(self, q: np.ndarray, i: int | str) -> np.ndarray:
        """M_i (6×6): spacecraft i's spatial inertia with its joints locked, about its base origin in base axes."""
        s = self.body(i).base_v
        return self.mass_matrix(q)[s, s]

    def locked_twist(self, q: np.ndarray, v: np.ndarray, i: int | str) -> np.ndarray:
        """ξ_i = M_i⁻¹ h_i (6, base frame): h_i = (M v) on base i's rows, its momentum about its base origin."""
        return self.locked_state(self.mass_matrix(q), v, i)[0]

    def decomposition(self, q: np.ndarray, v: np.ndarray,
                      M: np.ndarray | None = None) -> tuple[PairDecomposition, np.ndarray, np.ndarray]:
        """(locked/shape decomposition at g12 = g1⁻¹ g2 with the locked inertias, ξ1, ξ2); ``M``: the mass matrix
        at q if the caller has it."""
        M = self.mass_matrix(q) if M is None else M
        s1, s2 = self.base_blocks
        return self.pair_decomposition(q, M), self.locked_state(M, v, 0)[0], self.locked_state(M, v, 1)[0]

    def pair_decomposition(self, q: np.ndarray, M: np.ndarray) -> PairDecomposition:
        """The locked/shape decomposition at q (g12 = g1⁻¹ g2, the locked inertias from the mass matrix M at q)."""
        s1, s2 = self.base_blocks
        return decompose(M[s1, s1], M[s2, s2], self.base_pose(q, 0).inverse() * self.base_pose(q, 1))

    def connection(self, M: np.ndarray, i: int | str) -> tuple[np.ndarray, np.ndarray]:
        """(Λ_i = M_bb⁻¹ M_bθ, 6 × joints of body i: the mechanical connection, so that its locked twist is
        ξ_i = V_i + Λ_i θ̇_i; M_θθ − M_θb Λ_i, the joints' shape inertia) from the mass matrix M at q."""
        return self.locked_state(M, np.zeros(M.shape[0]), i)[1:]

    def locked_state(self, M: np.ndarray, v: np.ndarray, i: int | str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ξ_i = M_bb⁻¹ (M v)_b, its locked twist (6, base frame); Λ_i and the joints' shape inertia as
        ``connection``) from the mass matrix M and velocity v (kernel ``pair_decomposition.locked_state``)."""
        from sms_cli.sim.compiled.pair_decomposition import locked_state

        b = self.body(i)
        return locked_state(np.ascontiguousarray(M, dtype=float), np.ascontiguousarray(v, dtype=float), b.base_v.start,
                            b.joints_v.start, b.joints_v.stop - b.joints_v.start)

    # ------------------------------------------------------------------ dynamics
    def accelerations(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, base_wrenches: Wrenches = (None, None),
                      frame_wrenches: Sequence[tuple[int, np.ndarray]] = ()) -> np.ndarray:
        """v̇ (nv) by ABA. ``tau`` (nv): joint torques (N m or N), base entries ignored; ``base_wrenches``: (F1, F2),
        each on its base in its base frame, None for none; ``frame_wrenches``: (frame id, wrench in the frame's
        LOCAL axes at its origin), moved to the parent joint frame by the frame placement."""
        tau = np.array(tau, dtype=float)
        for s, F in zip(self.base_blocks, base_wrenches):
            tau[s] = 0.0 if F is None else F
        if not frame_wrenches:
            return pin.aba(self.model, self.data, q, v, tau).copy()
        return pin.aba(self.model, self.data, q, v, tau, joint_forces(self.model, frame_wrenches)).copy()

    def step(self, q: np.ndarray, v: np.ndarray, dt: float, tau: np.ndarray, base_wrenches: Wrenches = (None, None),
             interface: Interface | None = None) -> tuple[np.ndarray, np.ndarray]:
        """One RKMK4 step of dt (s); tau and base wrenches held (ZOH), ``interface(q, v)`` evaluated at every stage."""
        def rhs(qs, vs):
            fw = interface(qs, vs) if interface is not None else ()
            return vs, self.accelerations(qs, vs, tau, base_wrenches, fw)

        return rkmk4(self.model, self.base_blocks, q, v, dt, rhs)

    # ------------------------------------------------------------------ invariants
    def momentum_world(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """[linear momentum (kg m/s); angular momentum about the world origin (kg m²/s)], world axes (6)."""
        return system_momentum(self.model, self.data, q, v)

    def kinetic_energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """½ vᵀ M(q) v (J)."""
        return float(pin.computeKineticEnergy(self.model, self.data, q, v))


class DecomposedIntegrator:
    """Vicariotto 2023's HIL integrator (L1159–L1167) on a ``TwoBodyPlant``: RKMK4 on the poses and joint
    positions (q as the plant's) and on ``y = [V_L; V_E; joint rates₁; joint rates₂]`` (nv).

    At each stage the absolute velocities come back from y: ξ = S⁻¹[V_L; V_E], base twists V_i = ξ_i − M_i⁻¹ M_ij q̇_j
    (M_ij the base/joint block of spacecraft i); then v̇ by ABA and
    ``d/dt[V_L; V_E] = S ξ̇ + Ṡ ξ`` with ``ξ̇_i = M_i⁻¹(ḣ_i − Ṁ_i ξ_i)``, ``ḣ_i = (M v̇ + Ṁ v)`` on base i's rows,
    ``Ṁ = C + Cᵀ`` (Pinocchio's Coriolis matrix) and Ṡ in closed form (``PairDecomposition.S_rate`` with the
    relative base twist V12 = V2 − Ad⁻¹V1 and Ṁ_1, Ṁ_2)."""

    def __init__(self, plant: TwoBodyPlant):
        self.plant = plant
        self._data = plant.model.createData()

    def _split(self, q: np.ndarray):
        p = self.plant
        M = p.mass_matrix(q)
        return M, p.pair_decomposition(q, M), [p.connection(M, i)[0] for i in range(2)]

    def _joint_rates(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n1 = self.plant.bodies[0].system.nv - 6
        return y[12:12 + n1], y[12 + n1:]

    def to_decomposed(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """y = [V_L; V_E; joint rates₁; joint rates₂] of the plant state (q, v)."""
        p = self.plant
        M, dec, _ = self._split(q)
        xi = [np.linalg.solve(M[b.base_v, b.base_v], M[b.base_v] @ v) for b in p.bodies]
        return np.concatenate([*dec.locked_shape(*xi), *(v[b.joints_v] for b in p.bodies)])

    def _plain(self, q, y):
        p = self.plant
        M, dec, conn = self._split(q)
        xis = dec.body_twists(y[:6], y[6:12])
        v = np.zeros(p.nv)
        for b, xi, c, jr in zip(p.bodies, xis, conn, self._joint_rates(y)):
            v[b.base_v] = xi - c @ jr
            v[b.joints_v] = jr
        return v, M, dec, xis

    def to_plain(self, q: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Plant velocity v (nv) of the decomposed state (q, y)."""
        return self._plain(q, y)[0]

    def rates(self, q: np.ndarray, y: np.ndarray, tau: np.ndarray, base_wrenches: Wrenches = (None, None),
              frame_wrenches: Sequence[tuple[int, np.ndarray]] = ()) -> tuple[np.ndarray, np.ndarray]:
        """(v (nv, tangent velocity of q), ẏ (nv)) at (q, y) under the given inputs."""
        p = self.plant
        v, M, dec, (xi1, xi2) = self._plain(q, y)
        vdot = p.accelerations(q, v, tau, base_wrenches, frame_wrenches)
        C = pin.computeCoriolisMatrix(p.model, self._data, q, v)
        Mdot = C + C.T
        s1, s2 = p.base_blocks
        xidot = [np.linalg.solve(M[s, s], M[s] @ vdot + Mdot[s] @ v - Mdot[s, s] @ xi)
                 for s, xi in ((s1, xi1), (s2, xi2))]
        V12 = v[s2] - dec.Ad12_inv @ v[s1]
        xi = np.concatenate([xi1, xi2])
        VLE_dot = dec.S @ np.concatenate(xidot) + dec.S_rate(V12, Mdot[s1, s1], Mdot[s2, s2]) @ xi
        return v, np.concatenate([VLE_dot, *(vdot[b.joints_v] for b in p.bodies)])

    def step(self, q: np.ndarray, y: np.ndarray, dt: float, tau: np.ndarray, base_wrenches: Wrenches = (None, None),
             interface: Interface | None = None) -> tuple[np.ndarray, np.ndarray]:
        """One RKMK4 step of dt (s) of (q, y); inputs held (ZOH); ``interface(q, v)`` sees the plant velocity."""
        def rhs(qs, ys):
            if interface is None:
                return self.rates(qs, ys, tau, base_wrenches)
            v = self.to_plain(qs, ys)
            return self.rates(qs, ys, tau, base_wrenches, interface(qs, v))

        return rkmk4(self.plant.model, self.plant.base_blocks, q, y, dt, rhs)
