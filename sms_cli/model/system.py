"""``SystemModel``: the compiled floating-base system every stage reads.

State (Pinocchio convention, DESIGN.md §3): ``q`` (nq) = [x y z (world), qx qy qz qw, joints…];
``v`` (nv) = [v_base (base frame, base-link origin), ω_base (base frame), joint rates…];
modal coordinates ``eta`` and rates ``etadot`` (n_modes). Augmented velocity ``x = [v; etadot]``.

Flexible appendages use hybrid coordinates at a junction frame j (Craig–Bampton,
mass-normalised modes). With ``V = J_j(q) v`` the junction twist in the junction frame
([v; ω], Pinocchio LOCAL) and ``L`` the participation matrix (n_η × 6, [T; R] order):

  T = ½ vᵀH v + η̇ᵀ L V + ½ η̇ᵀη̇,   U = ½ ηᵀ Ω² η,   damping 2ζΩ η̇.

Euler–Poincaré on the junction body gives the exact equations (DESIGN.md §3 plus the
gyroscopic term of the modal momentum p = Lᵀη̇ that the design's form leaves out):

  [[H, JᵀLᵀ], [L J, I]] [v̇; η̈] + [h(q,v) + Jᵀ (V ×* p) ; L J̇v] = [τ; −Ω²η − 2ζΩη̇]

with ``×*`` the spatial force cross product and ``J̇v`` the drift of the junction twist.
These conserve momentum and (undamped) energy exactly; the design's form drifts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv as _dposv

from sms_cli.model.conventions import seed_map

LOCAL = pin.ReferenceFrame.LOCAL
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3-vector cross product (np.cross costs ~10 µs on 3-vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def symmetric_from_crba(upper: np.ndarray) -> np.ndarray:
    """Full symmetric matrix from Pinocchio's CRBA output (upper triangle filled)."""
    full = np.triu(upper)
    full += full.T
    full.flat[:: full.shape[0] + 1] *= 0.5
    return full


@dataclass
class Wheel:
    """A reaction wheel joint. ``axis`` is its unit spin axis in the base frame at q0."""

    name: str
    joint_id: int
    v_index: int
    q_index: int
    axis: np.ndarray
    spin_inertia: float
    max_torque: float
    max_speed: float
    initial_speed: float


@dataclass
class ArmJoint:
    """An actuated manipulator joint; limits are ``inf`` where the URDF gives none."""

    name: str
    joint_id: int
    v_index: int
    q_index: int
    kind: str
    lower: float
    upper: float
    max_velocity: float
    max_effort: float


@dataclass
class Spring:
    """A passive spring/damper joint: generalized force −k (q − rest) − c q̇."""

    joint: str
    v_index: int
    q_index: int
    stiffness: float
    damping: float
    rest: float


@dataclass
class Appendage:
    """Modal appendage: L (n×6, [Tx Ty Tz Rx Ry Rz] in the junction frame), Ω (rad/s), ζ."""

    name: str
    frame_id: int
    L: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray
    modes: slice


@dataclass
class Payload:
    """A body attachable to a frame: its spatial inertia expressed in the parent joint frame."""

    name: str
    frame_id: int
    joint_id: int
    inertia_in_joint: pin.Inertia
    attached: bool


@dataclass
class Partitions:
    """Index sets of the velocity vector (and of q) per partition (DESIGN.md §3)."""

    base: np.ndarray
    base_linear: np.ndarray
    base_angular: np.ndarray
    wheels: np.ndarray
    arm: np.ndarray
    passive: np.ndarray
    modes: np.ndarray
    q_wheels: np.ndarray
    q_arm: np.ndarray
    q_passive: np.ndarray


