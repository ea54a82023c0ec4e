"""The model quantities the control laws need, from a constant rigid body or from the SystemModel.

Attitude laws see the base as a rigid body of inertia J (kg m², base frame, about the system CoM)
carrying internal angular momentum h (N m s, base frame: wheels, moving arm):

    d/dt(J ω) = τ − ω × (J ω + h) − ḣ_arm          (base frame; τ = torque the actuators put on the base)

``SystemBody`` takes J as the locked inertia of the whole system with the base translation free
(CoM-centred) and the wheels free to spin: J = Schur complement of the rigid mass matrix H on the
base angular block after eliminating the base linear and wheel coordinates (arm and springs held).
For a hub with wheels this is Basilisk's [I_RW] = hub inertia + wheel transverse inertia, and
h = Rᵀ k_G − J ω then contains Σ a_i J_s,i (a_iᵀ ω + Ω_i) plus the arm's relative momentum.

Arm laws see the manipulator joint-space dynamics M*(q) q̈_m + h*(q, v) = τ_m, where the other
coordinates are either held (q̈ = 0) or free (zero generalized force): ``ArmDynamics``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from sms_cli.sim.interfaces import Sensed


def base_rotation(quat_xyzw: np.ndarray) -> np.ndarray:
    """World ← base rotation matrix of a unit quaternion [x, y, z, w]."""
    x, y, z, w = quat_xyzw
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _schur(M: np.ndarray, keep: np.ndarray, elim: np.ndarray) -> np.ndarray:
    """M_kk − M_ke M_ee⁻¹ M_ek."""
    Mkk = M[np.ix_(keep, keep)]
    if elim.size == 0:
        return Mkk
    Mke = M[np.ix_(keep, elim)]
    return Mkk - Mke @ np.linalg.solve(M[np.ix_(elim, elim)], Mke.T)


def effective_inertia(sm, q: np.ndarray) -> np.ndarray:
    """Locked attitude inertia (3×3, kg m², base frame, about the system CoM), wheels free to spin."""
    M = sm.rigid_mass_matrix(q)
    elim = np.concatenate([sm.idx.base_linear, sm.idx.wheels]).astype(int)
    J = _schur(M, sm.idx.base_angular.astype(int), elim)
    return 0.5 * (J + J.T)


class RigidBody:
    """Constant inertia J (3×3) and optional wheels (axes G as columns, spin inertias Js)."""

    def __init__(self, inertia, wheel_axes=None, wheel_spin=None):
        J = np.asarray(inertia, dtype=float)
        self.J = np.diag(J) if J.ndim == 1 else J
        self.G = np.zeros((3, 0)) if wheel_axes is None else np.ascontiguousarray(np.reshape(wheel_axes, (3, -1)), dtype=float)
        self.Js = np.zeros(self.G.shape[1]) if wheel_spin is None else np.ascontiguousarray(wheel_spin, dtype=float)

    def inertia(self, s: Sensed) -> np.ndarray:
        return self.J

    def inertia_rate(self, s: Sensed) -> np.ndarray:
        return np.zeros((3, 3))

    def internal_momentum(self, s: Sensed) -> np.ndarray:
        """Σ ĝ_i J_s,i (ĝ_iᵀ ω + Ω_i): wheel momentum, base frame (N m s); the compiled loop's kernel
        (``sms_cli.sim.compiled.attitude_laws.wheel_momentum``)."""
        from sms_cli.sim.compiled.attitude_laws import wheel_momentum

        out = np.zeros(3)
        if self.Js.size:
            wheel_momentum(self.G, self.Js, np.ascontiguousarray(s.omega, dtype=float),
                           np.ascontiguousarray(s.wheel_speed, dtype=float), out)
        return out


class SystemBody:
    """J(q), J̇ and h from the SystemModel at the sensed state (``online``) or J frozen at q0."""

    def __init__(self, sm, online: bool = True, fd_step: float = 1e-6):
        self.sm = sm
        self.online = online
        self.h = fd_step
        self._J0 = effective_inertia(sm, sm.q0)
        self._key = None
        self._J = self._J0

    def _update(self, s: Sensed) -> None:
        key = (s.t, s.q.tobytes())
        if key != self._key:
            self._key = key
            self._J = effective_inertia(self.sm, s.q) if self.online else self._J0

    @property
    def initial_inertia(self) -> np.ndarray:
        """J at the initial configuration q0 (the ``initial`` inertia)."""
        return self._J0

    def inertia(self, s: Sensed) -> np.ndarray:
        self._update(s)
        return self._J

    def inertia_rate(self, s: Sensed) -> np.ndarray:
        """dJ/dt along the sensed motion (central difference of J(q ⊕ ±h v)); zero when frozen."""
        if not self.online:
            return np.zeros((3, 3))
        m = self.sm.model
        qp = pin.integrate(m, s.q, self.h * s.v)
        qm = pin.integrate(m, s.q, -self.h * s.v)
        return (effective_inertia(self.sm, qp) - effective_inertia(self.sm, qm)) / (2.0 * self.h)

    def internal_momentum(self, s: Sensed) -> np.ndarray:
        """h = Rᵀ k_G − J ω (base frame, N m s): wheels and arm motion relative to the locked body; k_G
        by Pinocchio, the rest by the compiled loop's kernel (``attitude_laws.system_momentum``)."""
        from sms_cli.sim.compiled.attitude_laws import system_momentum

        hg = pin.computeCentroidalMomentum(self.sm.model, self.sm.data, s.q, s.v)
        out = np.empty(3)
        system_momentum(np.ascontiguousarray(s.q[3:7], dtype=float), np.ascontiguousarray(hg.angular, dtype=float),
                        np.ascontiguousarray(self.inertia(s), dtype=float), np.ascontiguousarray(s.omega, dtype=float), out)
        return out


