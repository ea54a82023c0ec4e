"""Momentum-based (locked/shape) quantities of a floating base with reaction wheels (Vicariotto 2023, ch. 4,
(4.2)-(4.8)), from the blocks of the mass matrix, for any wheel axes.

Velocities are ``x = [v, ω, ṡ]`` in the order of ``SystemModel.mass_matrix`` (``nx``): ``v`` (m/s) the base
frame origin's velocity and ``ω`` (rad/s) the base angular rate, both in the base frame (Pinocchio's
free-flyer, linear first), then the shape rates ``ṡ`` = every other coordinate in mass-matrix order: the wheel
rates ``θ̇`` (rad/s), the arm and passive joint rates, and the modal rates ``η̇``. ``M`` is the (augmented)
mass matrix at q (kg, kg m, kg m²).

Definitions (base frame, SI):

- **Locked inertia** ``I`` (kg m²): the angular block of ``M`` with the base translation reduced out,
  ``I = M_ωω − M_ωv M_vv⁻¹ M_vω``. It is the inertia of the whole system frozen in its current shape
  (wheels, arm and appendages locked) about the system CoM, in base axes; ``I⁻¹ = (M_bb⁻¹)_ωω``. Why
  reduced: the thesis puts the base frame at the CoM (M = diag(m, I, …), so M_vω = 0); Pinocchio's base
  frame is the base link origin, generally off the CoM, where ``M_ωω`` is the inertia about that origin
  (parallel-axis terms included). A free system rotates about its CoM, so only the reduced block gives a
  locked velocity proportional to the angular momentum and a block-diagonal locked/shape form. With the
  base origin at the CoM the two coincide and ``I = I_s + G J Gᵀ`` (thesis (4.2)).
- **Wheel axes and inertias as the mass matrix holds them**: ``J_i = M_θθ,ii`` (axial inertia, kg m²) and
  ``G J = M_ωθ − M_ωv M_vv⁻¹ M_vθ`` (3×n, the translation-reduced coupling), so column i of ``G`` is
  wheel i's spin axis in the base frame (unit for a rotor balanced about its axis, whose axis is a
  principal axis; the thesis's A, (3.17)).
- **Connection** ``Λ = I⁻¹ G J`` (3×n_w, dimensionless; thesis (4.5) has A = I); over all shape coordinates
  ``Λ_s = I⁻¹ (M_ωs − M_ωv M_vv⁻¹ M_vs)`` (3×n_s), of which Λ is the wheel columns.
- **Locked velocity** ``μ = ω + Λ_s ṡ`` (rad/s, base frame) = ``I⁻¹ H_c`` with ``H_c`` the angular momentum
  about the CoM in base axes (modal momentum included). With arms or modes μ is the rate at which the
  system would rotate if its shape froze; with wheels only it is the thesis's ω + Λθ̇. μ is **not**
  conserved when the base rotates: the conserved form is ``R I μ`` (world angular momentum about the
  CoM; about the rigid CoM of the hybrid model when modes carry linear momentum, see
  ``SystemModel.momentum``).
- **Shape inertia** ``M_θ = M_ss − M_sb M_bb⁻¹ M_bs`` (n_s×n_s, the Schur complement of the base block);
  its wheel block is ``J − J Gᵀ I⁻¹ G J`` when the wheels ride on the base (thesis A^T I_w (A − Λ)).
- **Transformation** ``ζ = T x`` with ``ζ = [v_c, μ, ṡ]``, ``T = [[1, M_vv⁻¹M_vω, M_vv⁻¹M_vs], [0, 1, Λ_s],
  [0, 0, 1]]``: ``v_c`` is the CoM velocity in base axes (``= v`` when the base origin is at the CoM and no
  shape motion moves the CoM, the thesis's T of L680). Then ``T⁻ᵀ M T⁻¹ = diag(M_l, M_r, M_θ)`` with
  ``M_l = M_vv = m 1`` and ``M_r = I`` (thesis (4.8)), and ½ xᵀMx = ½ ζᵀ diag(…) ζ.

Arms and modes are held as further shape coordinates (not locked, not refused): every formula above is
exact for them; ``Lambda``, ``G``, ``J`` and ``M_theta_wheels`` are the wheel parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LIN, ANG = slice(0, 3), slice(3, 6)


@dataclass(frozen=True)
class LockedShape:
    """Locked/shape quantities at one configuration (see the module docstring for definitions)."""

    mass: float              # kg, M_vv = mass · 1
    com_base: np.ndarray     # (3,) m: system CoM relative to the base origin, base frame (M_vv⁻¹ M_vω = −[c]×)
    I: np.ndarray            # (3, 3) kg m²: locked inertia about the CoM, base axes
    G: np.ndarray            # (3, n_w): wheel spin axes, base frame
    J: np.ndarray            # (n_w,) kg m²: wheel axial inertias
    Lambda: np.ndarray       # (3, n_w): I⁻¹ G J
    Lambda_shape: np.ndarray  # (3, n_s): I⁻¹ × reduced coupling of every shape coordinate
    M_theta: np.ndarray      # (n_s, n_s): Schur complement of the base block
    T: np.ndarray            # (nx, nx): ζ = T x
    wheel_cols: np.ndarray   # positions of the wheels among the shape coordinates

    @property
    def M_theta_wheels(self) -> np.ndarray:
        """Wheel block of M_θ (n_w × n_w): J − J Gᵀ I⁻¹ G J for wheels on the base."""
        return self.M_theta[np.ix_(self.wheel_cols, self.wheel_cols)]

    def locked_velocity(self, x: np.ndarray) -> np.ndarray:
        """μ = ω + Λ_s ṡ (rad/s, base frame) of the velocity x (nx) at this configuration."""
        x = np.asarray(x, float)
        return x[ANG] + self.Lambda_shape @ x[6:]

    def block_diagonal(self) -> np.ndarray:
        """diag(M_l, M_r, M_θ) (nx × nx) = T⁻ᵀ M T⁻¹."""
        n = self.T.shape[0]
        D = np.zeros((n, n))
        D[LIN, LIN] = self.mass * np.eye(3)
        D[ANG, ANG] = self.I
        D[6:, 6:] = self.M_theta
        return D


def _translation_reduced(M: np.ndarray, cols) -> tuple[np.ndarray, np.ndarray]:
    """(M_vv⁻¹ M_v,cols, M_ω,cols − M_ωv M_vv⁻¹ M_v,cols): the base translation reduced out of the angular rows."""
    A = np.linalg.solve(M[LIN, LIN], M[LIN, cols])
    return A, M[ANG, cols] - M[ANG, LIN] @ A


def reduced_coupling(M: np.ndarray, cols) -> np.ndarray:
    """Angular momentum about the CoM (base axes) per unit rate of the coordinates ``cols``, translation
    reduced out (3 × len(cols)): G J for the wheel columns (also used by ``sms_cli.sim.authority``)."""
    return _translation_reduced(M, cols)[1]


def _reduce(M: np.ndarray):
    """(M_vv⁻¹ [M_vω, M_vs], I, Λ_s): the translation reduced out of the base rows, then the rotation."""
    A, red = _translation_reduced(M, np.arange(3, M.shape[0]))  # 3 × (3 + n_s): [I, reduced coupling]
    I = 0.5 * (red[:, :3] + red[:, :3].T)
    return A, I, np.linalg.solve(I, red[:, 3:])


def locked_shape(sm, q: np.ndarray, M: np.ndarray | None = None) -> LockedShape:
    """The locked/shape quantities of ``sm`` at configuration q (``M``: its mass_matrix(q) if the caller has it)."""
    M = sm.mass_matrix(q) if M is None else np.asarray(M, float)
    A, I, Lam_s = _reduce(M)
    C_s = I @ Lam_s
    M_theta = M[6:, 6:] - M[LIN, 6:].T @ A[:, 3:] - C_s.T @ Lam_s
    M_theta = 0.5 * (M_theta + M_theta.T)
    wcols = np.asarray(sm.idx.wheels, dtype=int) - 6
    J = np.diag(M)[6:][wcols].copy()
    GJ = C_s[:, wcols]
    T = np.eye(M.shape[0])
    T[LIN, 3:] = A
    T[ANG, 6:] = Lam_s
    mass = float(M[0, 0])
    cx = A[:, :3]  # M_vv⁻¹ M_vω = −[c]×: v_c = v + ω × c is the CoM velocity
    com = -np.array([cx[2, 1], cx[0, 2], cx[1, 0]])
    return LockedShape(mass=mass, com_base=com, I=I, G=GJ / J if J.size else GJ, J=J, Lambda=Lam_s[:, wcols],
                       Lambda_shape=Lam_s, M_theta=M_theta, T=T, wheel_cols=wcols)


def locked_velocity(sm, q: np.ndarray, v: np.ndarray, etadot: np.ndarray | None = None,
                    M: np.ndarray | None = None) -> np.ndarray:
    """μ (3,) rad/s, base frame, at (q, v, η̇) of the current model (payloads as attached now)."""
    x = v if not sm.n_modes else np.concatenate([v, np.zeros(sm.n_modes) if etadot is None else etadot])
    M = (sm.mass_matrix(q) if sm.n_modes else sm.rigid_mass_matrix(q)) if M is None else M
    _, _, Lam_s = _reduce(M)
    return x[ANG] + Lam_s @ x[6:]


def shape_invariant(sm) -> bool:
    """True when the rigid mass matrix does not depend on q: no modes, and every joint but the base is a
    leaf revolute joint on the base whose body is balanced and symmetric about the joint axis (a rotor)."""
    if sm.n_modes:
        return False
    m = sm.model
    b = sm.base_joint_id
    for j in range(1, m.njoints):
        if j == b:
            continue
        if m.parents[j] != b or any(m.parents[k] == j for k in range(1, m.njoints)):
            return False
        short = m.joints[j].shortname()
        if short in ("JointModelRX", "JointModelRY", "JointModelRZ"):
            axis = np.eye(3)["XYZ".index(short[-1])]
        elif short == "JointModelRevoluteUnaligned":
            axis = np.asarray(m.joints[j].extract().axis, float)
        else:
            return False
        Y = m.inertias[j]
        scale = max(float(np.abs(Y.inertia).max()), 1e-300)
        if Y.mass > 0 and np.linalg.norm(np.cross(Y.lever, axis)) > 1e-12 * max(1.0, np.linalg.norm(Y.lever)):
            return False
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        if np.abs(K @ Y.inertia - Y.inertia @ K).max() > 1e-12 * scale:
            return False
    return True


def locked_velocities(sm, qs: np.ndarray, vs: np.ndarray) -> np.ndarray:
    """μ (n, 3) for stacks of rigid states (n, nq), (n, nv) (no modal rates: the compiled loop's samples).
    One mass matrix for the whole stack when it does not depend on q (``shape_invariant``), else one per sample."""
    vs = np.asarray(vs, float)
    n = vs.shape[0]
    if n == 0:
        return np.zeros((0, 3))
    if shape_invariant(sm):
        _, _, Lam_s = _reduce(sm.rigid_mass_matrix(qs[0]))
        return vs[:, ANG] + vs[:, 6:] @ Lam_s.T
    return np.array([locked_velocity(sm, qs[i], vs[i]) for i in range(n)])


def locked_summary(sm) -> dict | None:
    """``sms compile``'s figures at q0 (None without wheels or on a kinematics-only model): the locked inertia
    about the CoM in base axes (kg m²) and its principal values, Λ = I⁻¹GJ and its largest singular value |Λ|."""
    if not sm.wheels or sm.kinematics_only:
        return None
    ls = locked_shape(sm, sm.q0)
    return {"inertia_base_kgm2": ls.I, "principal_inertia_kgm2": np.linalg.eigvalsh(ls.I),
            "coupling": ls.Lambda, "coupling_norm": float(np.linalg.norm(ls.Lambda, 2))}


def format_locked(s: dict | None) -> list[str]:
    """The summary line of ``locked_summary``."""
    if not s:
        return []
    p = " / ".join(f"{x:.5g}" for x in s["principal_inertia_kgm2"])
    return [f"locked    inertia about the CoM, shape locked: principal {p} kg m^2; |Λ| = |I⁻¹GJ| = {s['coupling_norm']:.3e}"
            " (Vicariotto 2023 (4.5))"]
