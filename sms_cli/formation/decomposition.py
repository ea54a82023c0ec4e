"""Passive (locked/shape) decomposition of two or n free-flying spacecraft (Vicariotto 2023 §5.3–5.5).

Frames and units (SI; twists linear first ``[v; ω]``, wrenches ``[f; τ]``, Pinocchio order):

- Body 1 is the master. ``ξ_i`` (6) is the *locked* twist of spacecraft i in its base frame: the twist the
  whole spacecraft would have with its joints locked and the same momentum, ``ξ_i = M_i⁻¹ h_i``. ``M_i``
  (6×6, kg, kg m, kg m²) is its locked spatial inertia about its base-frame origin in base axes. For a
  rigid body ``ξ_i`` is its body twist.
- ``g12 = g1⁻¹ g2`` (SE3, frame 1 <- frame 2), ``Ad = Ad_{g12}`` and ``Ad⁻¹ = Ad_{g21}``.
- Locked system (frame 1): ``H = M1 ξ1 + Ad⁻ᵀ M2 ξ2`` (5.4), ``M_tot = M1 + Ad⁻ᵀ M2 Ad⁻¹``,
  ``V_L = M_tot⁻¹ H``. Shape system (frame 2): ``V_E = ξ2 − Ad⁻¹ ξ1``.
- ``[V_L; V_E] = S [ξ1; ξ2]`` with ``S = [[1 − A* Ad⁻¹, A*], [−Ad⁻¹, 1]]`` (5.6), ``A* = M_tot⁻¹ Ad⁻ᵀ M2`` (5.5);
  ``S⁻¹ = [[1, −A*], [Ad⁻¹, 1 − Ad⁻¹ A*]]``.
- Wrenches by power conjugacy: ``[F_L; F_E] = S⁻ᵀ [F1; F2]``, ``[F1; F2] = Sᵀ [F_L; F_E]``.
- ``M* = S⁻ᵀ diag(M1, M2) S⁻¹ = diag(M_L, M_E)`` with ``M_L = M_tot`` and
  ``M_E = (M2⁻¹ + Ad⁻¹ M1⁻¹ Ad⁻ᵀ)⁻¹`` (the thesis's L950 form with its operand order corrected).
- ``C* = S⁻ᵀ C12 S⁻¹ + S⁻ᵀ M12 d/dt(S⁻¹)`` (5.8), ``C12 = diag(C_1, C_2)`` skew-symmetric rigid-body
  Coriolis matrices, ``d/dt Ad⁻¹ = −ad_{V12} Ad⁻¹`` with ``V12`` the body twist of ``g12``.

The two-body formulas are computed by the compiled kernels of ``sms_cli.sim.compiled.pair_decomposition`` (their one
implementation); this module wraps them in ``PairDecomposition`` (numpy arrays) and keeps the n-body form.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import pinocchio as pin

from sms_cli.sim.compiled import pair_decomposition as _k
from sms_cli.sim.compiled import pair_law as _law

I6 = np.eye(6)
L_, E_ = slice(0, 6), slice(6, 12)


def _c(x) -> np.ndarray:
    """A float64 C-contiguous copy or view (the kernels' one signature)."""
    return np.ascontiguousarray(x, dtype=float)


def ad(xi: np.ndarray) -> np.ndarray:
    """Small adjoint ad_ξ (6×6) of a twist ξ = [v; ω]: [[ω×, v×], [0, ω×]] (Vicariotto 2023 (3.3)), Pinocchio's
    ``Motion.action`` (kernel ``pair_decomposition.ad_matrix``)."""
    out = np.empty((6, 6))
    _k.ad_matrix(_c(xi), out)
    return out


def rigid_coriolis(M: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Skew-symmetric Euler–Poincaré Coriolis matrix C(ξ) of a rigid body (6×6, body frame; kernel
    ``pair_decomposition.rigid_coriolis``).

    C = ½(M ad_ξ − ad_ξᵀ M) − ½ H̄(Mξ), H̄([f; n]) = [[0, [f]×], [[f]×, [n]×]]; then C ξ = −ad_ξᵀ M ξ
    (because H̄(h) ξ = ad_ξᵀ h and ad_ξ ξ = 0) and C + Cᵀ = 0, so M ξ̇ + C ξ = F is (3.6)."""
    return _k.rigid_coriolis(_c(M), _c(xi))


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


@dataclass(frozen=True)
class PairDecomposition:
    """Locked/shape decomposition of two spacecraft at one relative pose (see the module docstring).

    All matrices are numpy arrays: ``S`` and ``S_inv`` are 12×12 on ``[ξ1; ξ2]``; the others 6×6."""

    M1: np.ndarray
    M2: np.ndarray
    g12: pin.SE3
    Ad12_inv: np.ndarray   # Ad_{g12}⁻¹: twists of frame 1 -> frame 2
    M_tot: np.ndarray      # M1 + Ad⁻ᵀ M2 Ad⁻¹ (frame 1)
    A_star: np.ndarray     # M_tot⁻¹ Ad⁻ᵀ M2
    S: np.ndarray          # (5.6) on [ξ1; ξ2]
    S_inv: np.ndarray
    M_E: np.ndarray        # shape inertia (frame 2)

    @property
    def M_L(self) -> np.ndarray:
        """Locked inertia (frame 1) = M_tot."""
        return self.M_tot

    @property
    def M_star(self) -> np.ndarray:
        """diag(M_L, M_E) (12×12)."""
        out = np.zeros((12, 12))
        out[L_, L_] = self.M_tot
        out[E_, E_] = self.M_E
        return out

    # ------------------------------------------------------------------ velocities
    def locked_shape(self, xi1: np.ndarray, xi2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(V_L in frame 1, V_E in frame 2) of the locked twists ξ1 (frame 1) and ξ2 (frame 2)."""
        V = self.S @ np.concatenate([xi1, xi2])
        return V[L_], V[E_]

    def body_twists(self, V_L: np.ndarray, V_E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ξ1, ξ2), the inverse of ``locked_shape``."""
        xi = self.S_inv @ np.concatenate([V_L, V_E])
        return xi[L_], xi[E_]

    def momentum(self, xi1: np.ndarray, xi2: np.ndarray) -> np.ndarray:
        """Total momentum H = M1 ξ1 + Ad⁻ᵀ M2 ξ2 (6, [linear; angular about origin 1], frame-1 axes), (5.4)."""
        return self.M1 @ xi1 + self.Ad12_inv.T @ (self.M2 @ xi2)

    def energies(self, V_L: np.ndarray, V_E: np.ndarray) -> tuple[float, float]:
        """Kinetic energies (J) of the locked and shape systems, ½VᵀMV each."""
        return float(0.5 * V_L @ self.M_tot @ V_L), float(0.5 * V_E @ self.M_E @ V_E)

    # ------------------------------------------------------------------ wrenches
    def to_locked_shape(self, F1: np.ndarray, F2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(F_L, F_E) = S⁻ᵀ [F1; F2]: F_L = F1 + Ad⁻ᵀ F2 (total wrench, frame 1), F_E = F2 − A*ᵀ F_L (frame 2).
        F1 acts on body 1 in frame 1, F2 on body 2 in frame 2, each at its base-frame origin."""
        F_L, F_E = np.empty(6), np.empty(6)
        _law.to_locked_shape(self.Ad12_inv, self.A_star, _c(F1), _c(F2), F_L, F_E)
        return F_L, F_E

    def to_bodies(self, F_L: np.ndarray, F_E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(F1, F2) = Sᵀ [F_L; F_E], the inverse of ``to_locked_shape``."""
        F1, F2 = np.empty(6), np.empty(6)
        _law.to_bodies(self.S, _c(F_L), _c(F_E), F1, F2)
        return F1, F2

    def shape_effort(self, F_E: np.ndarray,
                     actuated: Literal["both", "master", "other"] = "both") -> tuple[np.ndarray, np.ndarray]:
        """A wrench pair (F1 frame 1, F2 frame 2) that realises the shape wrench F_E (frame 2).

        - ``"both"``: F_L = 0, internal and equal-and-opposite: F2 = F_E, F1 = −Ad⁻ᵀ F_E.
        - ``"master"``: F2 = 0, so F1 = F_L = −M_tot Ad M2⁻¹ F_E: the master's wrench also moves the locked
          system (total momentum changes by F1).
        - ``"other"``: F1 = 0, so F2 = (1 + M2 M̂1⁻¹) F_E with M̂1 = Adᵀ M1 Ad, and F_L = Ad⁻ᵀ F2.
        The implied locked wrench is ``to_locked_shape(F1, F2)[0]``."""
        modes = {"both": _law.BOTH, "master": _law.MASTER, "other": _law.OTHER}
        if actuated not in modes:
            raise ValueError(f"actuated must be 'both', 'master' or 'other', not {actuated!r}")
        F1, F2 = np.empty(6), np.empty(6)
        _law.shape_effort(self.Ad12_inv, self.A_star, _c(F_E), modes[actuated], F1, F2)
        return F1, F2

    # ------------------------------------------------------------------ rates
    def S_inv_rate(self, V12: np.ndarray, M1_dot: np.ndarray | None = None,
                   M2_dot: np.ndarray | None = None) -> np.ndarray:
        """d/dt S⁻¹ (12×12) given V12 (6, body twist of g12 in frame 2, = V_E for rigid bodies) and the
        rates of the locked inertias (zero for rigid bodies; non-zero when an arm moves). Closed form:
        d/dt Ad⁻¹ = −ad_{V12} Ad⁻¹; Ṁ_tot = Ṁ1 + Ad⁻ᵀ(Ṁ2 − ad_{V12}ᵀ M2 − M2 ad_{V12})Ad⁻¹ (L970);
        Ȧ* = M_tot⁻¹(Ad⁻ᵀ(Ṁ2 − ad_{V12}ᵀ M2) − Ṁ_tot A*) (L966)."""
        z = np.zeros((6, 6))
        return _k.s_inv_rate(self.M2, self.Ad12_inv, self.M_tot, self.A_star, _c(V12),
                             z if M1_dot is None else _c(M1_dot), z if M2_dot is None else _c(M2_dot))

    def S_rate(self, V12: np.ndarray, M1_dot: np.ndarray | None = None,
               M2_dot: np.ndarray | None = None) -> np.ndarray:
        """d/dt S (12×12) = −S (d/dt S⁻¹) S, arguments as ``S_inv_rate``."""
        return -self.S @ self.S_inv_rate(V12, M1_dot, M2_dot) @ self.S


def decompose(M1: np.ndarray, M2: np.ndarray, g12: pin.SE3) -> PairDecomposition:
    """Decomposition at relative pose g12 = g1⁻¹ g2 of two spacecraft with locked inertias M1 (frame 1), M2 (frame 2)
    (kernel ``pair_decomposition.pair_decompose``)."""
    M1, M2 = _c(M1), _c(M2)
    Ai, M_tot, A, S, S_inv, M_E = _k.pair_decompose(M1, M2, _c(g12.rotation), _c(g12.translation))
    return PairDecomposition(M1=M1, M2=M2, g12=g12.copy(), Ad12_inv=Ai, M_tot=M_tot, A_star=A, S=S, S_inv=S_inv, M_E=M_E)


def closed_form_M_E(M1: np.ndarray, M2: np.ndarray, g12: pin.SE3) -> np.ndarray:
    """Shape inertia M2 (M̂1 + M2)⁻¹ M̂1 with M̂1 = Adᵀ M1 Ad, Ad = Ad_{g12} (frame 2): Vicariotto 2023 L950 with
    the operand order corrected (the printed M̂_tot⁻¹(M̂1 M2) is not symmetric in general)."""
    Ad = g12.toActionMatrix()
    M1h = Ad.T @ M1 @ Ad
    return M2 @ np.linalg.solve(M1h + M2, M1h)


def coriolis(dec: PairDecomposition, xi1: np.ndarray, xi2: np.ndarray, V12: np.ndarray | None = None) -> np.ndarray:
    """C* (12×12) of (5.8) for two rigid bodies: S⁻ᵀ C12 S⁻¹ + S⁻ᵀ M12 d/dt(S⁻¹), C12 = diag(C(M1, ξ1), C(M2, ξ2))
    (``rigid_coriolis``). ``V12`` is the body twist of g12; default V_E = ξ2 − Ad⁻¹ ξ1 (exact for rigid bodies).
    Then M* d/dt[V_L; V_E] + C* [V_L; V_E] = [F_L; F_E] and d/dt M* − 2 C* is skew."""
    if V12 is None:
        V12 = xi2 - dec.Ad12_inv @ xi1
    return _k.pair_coriolis(dec.M1, dec.M2, dec.Ad12_inv, dec.M_tot, dec.A_star, dec.S_inv, _c(xi1), _c(xi2), _c(V12))


def warm_calls(rates: bool = False) -> list:
    """The kernel calls of ``decompose`` and ``TwoBodyPlant.locked_state`` (and of ``PairDecomposition.S_inv_rate`` when
    asked) on throw-away arrays of their argument types (``sms_cli.sim.compiled.warmup``)."""
    from sms_cli.sim.compiled.warmup import KernelCall

    mod = "sms_cli.sim.compiled.pair_decomposition"
    M, z = I6.copy(), np.zeros((6, 6))
    calls = [KernelCall(f"{mod}:pair_decompose", (M, M, np.eye(3), np.zeros(3)), cost=1.5),
             KernelCall(f"{mod}:locked_state", (np.eye(7), np.zeros(7), 0, 6, 1), cost=1.0)]
    if rates:
        calls.append(KernelCall(f"{mod}:s_inv_rate", (M, M, M, M, np.zeros(6), z, z), cost=1.0))
    return calls


def coriolis_blocks(C_star: np.ndarray) -> dict[str, np.ndarray]:
    """The four 6×6 blocks {"C_LL", "C_LE", "C_EL", "C_EE"} of a 12×12 C* (rows: equation, columns: velocity)."""
    return {"C_LL": C_star[L_, L_], "C_LE": C_star[L_, E_], "C_EL": C_star[E_, L_], "C_EE": C_star[E_, E_]}


# ---------------------------------------------------------------------- n bodies (§5.5, (5.13))
@dataclass(frozen=True)
class NBodyDecomposition:
    """Locked system (frame 1) and n−1 shape twists (V_E,i in frame i, i = 2..n) of n spacecraft (see ``M_star``).

    ``S`` (6n×6n, (5.13)) maps [ξ1; …; ξn] to [V_L; V_E,2; …; V_E,n]."""

    Ms: tuple
    Ad_inv: tuple          # Ad_{g1i}⁻¹ (i = 1..n; the first is the identity)
    M_tot: np.ndarray      # M1 + Σ Ad⁻ᵀ M_i Ad⁻¹ (frame 1)
    A_stars: tuple         # A_i* = M_tot⁻¹ Ad_{g1i}⁻ᵀ M_i (i = 2..n)
    S: np.ndarray
    S_inv: np.ndarray

    @property
    def n(self) -> int:
        return len(self.Ms)

    @property
    def M_star(self) -> np.ndarray:
        """S⁻ᵀ diag(M_i) S⁻¹ (6n×6n) = diag(M_tot, M_EE): the locked system is decoupled from the shapes, but
        for n ≥ 3 the shape block M_EE (6(n−1) square) is *not* block-diagonal: shapes relative to one master
        couple (three masses on a line: −m_i m_j / Σm between shapes i and j). (5.13) does not say otherwise,
        but "consistently with (5.8)" does not give n−1 independent shape systems."""
        n = self.n
        Mb = np.zeros((6 * n, 6 * n))
        for i, M in enumerate(self.Ms):
            Mb[6 * i:6 * i + 6, 6 * i:6 * i + 6] = M
        return self.S_inv.T @ Mb @ self.S_inv

    def locked_shape(self, xis) -> tuple[np.ndarray, list[np.ndarray]]:
        """(V_L frame 1, [V_E,i frame i for i = 2..n]) of the locked twists ξ_i (frame i)."""
        V = self.S @ np.concatenate(list(xis))
        return V[:6], [V[6 * i:6 * i + 6] for i in range(1, self.n)]

    def body_twists(self, V_L: np.ndarray, V_Es) -> list[np.ndarray]:
        """[ξ_1, …, ξ_n], the inverse of ``locked_shape``."""
        xi = self.S_inv @ np.concatenate([V_L, *V_Es])
        return [xi[6 * i:6 * i + 6] for i in range(self.n)]

    def momentum(self, xis) -> np.ndarray:
        """Total momentum Σ Ad_{g1i}⁻ᵀ M_i ξ_i (6, frame 1)."""
        return sum(Ai.T @ (M @ xi) for Ai, M, xi in zip(self.Ad_inv, self.Ms, xis))


def decompose_n(Ms, g1i) -> NBodyDecomposition:
    """Decomposition of n ≥ 2 spacecraft: locked inertias ``Ms`` (each in its own frame) and relative poses
    ``g1i`` (g1⁻¹ g_i, i = 2..n, n−1 entries; or n entries whose first is the identity)."""
    Ms = [np.asarray(M, dtype=float) for M in Ms]
    n = len(Ms)
    g1i = list(g1i)
    if len(g1i) == n - 1:
        g1i = [pin.SE3.Identity(), *g1i]
    if n < 2 or len(g1i) != n:
        raise ValueError(f"need n ≥ 2 inertias and n−1 relative poses, got {n} and {len(g1i)}")
    Ais = [g.toActionMatrixInverse() for g in g1i]
    M_tot = _sym(Ms[0] + sum(Ai.T @ M @ Ai for Ai, M in zip(Ais[1:], Ms[1:])))
    A_stars = [np.linalg.solve(M_tot, Ai.T @ M) for Ai, M in zip(Ais[1:], Ms[1:])]
    S = np.zeros((6 * n, 6 * n))
    S_inv = np.zeros((6 * n, 6 * n))
    S[:6, :6] = I6 - sum(A @ Ai for A, Ai in zip(A_stars, Ais[1:]))
    S_inv[:6, :6] = I6
    for i in range(1, n):
        b = slice(6 * i, 6 * i + 6)
        A, Ai = A_stars[i - 1], Ais[i]
        S[:6, b] = A
        S[b, :6] = -Ai
        S[b, b] = I6
        # ξ1 = V_L − Σ_j A_j* V_E,j ; ξ_i = V_E,i + Ad⁻¹ ξ1
        S_inv[:6, b] = -A
        S_inv[b, :6] = Ai
        for j in range(1, n):
            bj = slice(6 * j, 6 * j + 6)
            S_inv[b, bj] = (I6 if i == j else 0.0) - Ai @ A_stars[j - 1]
    return NBodyDecomposition(Ms=tuple(Ms), Ad_inv=tuple(Ais), M_tot=M_tot, A_stars=tuple(A_stars), S=S, S_inv=S_inv)