@dataclass
class SystemModel:
    """The compiled system. See the module docstring for the state and equations."""

    model: pin.Model
    name: str
    urdf_text: str
    idx: Partitions
    wheels: list[Wheel]
    arm: list[ArmJoint]
    springs: list[Spring]
    appendages: list[Appendage]
    payloads: dict[str, Payload]
    ee_frame_id: int
    base_frame_id: int
    q0: np.ndarray
    v0: np.ndarray
    eta0: np.ndarray
    etadot0: np.ndarray
    warnings: list = field(default_factory=list)
    base_joint_id: int = 1
    link_parents: dict[str, str] = field(default_factory=dict)  # URDF link (and wheel rotor) -> parent link; base -> "world"
    link_frames: dict[str, int] = field(default_factory=dict)  # the same links -> their BODY frame id (names may clash with joints)
    kinematics_only: list[str] = field(default_factory=list)  # links given a placeholder inertia (robot.kinematics_only)
    link_inertias: dict[str, pin.Inertia] = field(default_factory=dict)  # the same links -> own inertia, link frame
    thrusters: object = None  # sms_cli.thrusters.layout.ThrusterSet of the mission's thrusters: section, or None

    def link_inertial(self, link: str) -> tuple[float, np.ndarray, np.ndarray]:
        """(mass kg, CoM (3,) m in the link frame, [ixx iyy izz ixy ixz iyz] kg m² about the CoM in the link
        axes (sms_cli.inertia convention)) of a URDF link or wheel rotor, as this model's bodies hold it: the
        URDF's <inertial> with ``robot.links`` applied (placeholders of ``kinematics_only`` not included)."""
        if link not in self.link_inertias:
            import difflib

            close = difflib.get_close_matches(link, list(self.link_inertias), n=1)
            raise KeyError(f"no link named '{link}'" + (f"; did you mean '{close[0]}'?" if close else ""))
        Y = self.link_inertias[link]
        inertia = Y.inertia
        return float(Y.mass), Y.lever.copy(), np.array([inertia[0, 0], inertia[1, 1], inertia[2, 2],
                                                         inertia[0, 1], inertia[0, 2], inertia[1, 2]])

    def require_dynamics(self, what: str) -> None:
        """Refuse (exit 2) a stage that needs real inertias on a kinematics-only model."""
        if self.kinematics_only:
            from sms_cli.errors import InputError, Problem

            raise InputError(problems=[Problem(
                f"{what} needs the robot's inertias, but links {', '.join(self.kinematics_only)} have placeholder "
                "inertias (robot.kinematics_only)", field="robot.kinematics_only",
                hint="give these links an <inertial> in the URDF and remove robot.kinematics_only")])

    def __post_init__(self) -> None:
        self.data = self.model.createData()
        self.nq = self.model.nq
        self.nv = self.model.nv
        self.n_modes = int(sum(a.omega.size for a in self.appendages))
        self.nx = self.nv + self.n_modes
        self._omega = np.concatenate([a.omega for a in self.appendages]) if self.appendages else np.zeros(0)
        self._zeta = np.concatenate([a.zeta for a in self.appendages]) if self.appendages else np.zeros(0)
        self._spring_v = np.array([s.v_index for s in self.springs], dtype=int)
        self._spring_q = np.array([s.q_index for s in self.springs], dtype=int)
        self._spring_k = np.array([s.stiffness for s in self.springs])
        self._spring_c = np.array([s.damping for s in self.springs])
        self._spring_rest = np.array([s.rest for s in self.springs])
        self._prepare_base_modes()
        # Pinocchio 4's Python crba returns the full symmetric matrix; older ones fill the upper triangle
        M = pin.crba(self.model, self.data, pin.neutral(self.model))
        self._crba_full = bool(np.allclose(M, M.T) and (self.nv == 1 or np.any(np.tril(M, -1) != 0)))

    def _prepare_base_modes(self) -> None:
        """Fast path when every appendage is mounted on the base body (the usual case):
        the junction Jacobian is the constant adjoint X (6×6) on the base columns, so
        B = L X (n_η×6) is constant, the drift L J̇ v vanishes and Jᵀ(V ×* p) = v_b ×* (Bᵀη̇)."""
        self._base_B = None
        if self.appendages and all(self.model.frames[a.frame_id].parentJoint == self.base_joint_id for a in self.appendages):
            B = np.zeros((self.n_modes, 6))
            for a in self.appendages:
                X = self.model.frames[a.frame_id].placement.inverse().action  # base twist -> junction twist
                B[a.modes] = a.L @ X
            self._base_B = B
            self._base_Bt = np.ascontiguousarray(B.T)
            self._base_BtB = B.T @ B
            self._neg_omega2 = -(self._omega**2)
            self._neg_2zo = -2.0 * self._zeta * self._omega

    # ------------------------------------------------------------------ inertia
    @property
    def base_modal_coupling(self) -> np.ndarray | None:
        """B (n_modes × 6) when every appendage is on the base (η̈ = r_η − B v̇_base), else None."""
        return self._base_B

    @cached_property
    def reduced(self):
        """The reduced form for Kraiem 2022 §3.3 (``sms_cli.model.reduced.ReducedModel``), built once: index
        sets, flexible stiffness and damping (they do not change when payloads are attached or released)."""
        from sms_cli.model.reduced import reduced_model

        return reduced_model(self)

    @property
    def total_mass(self) -> float:
        return float(sum(self.model.inertias[i].mass for i in range(1, self.model.njoints)))

    def attach_payload(self, name: str) -> None:
        """Add a payload's inertia to its frame's body (topology unchanged)."""
        p = self.payloads[name]
        if not p.attached:
            self.model.inertias[p.joint_id] = self.model.inertias[p.joint_id] + p.inertia_in_joint
            p.attached = True

    def detach_payload(self, name: str) -> None:
        """Remove a payload's inertia from its frame's body."""
        p = self.payloads[name]
        if p.attached:
            Y = self.model.inertias[p.joint_id]
            self.model.inertias[p.joint_id] = pin.Inertia.FromDynamicParameters(
                Y.toDynamicParameters() - p.inertia_in_joint.toDynamicParameters())
            p.attached = False

    # ------------------------------------------------------------------ kinematics
    def frame_pose(self, q: np.ndarray, frame_id: int) -> pin.SE3:
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[frame_id].copy()

    def ee_pose(self, q: np.ndarray) -> pin.SE3:
        return self.frame_pose(q, self.ee_frame_id)

    def com(self, q: np.ndarray) -> np.ndarray:
        """System centre of mass in the world frame (m)."""
        return pin.centerOfMass(self.model, self.data, q).copy()

    def _junctions(self, q: np.ndarray, v: np.ndarray | None = None):
        """Per appendage: (J local 6×nv, V local twist, drift acceleration, oMf). Kinematics at (q, v, a=0)."""
        m, d = self.model, self.data
        if v is None:
            pin.forwardKinematics(m, d, q)
        else:
            pin.forwardKinematics(m, d, q, v, np.zeros(m.nv))
        pin.computeJointJacobians(m, d, q)
        pin.updateFramePlacements(m, d)
        out = []
        for a in self.appendages:
            J = pin.getFrameJacobian(m, d, a.frame_id, LOCAL)
            if v is None:
                out.append((J, None, None, d.oMf[a.frame_id]))
            else:
                V = pin.getFrameVelocity(m, d, a.frame_id, LOCAL)
                acc = pin.getFrameAcceleration(m, d, a.frame_id, LOCAL)
                out.append((J, V, acc, d.oMf[a.frame_id]))
        return out

    # ------------------------------------------------------------------ dynamics
    def rigid_mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Symmetric joint-space inertia H(q) of the rigid system (nv×nv)."""
        M = pin.crba(self.model, self.data, q)
        return M.copy() if self._crba_full else symmetric_from_crba(M)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Augmented mass matrix [[H, JᵀLᵀ], [L J, I]] (nx×nx)."""
        nv = self.nv
        M = np.zeros((self.nx, self.nx))
        M[:nv, :nv] = self.rigid_mass_matrix(q)
        if self.appendages:
            for a, (J, _, _, _) in zip(self.appendages, self._junctions(q)):
                LJ = a.L @ J
                s = slice(nv + a.modes.start, nv + a.modes.stop)
                M[s, :nv] = LJ
                M[:nv, s] = LJ.T
                M[s, s] = np.eye(a.omega.size)
        return M

    def bias_forces(self, q: np.ndarray, v: np.ndarray, etadot: np.ndarray) -> np.ndarray:
        """Velocity-dependent terms (nx): [h(q,v) + Σ Jᵀ(V ×* Lᵀη̇) ; L J̇v] (no springs, no modal stiffness)."""
        nv = self.nv
        b = np.zeros(self.nx)
        b[:nv] = pin.nonLinearEffects(self.model, self.data, q, v)
        if self.appendages:
            for a, (J, V, acc, _) in zip(self.appendages, self._junctions(q, v)):
                p = pin.Force(a.L.T @ etadot[a.modes])
                b[:nv] += J.T @ V.cross(p).vector
                b[nv + a.modes.start: nv + a.modes.stop] = a.L @ acc.vector
        return b

    def internal_forces(self, q: np.ndarray, v: np.ndarray, eta: np.ndarray, etadot: np.ndarray) -> np.ndarray:
        """Right-hand-side generalized forces of springs/dampers and modal stiffness/damping (nx)."""
        f = np.zeros(self.nx)
        if self.springs:
            f[self._spring_v] = -self._spring_k * (q[self._spring_q] - self._spring_rest) - self._spring_c * v[self._spring_v]
        if self.n_modes:
            f[self.nv:] = -(self._omega**2) * eta - 2.0 * self._zeta * self._omega * etadot
        return f

    def forward_dynamics(self, q: np.ndarray, v: np.ndarray, eta: np.ndarray, etadot: np.ndarray,
                         tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Accelerations (v̇, η̈) under generalized forces tau (nv; base entries = wrench [f; n] in the base frame)."""
        if not self.n_modes:
            tau_total = np.array(tau, dtype=float)
            if self.springs:
                tau_total = tau_total + self.internal_forces(q, v, eta, etadot)[: self.nv]
            return pin.aba(self.model, self.data, q, v, tau_total).copy(), np.zeros(0)
        if self._base_B is not None:
            return self._forward_dynamics_base_modes(q, v, eta, etadot, tau)
        rhs = self.internal_forces(q, v, eta, etadot) - self.bias_forces(q, v, etadot)
        rhs[: self.nv] += tau
        acc = np.linalg.solve(self.mass_matrix(q), rhs)
        return acc[: self.nv], acc[self.nv:]

    def forward_dynamics_fixed_base(self, q: np.ndarray, v: np.ndarray, eta: np.ndarray, etadot: np.ndarray,
                                    tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Accelerations with the base held (v_base = 0, v̇_base = 0): joints and modes only.
        The wrench that holds the base is ``base_reaction(q, v, vdot, etaddot)``."""
        rhs = self.internal_forces(q, v, eta, etadot) - self.bias_forces(q, v, etadot)
        rhs[: self.nv] += tau
        free = np.r_[6:self.nx]
        M = self.mass_matrix(q)
        acc = np.zeros(self.nx)
        acc[free] = np.linalg.solve(M[np.ix_(free, free)], rhs[free])
        return acc[: self.nv], acc[self.nv:]

    def base_reaction(self, q: np.ndarray, v: np.ndarray, eta: np.ndarray, etadot: np.ndarray, vdot: np.ndarray,
                      etaddot: np.ndarray) -> np.ndarray:
        """Wrench [f; n] (base frame) the base support applies to hold the base: the base rows of M ẍ + b."""
        x_dot = np.concatenate([vdot, etaddot])
        return (self.mass_matrix(q)[:6] @ x_dot + self.bias_forces(q, v, etadot)[:6] - self.internal_forces(q, v, eta, etadot)[:6])

    def _forward_dynamics_base_modes(self, q, v, eta, etadot, tau):
        """Schur complement on the modal block: (H − BᵀB) v̇ = τ − h − g − Bᵀ r_η, η̈ = r_η − B v̇.
        Hot path of the simulator (4 calls per plant step): scalars are Python floats."""
        m, d = self.model, self.data
        H = pin.crba(m, d, q).copy()  # dposv reads the upper triangle only
        H[:6, :6] -= self._base_BtB
        rhs = tau - pin.nonLinearEffects(m, d, q, v)
        if self.springs:
            rhs[self._spring_v] -= self._spring_k * (q[self._spring_q] - self._spring_rest) + self._spring_c * v[self._spring_v]
        fx, fy, fz, nx, ny, nz = (self._base_Bt @ etadot).tolist()  # modal momentum as a base-frame wrench [f; n]
        vx, vy, vz, wx, wy, wz = v[:6].tolist()
        r_eta = self._neg_omega2 * eta + self._neg_2zo * etadot
        rhs[:6] -= self._base_Bt @ r_eta + np.array((
            wy * fz - wz * fy, wz * fx - wx * fz, wx * fy - wy * fx,  # v_b ×* P = [ω×f; v×f + ω×n]
            vy * fz - vz * fy + wy * nz - wz * ny,
            vz * fx - vx * fz + wz * nx - wx * nz,
            vx * fy - vy * fx + wx * ny - wy * nx))
        _, vdot, info = _dposv(H, rhs, lower=0, overwrite_a=1, overwrite_b=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"mass matrix with modes is not positive definite (LAPACK dposv info {info})")
        return vdot, r_eta - self._base_B @ vdot[:6]

    # ------------------------------------------------------------------ momentum and energy
    def momentum(self, q: np.ndarray, v: np.ndarray, etadot: np.ndarray | None = None,
                 about: str = "com") -> tuple[np.ndarray, np.ndarray]:
        """(linear momentum, angular momentum) in the world frame; angular about the system CoM
        (``about="com"``) or the world origin (``about="origin"``).

        Both are conserved without external forces when there are no modes. With modes, the
        exactly conserved pair is (p, k about a fixed world point): the hybrid model's rigid CoM
        does not move with the modal deformation, so k about it is conserved only when p = 0."""
        if about not in ("com", "origin"):
            raise ValueError(f"about must be 'com' or 'origin', not {about!r}")
        p, k_com, k_origin = self.momenta(q, v, etadot)
        return p, (k_com if about == "com" else k_origin)

    def momenta(self, q: np.ndarray, v: np.ndarray, etadot: np.ndarray | None = None):
        """(p, k about the CoM, k about the world origin), world frame, in one pass."""
        m, d = self.model, self.data
        hg = pin.computeCentroidalMomentum(m, d, q, v)
        c = d.com[0].copy()
        p, k = hg.linear.copy(), hg.angular + _cross(c, hg.linear)  # k about the world origin
        if self.appendages and etadot is not None:
            pin.framesForwardKinematics(m, d, q)
            for a in self.appendages:
                f_world = d.oMf[a.frame_id].act(pin.Force(a.L.T @ etadot[a.modes]))  # about the world origin
                p += f_world.linear
                k += f_world.angular
        return p, k - _cross(c, p), k

    def energy(self, q: np.ndarray, v: np.ndarray, eta: np.ndarray, etadot: np.ndarray) -> float:
        """Kinetic + elastic energy (J): ½xᵀMx + ½ηᵀΩ²η + springs."""
        if self.n_modes:
            x = np.concatenate([v, etadot])
            e = 0.5 * x @ self.mass_matrix(q) @ x
        else:
            e = 0.5 * v @ self.rigid_mass_matrix(q) @ v
        if self.n_modes:
            e += 0.5 * np.sum(self._omega**2 * eta**2)
        if self.springs:
            e += 0.5 * np.sum(self._spring_k * (q[self._spring_q] - self._spring_rest) ** 2)
        return float(e)

    # ------------------------------------------------------------------ seed-convention blocks
    def seed_velocity_map(self, q: np.ndarray) -> np.ndarray:
        """P (nx×nx) with x_pinocchio = P x_seed (base block T of conventions.seed_map, identity elsewhere)."""
        P = np.eye(self.nx)
        P[:6, :6] = seed_map(q)
        return P

    def blocks(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Named blocks of the mass matrix in the seed convention (base velocity [ω0 body; ṙ0 inertial])."""
        P = self.seed_velocity_map(q)
        Hs = P.T @ self.mass_matrix(q) @ P
        r, mm, e = self.idx.wheels, self.idx.arm, self.idx.modes
        w, lin = np.arange(0, 3), np.arange(3, 6)

        def blk(a, b):
            return Hs[np.ix_(a, b)]

        return {
            "H0": Hs[:6, :6], "H_omega": blk(w, w), "H_L": blk(lin, lin), "H_omegaL": blk(w, lin),
            "H_omega_r": blk(w, r), "H_omega_m": blk(w, mm), "H_L_r": blk(lin, r), "H_L_m": blk(lin, mm),
            "H_0r": blk(np.arange(6), r), "H_0m": blk(np.arange(6), mm),
            "H_r": blk(r, r), "H_m": blk(mm, mm), "H_rm": blk(r, mm),
            "H_0eta": blk(np.arange(6), e), "H_m_eta": blk(mm, e), "H_r_eta": blk(r, e), "H_eta": blk(e, e),
        }

    def generalized_jacobians(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Kraiem 2022 (3.5)–(3.8) at zero momentum: J_m0, J_r0 (→ [ω0 body; ṙ0 inertial]),
        J_mEE, J_rEE (→ end-effector twist [ω; v] in the inertial frame, v of the EE frame origin)."""
        B = self.blocks(q)
        H0 = B["H0"]
        J_m0 = -np.linalg.solve(H0, B["H_0m"])
        J_r0 = -np.linalg.solve(H0, B["H_0r"])
        m, d = self.model, self.data
        pin.computeJointJacobians(m, d, q)
        pin.updateFramePlacements(m, d)
        J = pin.getFrameJacobian(m, d, self.ee_frame_id, LWA)  # [v; ω] world-aligned
        J = np.vstack([J[3:6], J[0:3]])  # [ω; v]
        J_0EE = J[:, :6] @ seed_map(q)
        return {
            "J_m0": J_m0, "J_r0": J_r0,
            "J_mEE": J_0EE @ J_m0 + J[:, self.idx.arm],
            "J_rEE": J_0EE @ J_r0 + J[:, self.idx.wheels],
            "J_0EE": J_0EE,
        }
