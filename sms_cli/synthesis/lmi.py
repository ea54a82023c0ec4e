"""Simultaneous controller + observer gain synthesis by LMIs (Kraiem 2022 §3.3.3 and §4.2.5).

Plant of the synthesis (one *linearisation* = one ``ErrorModel``): the NDI error dynamics
(Kraiem 2022 (3.41))::

    ż   = (A_z + B_z K) z + [0; B_ε] ε_e        z = [ε_c; ε̇_c] (actuator units: rad, m)
    ε̇_e = (A_e − L C_e) ε_e                     ε_e: observer error (units of the model)
    ε_c = C_z z,   A_z = [[0, I], [0, 0]],  B_z = [0; −I],  C_z = [I 0]

and, for the chapter 4 variant, the disturbance-observer error ε_d (N m, per actuator)::

    ε̇_d = −L_d ε_d + L_d D◇_x ε_e,   L_d = Q_d M◇⁻¹,   ż gets + [0; −M◇⁻¹] ε_d

Both propositions are plain SDPs (Kraiem 2022 reading notes §5.3). What is added to the thesis, and why:

* **Structure.** Q_z = [[Q11, Q12], [Q12, Q22]] with Q11, Q12, Q22 diagonal (per-actuator 2×2
  blocks) and W_z = [W_p, W_v] diagonal. K = W_z Q_z⁻¹ is then [K_p, K_v] with K_p, K_v
  diagonal. A literally diagonal Q_z is infeasible (its (1,1) block of (A_zQ_z + B_zW_z)^s is
  Q12 + Q12ᵀ = 0), which is why Kraiem 2022's "Q_z diagonal" cannot be meant literally.
* **Pole regions** (Chilali–Gahinet, on the same Q_z and P_ε as the γ-LMI) replace the
  trial-and-error bounds of the thesis; minimising γ without them drives K to ~1e7.
* **Actuator authority.** With V(0) ≤ 1 the state stays in zᵀQ_z⁻¹z ≤ 1, so the feedback
  acceleration |v_i| = |K_i z| ≤ a_i holds if [[a_i², W_i], [W_iᵀ, Q_i]] ⪰ 0 (Boyd et al. 1994,
  §7.2.3). a_i = τ_max,i / max M◇_ii. With optional initial tracking errors (z(0) ≠ 0 in a box
  per actuator) a decay rate beyond the authority makes the problem infeasible, and the
  diagnosis names the groups in conflict.
* **Initial conditions.** The thesis bound ∫ε_cᵀε_c < γ²V(0) is turned into ∫ε_cᵀε_c < γ² for
  every initial error in S = (box of tracking errors) × {ε_eᵀE_eε_e ≤ 1} (× {ε_dᵀE_dε_d ≤ 1}):
  V(0) ≤ 1 on S through a budget c_e + Σc_i (+ c_d) ≤ 1 with P_ε ⪯ c_e E_e (the thesis's
  P_ε < E when there is no tracking error) and each box corner v inside vᵀQ_i⁻¹v ≤ c_i.
  E_e is built from per-state bounds (``ellipsoid_from_box``); Kraiem 2022 never gives E.
  Chapter 4's condition P_dᵀM◇P_d ⪯ E_d is non-convex in Q_d = P_d⁻¹; it is replaced by the
  convex sufficient condition 2Q_d − E_d⁻¹ ⪰ M◇(q_j) at every linearisation j, from
  (Q_d − E_d⁻¹)E_d(Q_d − E_d⁻¹) ⪰ 0 ⇒ Q_d E_d Q_d ⪰ 2Q_d − E_d⁻¹ (with c_d = 1/2 fixed).
  The NDO poles eig(Q_d M◇⁻¹) (real, positive) are kept in [α, r] of the observer region
  by α M◇ ⪯ Q_d ⪯ r M◇; without this bound γ-minimisation makes the NDO arbitrarily fast.
* **Robustness (ρ).** The thesis (3.51)–(3.52) adds ρ I to diagonal blocks, omits the P_ε
  factor of P_εΔA_e and is scale dependent. ``relaxation="scaled"`` uses Petersen's lemma
  with multipliers λ, δ > 0 (decision variables) on the *structured* variation
  ΔA_e = GΔ_AN, ΔB_ε = D_gΔ_B (``_Uncertainty``; D_g = diag(g_B) per actuator)::

      (E₁D_gΔ_BE₂ᵀ)^s ⪯ λρ₂²E₁D_g²E₁ᵀ + λ⁻¹E₂E₂ᵀ,   (E₂PGΔ_ANE₂ᵀ)^s ⪯ δ⁻¹E₂PGGᵀPE₂ᵀ + δρ₁²E₂NᵀNE₂ᵀ

  for every σ̄(Δ_B) ≤ ρ₂, σ̄(Δ_A) ≤ ρ₁, giving one LMI with two extra blocks (Schur). G selects
  the acceleration rows of A_e and N = A_e[rows] (nominal): at rest ΔA_e = −Δ(M*⁻¹)S with the
  constant stiffness/damping map S, so ρ₁ is the relative change of the inverse inertia
  (dimensionless, independent of the state units). Why not the unstructured ΔA_e of norm ρ₁
  (a first version): its δ-block alone, [[(PA_e − W_eC_e)^s + ρ₁²I,
  P], [P, −I]] ≺ 0, is a necessary condition whose largest ρ₁ over all (P, W_e) (the quadratic
  stability radius of the best observer) is 0.0022 on the test case of
  ``test_several_linearisations_and_sampled_relaxation`` while its samples give ρ₁ = 0.014:
  no observer gain tolerates every unstructured ΔA_e of that size, most of which no
  configuration change produces (changes of the kinematic rows, or the same absolute change on
  a small coupling entry as on a stiffness entry; restricting ΔA_e to the varying rows and
  columns still gives only 0.0024). The relative form gives ρ₁ = 0.0033 there, radius 0.006.
  Both ρ forms keep the exact per-actuator split of ``_build_structured`` (chapter 3).
  ``relaxation="thesis"`` reproduces (3.52) (ρ₁ = 2 max σ̄(ΔA_e), ρ₂ = max σ̄(ΔB_ε), unstructured).
  It is not a sufficient condition (P_εΔA_e has become ΔA_e) and is scale dependent: with
  P_ε ⪯ E_e its observer block (P_εA_e − W_eC_e)^s + (ρ₁ + ρ₂)I ≺ 0 is feasible only for
  ρ₁ + ρ₂ ≤ 0.0101 on that test case (samples: 0.062), so it needs samples about ten times
  closer. ρ is measured in the scaled coordinates, between each sampled linearisation and the
  nominal one it is nearest to. Either way the
  guarantee at the samples is checked afterwards (``verify``: poles and the certificate of the
  returned P at every sample).
* **Scaling.** Time is scaled by ω_c (the controller disk radius) and the observer state by
  its initial-error bounds (x̃_i = x_i/b_i), so inertias from 1e-4 to 1e4 kg m²
  give O(1) data; actuator coordinates are scaled per actuator (unit-norm rows of B_ε, the
  weight moved into C_z, so the per-actuator structure and γ are unchanged). All outputs are
  mapped back: K_p = ω_c² K̃_p, K_v = ω_c K̃_v, L = ω_c T L̃, γ² = c_s²γ̃²/ω_c, P_ε = T⁻¹P̃T⁻¹.
* **Solver.** The structured chapter 3 problem (relaxation 'none' or 'polytopic', or no samples) is built as
  numpy blocks (``direct.py``, identical to the cvxpy constraints of ``_build_structured``) and
  solved by the dedicated interior-point method of ``sdp.py`` (Schur complement of the ~450
  variables instead of Clarabel's KKT system with dense n(n+1)/2 blocks per cone: pulsar_simple
  2.3 s instead of 17–29 s). Its point is accepted only if every block is ⪰ 0 at it (each block
  carries the EPS margin); otherwise, and for every other problem (the ρ forms, chapter 4), cvxpy +
  Clarabel (``_build_structured`` for chapter 3, ``_build`` for chapter 4).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from sms_cli.errors import NumericalError, Problem
from sms_cli.synthesis.regions import PoleRegion, damping_ratios, region_lmis, unobservable_eigenvalues

EPS = 1e-5  # strictness margin of the LMIs, in scaled units
Q_MAX = 1e6  # conditioning cap on each scaled Q_i (an actuator whose error barely enters γ)
C_D = 0.5  # share of V(0) given to the NDO initial error (chapter 4)
IPM_TOL = 1e-6  # relative gap and residuals of the dedicated solver (Clarabel's tolerances below)
# The largest LMI (rows of the full form Θ) handed to Clarabel when the dedicated solver fails. Measured on the 2-core,
# 24 GiB machine: at 111 rows Clarabel had not finished in 10 minutes (issue #16), and the full PULSAR's chapter 4
# problem (103 rows, 1460 variables) had grown past 13 GB of memory after 26 minutes without an answer.
CLARABEL_MAX_ROWS = 99


@dataclass
class ErrorModel:
    """One linearisation of the NDI + observer error dynamics.

    A_e (n_e×n_e), C_e (n_y×n_e), B_eps = M◇⁻¹D◇_x (n_q×n_e, rad/s² per unit of ε_e).
    Chapter 4 only: M (M◇, n_q×n_q, kg m² or kg), D_x (D◇_x, n_q×n_e, N m per unit of ε_e),
    D_sym (D◇ + D◇ᵀ, n_q×n_q; zero at rest).
    """

    A_e: np.ndarray
    C_e: np.ndarray
    B_eps: np.ndarray
    M: np.ndarray | None = None
    D_x: np.ndarray | None = None
    D_sym: np.ndarray | None = None
    label: str = ""

    @property
    def n_q(self) -> int:
        return self.B_eps.shape[0]

    @property
    def n_e(self) -> int:
        return self.A_e.shape[0]

    @property
    def n_y(self) -> int:
        return self.C_e.shape[0]


@dataclass
class SynthesisRequest:
    """What to synthesise. Bounds are in SI (rad/s, rad/s², N m); see ``ErrorModel``.

    accel_limit: per-actuator bound a_i on the feedback acceleration K_i z (rad/s² or m/s²),
      None = no authority constraint; inf entries = no constraint on that actuator.
    The γ guarantee covers every initial error in S = B_z × {ε_eᵀE_eε_e ≤ 1} × {ε_dᵀE_dε_d ≤ 1}:
    tracking: (n_q, 2) bounds (|ε_c,i(0)|, |ε̇_c,i(0)|) of the box B_z (None: z(0) = 0, as
      in Kraiem 2022); E_e: observer initial-error ellipsoid (n_e×n_e); E_d: NDO initial-error
      ellipsoid (n_q×n_q, chapter 4 only).
    """

    nominal: list[ErrorModel]
    controller_region: PoleRegion
    observer_region: PoleRegion
    E_e: np.ndarray
    samples: list[ErrorModel] = field(default_factory=list)
    relaxation: str = "scaled"  # 'polytopic' | 'scaled' | 'thesis' | 'none'
    accel_limit: np.ndarray | None = None
    tracking: np.ndarray | None = None
    E_d: np.ndarray | None = None
    variant: str = "ndi_observer"  # or 'ndi_observer_ndo'

    def linearisations(self) -> list[ErrorModel]:
        """The models that carry the full LMI set: the nominal ones, plus the samples when the
        robustness is polytopic (every sample is a vertex sharing the same variables)."""
        return list(self.nominal) + (list(self.samples) if self.relaxation == "polytopic" else [])


@dataclass
class LmiResult:
    """Gains and certificate. K_p, K_v (n_q, 1/s² and 1/s), L (n_e×n_y), gamma (∫ε_cᵀε_c < γ²
    for initial errors in the ellipsoid), Q_d (chapter 4: L_d(q) = Q_d M◇(q)⁻¹, p = Q_d q̇)."""

    K_p: np.ndarray
    K_v: np.ndarray
    L: np.ndarray
    gamma: float
    P_e: np.ndarray
    P_z: np.ndarray
    Q_d: np.ndarray | None
    rho: list[tuple[float, float]]
    solve_time: float
    status: str
    lmi_rows: int
    n_variables: int
    omega_c: float
    T: np.ndarray
    variant: str
    solver: str = "clarabel"

    @property
    def K(self) -> np.ndarray:
        """K = [diag(K_p), diag(K_v)] acting on z = [ε_c; ε̇_c]."""
        return np.hstack([np.diag(self.K_p), np.diag(self.K_v)])


def ellipsoid_from_box(bounds: np.ndarray, n_total: int | None = None) -> np.ndarray:
    """E = diag(1/(N b_i²)): the ellipsoid xᵀEx ≤ 1 contains the box |x_i| ≤ b_i (N = n_total,
    the number of components of the whole initial-error vector the ellipsoids share)."""
    b = np.asarray(bounds, dtype=float)
    n = len(b) if n_total is None else n_total
    return np.diag(1.0 / (n * b**2))


# ---------------------------------------------------------------------------------------
# scaling


@dataclass
class _Scaled:
    models: list[ErrorModel]
    samples: list[ErrorModel]
    omega_c: float
    T: np.ndarray  # diagonal of the observer-state scaling x = T x̃
    tau_c: float  # torque scale of ε_d (chapter 4)
    s_m: float  # inertia scale of M̃ (chapter 4)
    d: np.ndarray  # actuator-coordinate scaling ε_c = d ε_c' (per actuator)
    c_s: float  # output weight scaling: C_z' = diag(d)/c_s, γ'² = γ̃²/c_s²
    r_d: np.ndarray | None = None  # per-actuator ε_d scaling (chapter 4): ε_d = τ_c diag(r_d) ε̃_d


def _scale(req: SynthesisRequest) -> _Scaled:

    omega_c = req.controller_region.radius
    # observer state in units of its initial-error bounds (x̃_i = x_i/b_i, Ẽ ≈ I/n_e): the
    # balancing of A_e alone cannot scale ω0, whose column of A_e is zero at rest
    e_diag = np.clip(np.diag(req.E_e), 1e-300, None)
    T = 1.0 / np.sqrt(e_diag)
    if len(T):
        T = T / np.exp(np.mean(np.log(T)))
    m_scale = 1.0
    r_d = None
    if req.variant == "ndi_observer_ndo":
        m_diag = np.diag(req.nominal[0].M)
        m_scale = float(np.max(m_diag))
        # ε_d per actuator in units of τ_c r_i, r_i = (M◇_ii/max M◇_jj)^½: the congruence
        # ε_d = τ_c R ε̃_d (exact) gives M̃◇ a unit diagonal; with one torque scale for every
        # actuator a 0.2 kg m² wheel next to a 400 kg rail gave M̃◇ entries 5e-4 to 1
        r_d = np.sqrt(m_diag / m_scale)
    s_m = omega_c * m_scale
    # τ_c² = s_m ω_c: the scaled NDO Lyapunov term ε̃_dᵀP̃_dM̃◇P̃_dε̃_d (P̃_d = Q̃_d⁻¹) is then
    # exactly the SI ε_dᵀP_dM◇P_dε_d that ``verify`` certifies (in general it is s_mω_c/τ_c²
    # times it: with τ_c = ω_c² max M◇_ii the problem solved was a differently weighted one, and
    # verification failed on PULSAR-shaped problems)
    tau_c = omega_c * np.sqrt(m_scale)

    def one(m: ErrorModel) -> ErrorModel:
        A = (m.A_e * T[None, :] / T[:, None]) / omega_c
        C = m.C_e * T[None, :]
        B = m.B_eps * T[None, :] / omega_c**2
        M = Dx = Ds = None
        if req.variant == "ndi_observer_ndo":
            Ri = np.diag(1.0 / r_d)
            M = omega_c * Ri @ m.M @ Ri / s_m
            Dx = Ri @ m.D_x * T[None, :] / tau_c
            Ds = Ri @ (m.D_sym if m.D_sym is not None else np.zeros_like(m.M)) @ Ri / s_m
        return ErrorModel(A, C, B, M, Dx, Ds, m.label)

    models = [one(m) for m in req.linearisations()]
    samples = [] if req.relaxation == "polytopic" else [one(m) for m in req.samples]
    # actuator rows: unit-norm rows of B̃_ε (a wheel of 1e-4 kg m² and a joint of 1e4 kg m² see
    # disturbance accelerations decades apart); the weight moves into C_z so γ is unchanged
    rows = np.max([np.linalg.norm(m.B_eps, axis=1) for m in models], axis=0)
    pos = rows[rows > 0]
    d = np.where(rows > 0, rows, np.exp(np.mean(np.log(pos))) if len(pos) else 1.0)
    for m in models + samples:
        m.B_eps = m.B_eps / d[:, None]
    return _Scaled(models, samples, omega_c, T, tau_c, s_m, d, float(np.max(d)), r_d)


@dataclass
class _Uncertainty:
    """The sampled variation around one nominal model, in scaled coordinates.

    ΔA_e = G Δ_A N_A and ΔB_ε = diag(g_B) Δ_B N_B with σ̄(Δ_A) ≤ rho1, σ̄(Δ_B) ≤ rho2 for every
    sample assigned to the model. G selects the rows of A_e that vary (the acceleration rows: the
    kinematic rows ḟ = ḟ never do). When every sampled row block lies in the row space of the
    nominal one, N_A = A_e[rows] and Δ_A = ΔA_e[rows] A_e[rows]⁺ is the relative change of the
    inverse inertia (ΔA = −Δ(M*⁻¹)S with the constant stiffness/damping map S); otherwise
    N_A = I (additive). ΔB_ε is additive (N_B = I: B_ε only enters the performance, and N_B =
    A_e[rows], whose rows carry the modal stiffness ω², made the bound useless on pulsar_simple)
    with per-actuator weights g_B (largest row variation, normalised to max 1).
    'thesis': G = N = I and the printed (3.51): rho1 = 2 max σ̄(ΔA_e), rho2 = max σ̄(ΔB_ε)."""

    rho1: float
    rho2: float
    G: np.ndarray
    N_A: np.ndarray
    N_B: np.ndarray
    form: str  # 'relative', 'additive', 'unstructured' (thesis) or 'none'
    g_B: np.ndarray | None = None  # per-actuator weights of ΔB_ε = diag(g_B) Δ_B (max 1)


def _uncertainty(sc: _Scaled, relaxation: str) -> list[_Uncertainty]:
    """Per nominal model: the variation of the samples nearest to it (see ``_Uncertainty``)."""
    n_e = sc.models[0].n_e
    eye = np.eye(n_e)
    out = [_Uncertainty(0.0, 0.0, eye, eye, eye, "none") for _ in sc.models]
    if relaxation in ("none", "polytopic") or not sc.samples:
        return out
    groups: list[list[ErrorModel]] = [[] for _ in sc.models]
    for s in sc.samples:
        d = [np.linalg.norm(s.A_e - m.A_e, 2) + np.linalg.norm(s.B_eps - m.B_eps, 2) for m in sc.models]
        groups[int(np.argmin(d))].append(s)
    for k, (m, grp) in enumerate(zip(sc.models, groups)):
        if not grp:
            continue
        dA = [s.A_e - m.A_e for s in grp]
        dB = [s.B_eps - m.B_eps for s in grp]
        if relaxation == "thesis":
            out[k] = _Uncertainty(2 * max(np.linalg.norm(x, 2) for x in dA), max(np.linalg.norm(x, 2) for x in dB),
                                  eye, eye, eye, "unstructured")
            continue
        scale_a = max(np.abs(m.A_e).max(), 1e-300)
        rows = np.flatnonzero(np.max([np.abs(x).max(axis=1) for x in dA], axis=0) > 1e-12 * scale_a)
        if len(rows) == 0:
            rows = np.arange(n_e)
        G = eye[:, rows]
        AR = m.A_e[rows]
        AR_pinv = np.linalg.pinv(AR, rcond=1e-10)
        DA = [x[rows] @ AR_pinv for x in dA]
        res = max(np.abs(D @ AR - x[rows]).max() for D, x in zip(DA, dA))
        big = max([np.abs(x).max() for x in dA] + [1e-300])
        # ΔB_ε = diag(g)Δ_B: each actuator's row weighted by its own largest variation, so that an
        # actuator whose disturbance row barely changes does not pay for the one that changes most
        g = np.max([np.linalg.norm(x, axis=1) for x in dB], axis=0)
        g = np.maximum(g / max(g.max(), 1e-300), 1e-6)
        rho2 = max(np.linalg.norm(x / g[:, None], 2) for x in dB)
        if res <= 1e-8 * big:
            out[k] = _Uncertainty(max(np.linalg.norm(D, 2) for D in DA), rho2, G, AR, eye, "relative", g)
        else:
            out[k] = _Uncertainty(max(np.linalg.norm(x[rows], 2) for x in dA), rho2, G, eye, eye, "additive", g)
    return out


def _rho(sc: _Scaled, relaxation: str) -> list[tuple[float, float]]:
    """(ρ1, ρ2) per nominal model (see ``_Uncertainty`` for their meaning in each form)."""
    return [(float(u.rho1), float(u.rho2)) for u in _uncertainty(sc, relaxation)]


# ---------------------------------------------------------------------------------------
# problem construction


def _build(req: SynthesisRequest, sc: _Scaled, rho, drop: frozenset[str] = frozenset(),
           feasibility: bool = False):
    """The cvxpy problem and its constraint groups (scaled data). ``drop``: groups left out;
    ``feasibility``: no objective (min γ is unbounded in K without the controller region)."""
    import cvxpy as cp

    m0 = sc.models[0]
    n_q, n_e, n_y = m0.n_q, m0.n_e, m0.n_y
    ndo = req.variant == "ndi_observer_ndo"

    q11, q12, q22 = cp.Variable(n_q), cp.Variable(n_q), cp.Variable(n_q)
    wp, wv = cp.Variable(n_q), cp.Variable(n_q)
    Q = cp.bmat([[cp.diag(q11), cp.diag(q12)], [cp.diag(q12), cp.diag(q22)]])
    W = cp.hstack([cp.diag(wp), cp.diag(wv)])
    P = cp.Variable((n_e, n_e), symmetric=True)
    We = cp.Variable((n_e, n_y))
    g = cp.Variable(nonneg=True)  # γ̃²
    Qd = cp.Variable((n_q, n_q), symmetric=True) if ndo else None
    c_e = cp.Variable(nonneg=True)
    c_z = cp.Variable(n_q, nonneg=True)

    groups: dict[str, list] = {"performance": [], "controller_region": [], "observer_region": [],
                               "initial_conditions": [], "actuator_authority": [], "positivity": []}

    groups["positivity"] += [P >> EPS * np.eye(n_e)]
    for i in range(n_q):
        Qi = cp.bmat([[_s(cp, q11[i]), _s(cp, q12[i])],
                      [_s(cp, q12[i]), _s(cp, q22[i])]])
        Ni = cp.bmat([[_s(cp, q12[i]), _s(cp, q22[i])],
                      [_s(cp, -wp[i]), _s(cp, -wv[i])]])  # A_z,i Q_i + B_z,i W_i
        groups["positivity"] += [(Qi + Qi.T) / 2 >> EPS * np.eye(2), (Qi + Qi.T) / 2 << Q_MAX * np.eye(2)]
        groups["controller_region"] += region_lmis(cp, Ni, Qi, req.controller_region.scaled(sc.omega_c), EPS)
        if req.accel_limit is not None and np.isfinite(req.accel_limit[i]):
            a = float(req.accel_limit[i]) / sc.omega_c**2 / sc.d[i]
            Wi = cp.hstack([_s(cp, wp[i]), _s(cp, wv[i])])
            Mi = cp.bmat([[np.array([[a * a]]), Wi], [Wi.T, Qi]])
            groups["actuator_authority"].append((Mi + Mi.T) / 2 >> 0)
        if req.tracking is not None:
            # corners of the box |ε| ≤ e, |ε̇| ≤ ė (scaled: ε̇/ω_c) inside z_iᵀQ_i⁻¹z_i ≤ c_i
            e, ed = float(req.tracking[i, 0]) / sc.d[i], float(req.tracking[i, 1]) / sc.omega_c / sc.d[i]
            for v in ([e, ed], [e, -ed]) if ed > 0 else ([e, 0.0],):
                Mc = cp.bmat([[_s(cp, c_z[i]), np.array([v])], [np.array([v]).T, Qi]])
                groups["initial_conditions"].append((Mc + Mc.T) / 2 >> 0)
    # V(0) ≤ 1 on S: budget c_e + Σc_z (+ c_d = 1/2 in chapter 4) ≤ 1
    Ee = np.diag(sc.T) @ req.E_e @ np.diag(sc.T)
    groups["initial_conditions"].append(P << c_e * Ee)
    budget = c_e + (cp.sum(c_z) if req.tracking is not None else 0)
    groups["initial_conditions"].append(budget <= (1.0 - C_D if ndo else 1.0))
    if ndo:
        groups["positivity"].append(Qd >> EPS * np.eye(n_q))
        # P̃_dM̃P̃_d ⪯ c_d Ẽ_d  ⇐  2Q̃_d − (c_dẼ_d)⁻¹ ⪰ M̃_j  (convex substitute, see module doc)
        Edinv = _ed_inv(req, sc)
        ra = req.observer_region.scaled(sc.omega_c)
        for m in sc.models + sc.samples:
            Ms = (m.M + m.M.T) / 2
            groups["initial_conditions"].append(2 * Qd - Edinv >> Ms)
            # NDO poles eig(Q̃_d M̃⁻¹) are real: keep them in [α, r] of the observer region
            groups["observer_region"] += [Qd >> ra.alpha * Ms, Qd << ra.radius * Ms]

    obs_region = req.observer_region.scaled(sc.omega_c)
    unc = _uncertainty(sc, req.relaxation)
    rows = 0
    for k, m in enumerate(sc.models):
        r1, r2 = rho[k]
        PA = P @ m.A_e - We @ m.C_e
        groups["observer_region"] += region_lmis(cp, PA.T, P, obs_region, EPS)
        extra = (r2, r1 + r2) if req.relaxation == "thesis" else (0.0, 0.0)
        Om = cp.bmat(_theta_rows(m, sc, Q, W, PA, Qd, g, extra))
        n_om = Om.shape[0]
        if req.relaxation == "scaled" and (r1 > 0 or r2 > 0):
            # Petersen's lemma on the structured variation (``_Uncertainty``), multipliers λ, δ > 0:
            #   (E₁Δ_BN_BE₂ᵀ)^s ⪯ λρ₂²E₁E₁ᵀ + λ⁻¹E₂N_BᵀN_BE₂ᵀ  (E₁ carries the weights g_B),
            #   (E₂PGΔ_AN_AE₂ᵀ)^s ⪯ δ⁻¹E₂PGGᵀPE₂ᵀ + δρ₁²E₂N_AᵀN_AE₂ᵀ;  the λ⁻¹, δ⁻¹ terms by Schur
            u = unc[k]
            lam = cp.Variable(nonneg=True)
            dl = cp.Variable(nonneg=True)
            E1 = np.zeros((n_om, n_q))
            E1[n_q:2 * n_q, :] = np.diag(u.g_B)  # rows of ε̇_c, weighted per actuator
            E2 = np.zeros((n_om, n_e))
            E2[2 * n_q:2 * n_q + n_e, :] = np.eye(n_e)  # rows of ε_e
            nb, ng = u.N_B.shape[0], u.G.shape[1]
            E2NB = E2 @ u.N_B.T
            E2PG = cp.bmat([[np.zeros((2 * n_q, ng))], [P @ u.G], [np.zeros((n_om - 2 * n_q - n_e, ng))]])
            top = Om + lam * (r2**2) * (E1 @ E1.T) + dl * (r1**2) * (E2 @ u.N_A.T @ u.N_A @ E2.T)
            Om = cp.bmat([[top, E2NB, E2PG],
                          [E2NB.T, -lam * np.eye(nb), np.zeros((nb, ng))],
                          [E2PG.T, np.zeros((ng, nb)), -dl * np.eye(ng)]])
            n_om = Om.shape[0]
        rows = max(rows, n_om)
        groups["performance"].append((Om + Om.T) / 2 << -EPS * np.eye(n_om))

    cons = []
    for name, cs in groups.items():
        if name not in drop:
            cons += cs
    prob = cp.Problem(cp.Minimize(0 if feasibility else g), cons)
    var = {"q11": q11, "q12": q12, "q22": q22, "wp": wp, "wv": wv, "P": P, "We": We, "g": g, "Qd": Qd}
    return prob, var, groups, rows


def _theta_rows(m: ErrorModel, sc: _Scaled, Q, W, PA, Qd, g, extra=(0.0, 0.0)) -> list[list]:
    """The performance LMI Θ ≺ 0 of one linearisation as nested blocks (scaled units), rows
    [z; ε_e; γ] (Kraiem 2022 (3.4x), chapter 3, Qd None) or [z; ε_e; ε_d; γ] ((4.27), chapter 4)::

        [[(A_zQ + B_zW)^s, [0; B_ε], B_zdQ_d, QC_zᵀ], [*, (PA_e − W_eC_e)^s, D◇_xᵀ, 0],
         [*, *, −2Q_d + D◇_sym, 0], [*, *, *, −γ̃²I]]

    Q, W (2n_q×2n_q, n_q×2n_q), PA = PA_e − W_eC_e, Qd, g: cvxpy expressions (``_build``) or
    numpy arrays (``theta_at``). extra: (ρ₂, ρ₁ + ρ₂) added to the two diagonal blocks
    (relaxation 'thesis', Kraiem 2022 (3.52))."""
    n_q, n_e = m.n_q, m.n_e
    Iq, Zqq, Zeq = np.eye(n_q), np.zeros((n_q, n_q)), np.zeros((n_e, n_q))
    Az = np.block([[Zqq, Iq], [Zqq, Zqq]])
    Bz = np.vstack([Zqq, -Iq])
    Cz = np.hstack([np.diag(sc.d / sc.c_s), Zqq])
    AQBW = Az @ Q + Bz @ W
    Be = np.vstack([np.zeros((n_q, n_e)), m.B_eps])
    b11 = AQBW + AQBW.T + extra[0] * np.eye(2 * n_q)
    b22 = PA + PA.T + extra[1] * np.eye(n_e)
    if Qd is None:
        return [[b11, Be, Q @ Cz.T],
                [Be.T, b22, Zeq],
                [Cz @ Q, Zeq.T, -g * Iq]]
    BQ = np.vstack([Zqq, -_bzd(m, sc) / sc.d[:, None]]) @ Qd  # B_zd Q_d
    return [[b11, Be, BQ, Q @ Cz.T],
            [Be.T, b22, m.D_x.T, Zeq],
            [BQ.T, m.D_x, -2 * Qd + m.D_sym, Zqq],
            [Cz @ Q, Zeq.T, Zqq, -g * Iq]]


def theta_at(req: SynthesisRequest, res: "LmiResult") -> list[np.ndarray]:
    """Θ_k (``_theta_rows``, symmetrised, scaled units) at every linearisation of the request,
    evaluated at the variables recovered from the returned gains and certificate (SI → scaled):
    Q_i = S_iP_z,i⁻¹S_i, W_i = [K̃_p,i, K̃_v,i]Q_i, P = TP_εT, W_e = P T⁻¹L/ω_c, Q̃_d = R⁻¹Q_dR⁻¹/s_m,
    γ̃² = ω_cγ²/c_s². The synthesis requires Θ_k ⪯ −EPS·I."""
    sc = _scale(req)
    n_q = req.nominal[0].n_q
    Q = np.zeros((2 * n_q, 2 * n_q))
    W = np.zeros((n_q, 2 * n_q))
    for i in range(n_q):
        S = np.diag([1.0, 1.0 / sc.omega_c]) / sc.d[i]
        idx = [i, n_q + i]
        Qi = S @ np.linalg.inv(res.P_z[np.ix_(idx, idx)]) @ S
        Q[np.ix_(idx, idx)] = Qi
        W[i, idx] = np.array([res.K_p[i] / sc.omega_c**2, res.K_v[i] / sc.omega_c]) @ Qi
    Tm = np.diag(sc.T)
    P = Tm @ res.P_e @ Tm
    We = P @ np.diag(1.0 / sc.T) @ res.L / sc.omega_c
    g = sc.omega_c * (res.gamma / sc.c_s) ** 2
    Qd = None
    if res.Q_d is not None:
        Qd = res.Q_d / np.outer(sc.r_d, sc.r_d) / sc.s_m
    out = []
    for m in sc.models:
        Th = np.block(_theta_rows(m, sc, Q, W, P @ m.A_e - We @ m.C_e, Qd, g))
        out.append((Th + Th.T) / 2)
    return out


def _structured(req: SynthesisRequest) -> bool:
    """Problems without ρ terms (relaxation 'none' or 'polytopic', or no samples) go to the
    dedicated solver: chapter 3 in the decoupled form of ``_build_structured``, chapter 4 in that
    of ``direct.structured_problem`` (both exact); with ρ terms, cvxpy + Clarabel."""
    return req.relaxation in ("none", "polytopic") or not req.samples


def _build_structured(req: SynthesisRequest, sc: _Scaled, drop: frozenset[str] = frozenset(),
                      feasibility: bool = False):
    """Chapter 3, with the performance LMI Ω ≺ 0 split exactly (no loss).

    With z ordered per actuator, the (z, γ) part of Ω is block diagonal: one 3×3 block
    Γ_i = [[(A_iQ_i + B_iW_i)^s, Q_ic_iᵀ], [c_iQ_i, −γ²]] per actuator, coupled to the observer
    block only through the row b_i of B_ε (ε̇_c,i row). By the Schur complement on those blocks,
    Ω ≺ 0 ⇔ Γ_i ≺ 0 ∀i and (P A_e − W_e C_e)^s − Σ_i [Γ_i⁻¹]_{ε̇ε̇} b_iᵀb_i ≺ 0; with
    s_i ≥ −[Γ_i⁻¹]_{ε̇ε̇} ⇔ [[−Γ_i, e₂], [e₂ᵀ, s_i]] ⪰ 0 this is
        [[−Γ_i, e₂], [e₂ᵀ, s_i]] ⪰ 0 (4×4, per actuator)  and  (PA_e − W_eC_e)^s + B_εᵀ diag(s) B_ε ≺ 0
    (n_e×n_e, per linearisation). Γ_i does not depend on the linearisation, so s is shared. The
    largest cone drops from 3n_q + n_e to max(2n_e, ...) (the observer disk). P ≻ 0 is implied by
    the observer disk LMI's diagonal block −rP ≺ 0 and is not stated again.

    ρ terms (relaxation 'scaled' or 'thesis', see ``_Uncertainty``) keep this split: they add to
    Γ_i a per-actuator diagonal term (λρ₂²g_i² on ε̇_c,i for 'scaled', ρ₂I₂ for 'thesis'), so a
    linearisation with ρ gets its own Γ_i,k and s_k, and its observer block becomes
    [[Φ_k + δρ₁²NᵀN, N_Bᵀ, PG], [N_B, −λI, 0], [GᵀP, 0, −δI]] ≺ 0 ('scaled'; the border is the
    Schur form of λ⁻¹N_BᵀN_B + δ⁻¹PGGᵀP) or Φ_k + (ρ₁ + ρ₂)I ≺ 0 ('thesis'), with
    Φ_k = (PA_e − W_eC_e)^s + B_εᵀdiag(s_k)B_ε. Same LMI as ``_build``'s, split exactly.
    """
    import cvxpy as cp

    m0 = sc.models[0]
    n_q, n_e, n_y = m0.n_q, m0.n_e, m0.n_y
    q11, q12, q22 = cp.Variable(n_q), cp.Variable(n_q), cp.Variable(n_q)
    wp, wv = cp.Variable(n_q), cp.Variable(n_q)
    P = cp.Variable((n_e, n_e), symmetric=True)
    We = cp.Variable((n_e, n_y))
    g = cp.Variable(nonneg=True)  # γ̃²
    s = cp.Variable(n_q, nonneg=True)
    c_e = cp.Variable(nonneg=True)
    c_z = cp.Variable(n_q, nonneg=True)
    groups: dict[str, list] = {"performance": [], "controller_region": [], "observer_region": [],
                               "initial_conditions": [], "actuator_authority": [], "positivity": []}
    e2 = np.array([[0.0], [1.0], [0.0]])
    creg = req.controller_region.scaled(sc.omega_c)
    unc = _uncertainty(sc, req.relaxation)
    robust = [k for k, u in enumerate(unc) if u.rho1 > 0 or u.rho2 > 0]
    s_k = {k: cp.Variable(n_q, nonneg=True) for k in robust}
    lam = {k: cp.Variable(nonneg=True) for k in robust if req.relaxation == "scaled"}
    dl = {k: cp.Variable(nonneg=True) for k in robust if req.relaxation == "scaled"}
    for i in range(n_q):
        Qi = cp.bmat([[_s(cp, q11[i]), _s(cp, q12[i])],
                      [_s(cp, q12[i]), _s(cp, q22[i])]])
        Ni = cp.bmat([[_s(cp, q12[i]), _s(cp, q22[i])],
                      [_s(cp, -wp[i]), _s(cp, -wv[i])]])  # A_z,i Q_i + B_z,i W_i
        ci = float(sc.d[i] / sc.c_s)
        cQ = ci * cp.hstack([_s(cp, q11[i]), _s(cp, q12[i])])
        Gi = cp.bmat([[Ni + Ni.T, cQ.T], [cQ, _s(cp, -g)]])
        Mi = cp.bmat([[-Gi - EPS * np.eye(3), e2], [e2.T, _s(cp, s[i])]])
        groups["performance"].append(_sym(cp, Mi) >> 0)
        for k in robust:
            r2 = unc[k].rho2
            if k in lam:
                extra = lam[k] * (r2 * unc[k].g_B[i]) ** 2 * np.diag([0.0, 1.0, 0.0])
            else:
                extra = r2 * np.diag([1.0, 1.0, 0.0])
            Mik = cp.bmat([[-Gi - extra - EPS * np.eye(3), e2], [e2.T, _s(cp, s_k[k][i])]])
            groups["performance"].append(_sym(cp, Mik) >> 0)
        groups["positivity"].append(_sym(cp, Qi) << Q_MAX * np.eye(2))
        # Q_i ≻ 0 is implied by the disk LMI of the controller region (diagonal block −rQ_i)
        groups["controller_region"] += region_lmis(cp, Ni, Qi, creg, EPS)
        if "controller_region" in drop:
            groups["positivity"].append(_sym(cp, Qi) >> EPS * np.eye(2))
        if req.accel_limit is not None and np.isfinite(req.accel_limit[i]):
            a = float(req.accel_limit[i]) / sc.omega_c**2 / sc.d[i]
            Wi = cp.hstack([_s(cp, wp[i]), _s(cp, wv[i])])
            groups["actuator_authority"].append(_sym(cp, cp.bmat([[np.array([[a * a]]), Wi], [Wi.T, Qi]])) >> 0)
        if req.tracking is not None:
            e, ed = float(req.tracking[i, 0]) / sc.d[i], float(req.tracking[i, 1]) / sc.omega_c / sc.d[i]
            for v in ([e, ed], [e, -ed]) if ed > 0 else ([e, 0.0],):
                Mc = cp.bmat([[_s(cp, c_z[i]), np.array([v])], [np.array([v]).T, Qi]])
                groups["initial_conditions"].append(_sym(cp, Mc) >> 0)
    Ee = np.diag(sc.T) @ req.E_e @ np.diag(sc.T)
    groups["initial_conditions"].append(P << c_e * Ee)
    budget = c_e + (cp.sum(c_z) if req.tracking is not None else 0)
    groups["initial_conditions"].append(budget <= 1.0)
    oreg = req.observer_region.scaled(sc.omega_c)
    rows = 3 * n_q + n_e
    for k, m in enumerate(sc.models):
        PA = P @ m.A_e - We @ m.C_e
        groups["observer_region"] += region_lmis(cp, PA.T, P, oreg, EPS)
        Phi = PA + PA.T + m.B_eps.T @ cp.diag(s_k.get(k, s)) @ m.B_eps
        if k in lam:
            u = unc[k]
            nb, ng = u.N_B.shape[0], u.G.shape[1]
            PG = P @ u.G
            Om = cp.bmat([[Phi + dl[k] * u.rho1**2 * (u.N_A.T @ u.N_A), u.N_B.T, PG],
                          [u.N_B, -lam[k] * np.eye(nb), np.zeros((nb, ng))],
                          [PG.T, np.zeros((ng, nb)), -dl[k] * np.eye(ng)]])
            groups["performance"].append(_sym(cp, Om) << -EPS * np.eye(n_e + nb + ng))
            rows = max(rows, 3 * n_q + n_e + nb + ng)
        elif k in s_k:
            groups["performance"].append(_sym(cp, Phi + (unc[k].rho1 + unc[k].rho2) * np.eye(n_e)) << -EPS * np.eye(n_e))
        else:
            groups["performance"].append(_sym(cp, Phi) << -EPS * np.eye(n_e))
    if "observer_region" in drop:
        groups["positivity"].append(P >> EPS * np.eye(n_e))
    cons = [c for name, cs in groups.items() if name not in drop for c in cs]
    prob = cp.Problem(cp.Minimize(0 if feasibility else g), cons)
    var = {"q11": q11, "q12": q12, "q22": q22, "wp": wp, "wv": wv, "P": P, "We": We, "g": g, "Qd": None,
           "s": s, "c_e": c_e, "c_z": c_z}
    return prob, var, groups, rows


def _sym(cp, M):
    return (M + M.T) / 2


def _s(cp, x):
    """A scalar expression as a 1×1 block."""
    return cp.reshape(x, (1, 1), order="C")


def _bzd(m: ErrorModel, sc: _Scaled) -> np.ndarray:
    """Scaled −B_zd lower block: M◇⁻¹ τ_c R/ω_c² (ε_d = τ_c R ε̃_d, z̃ in scaled time).

    m.M is already the scaled M̃ = ω_c R⁻¹MR⁻¹/s_m, so M⁻¹R = R⁻¹M̃⁻¹ ω_c/s_m."""
    return (np.linalg.inv(m.M) / sc.r_d[:, None]) * (sc.omega_c / sc.s_m) * sc.tau_c / sc.omega_c**2


def _ed_inv(req: SynthesisRequest, sc: _Scaled) -> np.ndarray:
    """(c_dẼ_d)⁻¹ of the NDO initial-condition LMI, Ẽ_d = τ_c² R E_d R (ε_d = τ_c R ε̃_d)."""
    R = np.diag(sc.r_d)
    return np.linalg.inv(C_D * sc.tau_c**2 * R @ req.E_d @ R)


def _builder(req, sc, rho, drop: frozenset[str] = frozenset(), feasibility: bool = False):
    """Chapter 3 (every relaxation) in the split form of ``_build_structured``, chapter 4 in the
    full form of ``_build`` (``rho`` is informative: both recompute the uncertainty)."""
    if req.variant == "ndi_observer":
        return _build_structured(req, sc, drop, feasibility)
    return _build(req, sc, rho, drop, feasibility)


def _solve(prob, max_iter: int = 200) -> float:
    import warnings

    import cvxpy as cp

    t0 = time.perf_counter()
    # 1e-7: verification recomputes every guarantee from the gains, and the certificate check
    # needs the solver's γ to 0.1 %; tighter tolerances only add iterations
    # a KKT factorisation failure at the first iterations (pulsar_simple's full form) goes away
    # with a stronger static regularisation of the KKT system (default 1e-8)
    for opts in ({"max_iter": max_iter, "tol_gap_abs": 1e-7, "tol_gap_rel": 1e-7, "tol_feas": 1e-7},
                 {"max_iter": 2 * max_iter},
                 {"max_iter": 2 * max_iter, "tol_gap_abs": 1e-7, "tol_gap_rel": 1e-7, "tol_feas": 1e-7,
                  "static_regularization_constant": 1e-7}):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                prob.solve(solver=cp.CLARABEL, **opts)
        except cp.error.SolverError:
            continue
        break
    return time.perf_counter() - t0


RELAXABLE = {
    "controller_region": "widen the controller pole region (lower decay_rate or min_damping, raise max_frequency)",
    "observer_region": "widen the observer pole region (observer_region: lower decay_rate/min_damping, raise max_frequency)",
    "actuator_authority": "raise the actuator torque limits, lower tracking_error_amplitude or the controller decay_rate",
    "initial_conditions": "enlarge the initial-error bounds (initial_errors: E ellipsoid) or drop 'tracking'",
    "robustness": "the nominal configuration alone is feasible: narrow the sampled workspace (sampling.spread, "
                  "sampling.samples), add intermediate configurations, or use relaxation: polytopic (the "
                  "samples as vertices instead of a ρ-ball around the nominal)",
}


def synthesize(req: SynthesisRequest, diagnose: bool = True, solver: str = "auto") -> LmiResult:
    """Minimise γ subject to the LMIs; map the solution back to SI gains.

    solver: 'auto' (the structured problem with the dedicated interior-point solver of
    ``sdp.py``, built directly by ``direct.py``; anything else, or a run of it that does not
    converge to a point satisfying every block, through cvxpy + Clarabel), 'ipm' (the dedicated
    solver only, NumericalError if it fails) or 'clarabel'.
    Raises NumericalError (exit 3) when infeasible, naming the constraint group(s) whose
    removal makes the problem feasible and what to relax. The solver status is not trusted:
    callers must run ``verify``.
    """
    _check_dims(req)
    _check_fixed_observer_poles(req)
    sc = _scale(req)
    rho = _rho(sc, req.relaxation)
    if solver == "ipm" and not _structured(req):
        raise ValueError("solver='ipm' handles relaxation 'none' or 'polytopic' (or no samples) only")
    if solver in ("auto", "ipm") and _structured(req):
        res = _synthesize_ipm(req, sc, rho)
        if res is not None:
            return res
        if solver == "ipm":
            raise NumericalError("the interior-point solver did not converge on the structured LMI problem")
        rows = (4 if req.variant == "ndi_observer_ndo" else 3) * req.nominal[0].n_q + req.nominal[0].n_e
        if solver == "auto" and rows > CLARABEL_MAX_ROWS:
            raise NumericalError(problems=[Problem(
                f"the LMI synthesis did not converge: the dedicated interior-point solver stalled on this {rows}-row "
                f"problem ({len(req.linearisations())} linearisation(s)), and the general solver (Clarabel) is not tried "
                f"above {CLARABEL_MAX_ROWS} rows (at 111 rows it had not finished in 10 minutes, and its memory grows "
                "past 13 GB)", field="synthesis.lmi",
                hint="tighten synthesis.lmi.initial_errors (smaller bounds allow a larger observer Lyapunov matrix), "
                     "widen the observer region (a smaller decay_rate or min_damping), or use fewer linearisations")])
    prob, var, groups, rows = _builder(req, sc, rho)
    dt = _solve(prob)
    if prob.status not in ("optimal", "optimal_inaccurate") or var["g"].value is None:
        raise _infeasible(req, sc, rho, prob.status, diagnose)
    vals = {k: (v.value if v is not None else None) for k, v in var.items()}
    n_vars = sum(int(np.prod(v.shape)) if v.shape else 1 for v in prob.variables())
    return _extract(req, sc, rho, vals, prob.status, n_vars, dt, rows, "clarabel")


def _synthesize_ipm(req: SynthesisRequest, sc: _Scaled, rho) -> LmiResult | None:
    """The structured problem through ``direct.solve_structured``; None unless the solver
    converged (to IPM_TOL, or to the reduced tolerances of ``sdp.NEAR_GAP``/``NEAR_FEAS``:
    'optimal_inaccurate', as the Clarabel path accepts) and the returned point satisfies every
    block (each includes the EPS margin)."""
    from sms_cli.synthesis.direct import solve_structured

    t0 = time.perf_counter()
    try:
        vals, sres, n_vars = solve_structured(req, sc, EPS, Q_MAX, tol=IPM_TOL)
    except (ValueError, np.linalg.LinAlgError):
        return None
    dt = time.perf_counter() - t0
    if sres.status not in ("optimal", "optimal_inaccurate") or sres.min_eig < -1e-9 or not np.isfinite(vals["g"]):
        return None
    m0 = sc.models[0]
    rows = (4 if req.variant == "ndi_observer_ndo" else 3) * m0.n_q + m0.n_e  # the full form's Θ
    near = "" if sres.status == "optimal" else f", relative gap {sres.gap:.1e}"
    return _extract(req, sc, rho, vals, sres.status, n_vars, dt, rows,
                    f"sms-ipm ({sres.iterations} iterations{near})")


def _extract(req, sc, rho, vals, status, n_vars, dt, rows, solver) -> LmiResult:
    n_q = req.nominal[0].n_q
    q11, q12, q22 = vals["q11"], vals["q12"], vals["q22"]
    wp, wv = vals["wp"], vals["wv"]
    Kp_s = np.empty(n_q)
    Kv_s = np.empty(n_q)
    Pz = np.zeros((2 * n_q, 2 * n_q))
    for i in range(n_q):
        S = np.diag([1.0, 1.0 / sc.omega_c]) / sc.d[i]  # z' = S z
        Qi = np.array([[q11[i], q12[i]], [q12[i], q22[i]]])
        Ki = np.array([wp[i], wv[i]]) @ np.linalg.inv(Qi)
        Kp_s[i], Kv_s[i] = Ki
        Pi = S @ np.linalg.inv(Qi) @ S  # P_z in unscaled z
        idx = np.ix_([i, n_q + i], [i, n_q + i])
        Pz[idx] = Pi
    P_s = vals["P"]
    L_s = np.linalg.solve(P_s, vals["We"])
    Tm = np.diag(sc.T)
    Ti = np.diag(1.0 / sc.T)
    Qd = None
    if vals.get("Qd") is not None:
        Qd = sc.s_m * (sc.r_d[:, None] * vals["Qd"] * sc.r_d[None, :])  # Q_d = s_m R Q̃_d R
    return LmiResult(
        K_p=Kp_s * sc.omega_c**2, K_v=Kv_s * sc.omega_c, L=sc.omega_c * Tm @ L_s,
        gamma=float(np.sqrt(max(float(vals["g"]), 0.0) / sc.omega_c) * sc.c_s), P_e=Ti @ P_s @ Ti, P_z=Pz, Q_d=Qd,
        rho=rho, solve_time=dt, status=status, lmi_rows=rows, n_variables=n_vars,
        omega_c=sc.omega_c, T=sc.T, variant=req.variant, solver=solver)


def _infeasible(req, sc, rho, status, diagnose) -> NumericalError:
    """Which constraint group makes the problem infeasible: first the robustness (is the nominal
    linearisation alone feasible?), then each group dropped in turn on the nominal model only,
    so that the diagnosis costs a few small solves."""
    import dataclasses

    culprits: list[str] = []
    if diagnose:
        prob, _, groups, _ = _builder(req, sc, rho, feasibility=True)
        _solve(prob, max_iter=100)
        if prob.status in ("optimal", "optimal_inaccurate"):
            msg = (f"the constraints are feasible but minimising γ did not converge (solver status: {status}); "
                   "the problem is badly conditioned")
            return NumericalError(msg, [Problem(msg, field="synthesis.lmi",
                                                hint="tighten the pole regions (smaller max_frequency bounds the gains) "
                                                     "or bound the initial errors more tightly")])
        nom = dataclasses.replace(req, nominal=req.nominal[:1], samples=[])
        sc_n = _scale(nom)
        rho_n = [(0.0, 0.0)]
        several = len(req.linearisations()) > 1 or any(r1 > 0 or r2 > 0 for r1, r2 in rho)
        if several:
            prob, _, _, _ = _builder(nom, sc_n, rho_n, feasibility=True)
            _solve(prob, max_iter=100)
            if prob.status in ("optimal", "optimal_inaccurate"):
                culprits.append("robustness")
        if not culprits:
            for grp in ("controller_region", "observer_region", "actuator_authority", "initial_conditions"):
                if not groups.get(grp):
                    continue
                prob, _, _, _ = _builder(nom, sc_n, rho_n, drop=frozenset({grp}), feasibility=True)
                _solve(prob, max_iter=100)
                if prob.status in ("optimal", "optimal_inaccurate"):
                    culprits.append(grp)
    problems = []
    if culprits:
        for c in culprits:
            msg = f"constraint group '{c}' cannot be met together with the others"
            if c == "robustness" and any(r1 > 0 or r2 > 0 for r1, r2 in rho):
                msg += (f" (relaxation '{req.relaxation}', sampled ρ₁, ρ₂ per linearisation: "
                        + ", ".join(f"({r1:.3g}, {r2:.3g})" for r1, r2 in rho) + ")")
            problems.append(Problem(msg, field="synthesis.lmi", hint=RELAXABLE[c]))
    else:
        problems.append(Problem("no single constraint group explains the infeasibility "
                                "(the observer may not be detectable from the measured base rate, or "
                                "several requirements conflict)", field="synthesis.lmi",
                                hint="relax several requirements at once: " + "; ".join(RELAXABLE.values())))
    head = f"LMI synthesis infeasible (solver status: {status})"
    return NumericalError(head, problems)


def _check_fixed_observer_poles(req: SynthesisRequest) -> None:
    """NumericalError (exit 3) when a mode the measurement does not see (``regions.unobservable_eigenvalues`` of
    A_e, C_e: a pole of the observer whatever its gain) is not strictly inside the observer region: the observer's
    LMI then has no strictly feasible point, and interior-point solvers stall instead of saying so (the full
    PULSAR's beam modes at 14.2, 44.8 and 87.2 rad/s, unseen by the gyro, have exactly the 0.005 damping that an
    observer region of min_damping 0.005 asks for)."""
    region = req.observer_region
    for m in req.linearisations():
        fixed = unobservable_eigenvalues(m.A_e, m.C_e)
        bad = fixed[~region.strictly_contains(fixed)]
        if not len(bad):
            continue
        mag, zeta = np.abs(bad), damping_ratios(bad)
        modes = ", ".join(f"{w:.4g} rad/s (ζ {z:.4g}, decay {-lam.real:.4g} 1/s)" for w, z, lam in zip(mag, zeta, bad))
        out = region.on_or_beyond(bad)
        fixes = ([f"min_damping below {zeta[out['damping']].min():.4g}"] if out["damping"].any() else []) + \
            ([f"decay_rate below {-bad.real[out['decay']].max():.4g} rad/s"] if out["decay"].any() else []) + \
            ([f"max_frequency above {mag[out['disk']].max():.4g} rad/s"] if out["disk"].any() else [])
        raise NumericalError(problems=[Problem(
            f"the observer region cannot hold {len(bad)} mode(s) that the measurement does not see at linearisation "
            f"'{m.label}': {modes}; no observer gain moves them, so the LMI has no strictly feasible point",
            field="synthesis.lmi.observer_region",
            hint="keep them strictly inside the region: " + ", ".join(fixes))])


def _check_dims(req: SynthesisRequest) -> None:
    m0 = req.nominal[0]
    for m in req.nominal + req.samples:
        if m.A_e.shape != (m0.n_e, m0.n_e) or m.C_e.shape != (m0.n_y, m0.n_e) or m.B_eps.shape != (m0.n_q, m0.n_e):
            raise ValueError(f"linearisation '{m.label}' has inconsistent dimensions")
        if req.variant == "ndi_observer_ndo" and (m.M is None or m.D_x is None):
            raise ValueError("the chapter 4 variant needs M and D_x in every linearisation")
    if req.E_e.shape != (m0.n_e, m0.n_e):
        raise ValueError("E_e must be n_e×n_e")


# ---------------------------------------------------------------------------------------
# closed loops (used by verify and the tests)


def closed_loop(model: ErrorModel, res: LmiResult) -> tuple[np.ndarray, np.ndarray]:
    """(A_cl, C_cl) of w = [z; ε_e] (chapter 3) or [z; ε_e; ε_d] (chapter 4), unscaled SI."""
    n_q, n_e = model.n_q, model.n_e
    Iq, Z = np.eye(n_q), np.zeros((n_q, n_q))
    Acz = np.block([[Z, Iq], [-np.diag(res.K_p), -np.diag(res.K_v)]])
    Be = np.vstack([np.zeros((n_q, n_e)), model.B_eps])
    Aee = model.A_e - res.L @ model.C_e
    if res.variant != "ndi_observer_ndo":
        A = np.block([[Acz, Be], [np.zeros((n_e, 2 * n_q)), Aee]])
        C = np.hstack([Iq, Z, np.zeros((n_q, n_e))])
        return A, C
    Minv = np.linalg.inv(model.M)
    Ld = res.Q_d @ Minv
    Bzd = np.vstack([Z, -Minv])
    A = np.block([[Acz, Be, Bzd],
                  [np.zeros((n_e, 2 * n_q)), Aee, np.zeros((n_e, n_q))],
                  [np.zeros((n_q, 2 * n_q)), Ld @ model.D_x, -Ld]])
    C = np.hstack([Iq, Z, np.zeros((n_q, n_e + n_q))])
    return A, C


# ---------------------------------------------------------------------------------------
# LQR as an LMI (an independent route to the Riccati solution, used as a test oracle)


def lqr_lmi(A: np.ndarray, B: np.ndarray, Qw: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K, P (u = −Kx) of the LQR problem via min tr(P) s.t. the Riccati inequality (X = P⁻¹ form):

    [[AX + BY + (AX + BY)ᵀ, X Qw^½, Yᵀ R^½], [*, −I, 0], [*, *, −I]] ⪯ 0,  [[Z, I], [I, X]] ⪰ 0.
    The minimal solution of the Riccati inequality is the stabilising ARE solution.
    """
    import cvxpy as cp

    def sqrtm(S):
        w, V = np.linalg.eigh((S + S.T) / 2)
        return V @ np.diag(np.sqrt(np.clip(w, 0, None))) @ V.T

    n, m = B.shape
    X = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((m, n))
    Zv = cp.Variable((n, n), symmetric=True)
    Qh = np.real(sqrtm(Qw))
    Rh = np.real(sqrtm(R))
    M = cp.bmat([[A @ X + B @ Y + (A @ X + B @ Y).T, X @ Qh, Y.T @ Rh],
                 [Qh @ X, -np.eye(n), np.zeros((n, m))],
                 [Rh @ Y, np.zeros((m, n)), -np.eye(m)]])
    cons = [(M + M.T) / 2 << 0, cp.bmat([[Zv, np.eye(n)], [np.eye(n), X]]) >> 0, X >> 1e-9 * np.eye(n)]
    prob = cp.Problem(cp.Minimize(cp.trace(Zv)), cons)
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    if prob.status not in ("optimal", "optimal_inaccurate"):
        raise NumericalError(f"LQR LMI infeasible (status {prob.status})")
    Xv = X.value
    return -Y.value @ np.linalg.inv(Xv), np.linalg.inv(Xv)  # u = −K x