ARM_MODELS = ("free_floating", "attitude_held", "fixed_base")


class ArmDynamics:
    """Joint-space dynamics of the arm, M* q̈_m + h* = τ_m, under one assumption about the rest:

    - ``fixed_base``: every other coordinate held (q̈ = 0): the joint rows of H and h (rigid part);
    - ``attitude_held``: base rotation and wheels held, base translation, springs and modes free;
    - ``free_floating``: base, wheels, springs and modes free (no force on them): exact for a
      free-floating plant with idle wheels (M* = generalized inertia of the arm).
    Free modal coordinates use the sensed η, η̇ (zeros unless an observer provides them).
    """

    def __init__(self, sm, model: str = "free_floating"):
        if model not in ARM_MODELS:
            raise ValueError(f"arm model must be one of {ARM_MODELS}, not {model!r}")
        self.sm = sm
        self.model = model
        a = sm.idx.arm.astype(int)
        self.a = a
        if model == "fixed_base":
            self.p = np.zeros(0, dtype=int)
        else:
            others = np.setdiff1d(np.arange(sm.nx), a)
            held = np.zeros(0, dtype=int)
            if model == "attitude_held":
                held = np.concatenate([sm.idx.base_angular, sm.idx.wheels]).astype(int)
            self.p = np.setdiff1d(others, held)

    def terms(self, s: Sensed) -> tuple[np.ndarray, np.ndarray]:
        """(M* (n_m×n_m), h* (n_m)) at the sensed state: Pinocchio's mass matrix and bias forces reduced by
        the kernel the compiled loop uses too (``sms_cli.sim.compiled.arm_laws.arm_model_terms``)."""
        sm = self.sm
        if self.model == "fixed_base":
            M = sm.rigid_mass_matrix(s.q)
            n = pin.nonLinearEffects(sm.model, sm.data, s.q, s.v)
            if sm.springs:
                n = n - sm.internal_forces(s.q, s.v, np.zeros(sm.n_modes), np.zeros(sm.n_modes))[: sm.nv]
        else:
            eta = s.eta if s.eta.size == sm.n_modes else np.zeros(sm.n_modes)
            etadot = s.etadot if s.etadot.size == sm.n_modes else np.zeros(sm.n_modes)
            M = sm.mass_matrix(s.q)
            n = sm.bias_forces(s.q, s.v, etadot) - sm.internal_forces(s.q, s.v, eta, etadot)
        return self.reduce(M, n)

    @property
    def indices(self) -> tuple[np.ndarray, np.ndarray]:
        """(arm coordinates a, free coordinates p) as the kernel takes them (int64)."""
        return np.ascontiguousarray(self.a, dtype=np.int64), np.ascontiguousarray(self.p, dtype=np.int64)

    def reduce(self, M: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(M*, h*) from the full mass matrix M and bias n (``arm_model_terms``)."""
        from sms_cli.sim.compiled.arm_laws import arm_model_terms

        a, p = self.indices
        Ms, hs = np.empty((a.size, a.size)), np.empty(a.size)
        arm_model_terms(np.ascontiguousarray(M, dtype=float), np.ascontiguousarray(n, dtype=float), a, p, Ms, hs)
        return Ms, hs

    def warm_call(self):
        """``reduce``'s kernel call on throw-away data (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        a, p = self.indices
        nx = self.sm.nx
        return KernelCall("sms_cli.sim.compiled.arm_laws:arm_model_terms",
                          (np.eye(nx), np.zeros(nx), a, p, np.empty((a.size, a.size)), np.empty(a.size)), cost=0.5)
