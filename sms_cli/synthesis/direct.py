"""The structured LMI problems built directly as numpy blocks for ``sdp.solve_lmi`` (no cvxpy
canonicalisation): chapter 3 as in ``lmi._build_structured``, chapter 4 (NDO) in the exactly
decoupled form of ``ndo_problem``'s docstring (same optimum as ``lmi._build``).

Same variables, same constraints, same objective as ``_build_structured`` (the test suite checks
that every block equals the corresponding cvxpy expression at random values of the variables).
Each block is written once as a numpy function of the variables, evaluated on stacks: its
affine coefficients are read off by evaluating it at 0 and at every unit vector of the variables
it involves (exact, since the block is affine), except for the matrix variables a block declares
(``matvar``), which are only evaluated at random probes that check the declaration: their dense
coefficients (p × n × n per block, most of the memory at Kraiem 2022's size) are never formed.

Variables (scaled units of ``lmi._scale``): q11, q12, q22, wp, wv (per actuator), P (n_e×n_e
symmetric, parameterised by its upper triangle), We (n_e×n_y), g = γ̃², s (per actuator),
c_e, c_z (per actuator, only with a tracking box); chapter 4 adds Q_d (n_q×n_q symmetric, scaled
Q̃_d = R⁻¹Q_dR⁻¹/s_m) and s is then σ (see ``structured_problem``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sms_cli.synthesis.matvar import MatrixTerm, check, sq_norms
from sms_cli.synthesis.regions import region_blocks, region_pattern
from sms_cli.synthesis.sdp import LmiBlock, single_thread_blas, solve_lmi


@dataclass
class Layout:
    """Positions of named variables in x. kind: 'vec' (n,), 'sym' (n, n), 'mat' (r, c)."""

    slots: dict = field(default_factory=dict)
    m: int = 0

    def add(self, name: str, kind: str, shape: tuple[int, ...]) -> None:
        if kind == "sym":
            size = shape[0] * (shape[0] + 1) // 2
        else:
            size = int(np.prod(shape))
        self.slots[name] = (kind, shape, slice(self.m, self.m + size))
        self.m += size

    def indices(self, names) -> np.ndarray:
        return np.concatenate([np.arange(self.slots[n][2].start, self.slots[n][2].stop) for n in names])

    def unpack(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """x (B, m) → {name: (B, *shape)}."""
        out = {}
        for name, (kind, shape, sl) in self.slots.items():
            v = x[:, sl]
            if kind == "sym":
                n = shape[0]
                iu, ju = np.triu_indices(n)
                S = np.zeros((x.shape[0], n, n))
                S[:, iu, ju] = v
                S[:, ju, iu] = v
                out[name] = S
            else:
                out[name] = v.reshape((x.shape[0],) + tuple(shape))
        return out


PROBES = 2  # random points at which each block's matrix-variable declarations are checked


def _blocks_of(layout: Layout, names: list[str], fn, group: str, terms=None) -> list[LmiBlock]:
    """LmiBlocks (one per matrix fn returns) of the affine fn(vars) over the named variables.

    terms: optional, one {variable name: [(L_s, R_s), …]} per returned matrix, declaring that the
    named matrix variable X enters it as Σ_s (L_sᵀ X R_s + R_sᵀ Xᵀ L_s) (``matvar``; the solver
    then handles it in Kronecker form). The coefficients of the undeclared variables are read off
    fn at 0 and at their unit vectors (exact, fn being affine); the declared ones are never
    formed: fn is evaluated at PROBES random points instead, at which each block's declarations
    must reproduce it (``matvar.check``, ValueError otherwise)."""
    terms = terms or []
    idx = layout.indices(names)
    x, unit, xp = _evaluation_points(layout, names, terms)
    nu = int(np.sum(unit))
    mats = fn(layout.unpack(x))
    out = []
    for j, F in enumerate(mats):
        F = (F + np.swapaxes(F, -1, -2)) / 2
        F0 = F[0].copy()  # a copy: a view would keep the whole evaluation stack alive
        declared = np.zeros(len(idx), dtype=bool)
        decl = terms[j] if terms else {}
        for nm in decl:
            declared |= np.isin(idx, layout.indices([nm]))
        Fu = F[1:1 + nu] - F0  # coefficients of the unit-evaluated variables
        keep = unit & ~declared
        nonzero = np.zeros(len(idx), dtype=bool)
        nonzero[keep] = np.any(Fu[keep[unit]] != 0, axis=(1, 2))
        used = declared | nonzero
        tl = [_declare(layout, name, LR, idx[used]) for name, LR in decl.items()]
        blk = LmiBlock(idx[used], F0, Fu[nonzero[unit]], group, tl)
        if blk.terms:  # the probes minus F0 and the undeclared variables' part: the declared part
            D = F[1 + nu:] - F0 - np.tensordot(xp[:, nonzero], blk.F, axes=1)
            check(blk.terms, xp[:, used], D)
        out.append(blk)
    return out


def _evaluation_points(layout: Layout, names: list[str], terms: list[dict]):
    """(x, unit, xp): the points at which ``_blocks_of`` evaluates fn, x (1 + Σ unit + probes, m):
    0, the unit vectors of the named variables at ``unit`` (those not declared in every returned
    matrix), then PROBES random points xp (probes, len(idx)) of all named variables (none without
    declarations)."""
    everywhere = set.intersection(*(set(t) for t in terms)) if terms else set()
    idx = layout.indices(names)
    unames = [nm for nm in names if nm not in everywhere]
    unit = np.isin(idx, layout.indices(unames)) if unames else np.zeros(len(idx), dtype=bool)
    nu, probes = int(np.sum(unit)), PROBES if terms else 0
    x = np.zeros((1 + nu + probes, layout.m))
    x[np.arange(1, 1 + nu), idx[unit]] = 1.0
    xp = np.random.default_rng(0).normal(size=(probes, len(idx)))
    x[1 + nu:, idx] = xp
    return x, unit, xp


def _declare(layout: Layout, name: str, LR, idx: np.ndarray) -> MatrixTerm:
    """The MatrixTerm of variable ``name`` (a 'sym' or 'mat' slot) with terms LR = [(L, R), …],
    positions counted in the block's variables idx; ValueError if one of its entries does not
    enter the block (zero coefficient, from the Kronecker form)."""
    kind, shape, sl = layout.slots[name]
    pos = np.flatnonzero((idx >= sl.start) & (idx < sl.stop))
    if kind == "sym":
        a, b = np.triu_indices(shape[0])
    else:
        a, b = np.divmod(np.arange(shape[0] * shape[1]), shape[1])
    L = np.stack([t[0] for t in LR])
    R = np.stack([t[1] for t in LR])
    t = MatrixTerm(pos, a, b, kind == "sym", L, R)
    if len(pos) != len(a) or np.any(sq_norms(t) == 0):
        raise ValueError(f"{name}: declared, but some of its entries do not enter the block")
    return t


def _emb(rows: int, nsub: int, size: int, p: int, M) -> np.ndarray:
    """(rows, nsub·size): M (rows×size) in column block p, zero elsewhere."""
    E = np.zeros((rows, nsub * size))
    E[:, p * size:(p + 1) * size] = M
    return E


def _mat(entries, B: int) -> np.ndarray:
    """A (B, r, c) stack from a nested list of scalars or (B,) arrays."""
    r, c = len(entries), len(entries[0])
    out = np.zeros((B, r, c))
    for a in range(r):
        for b in range(c):
            out[:, a, b] = entries[a][b]
    return out


def structured_problem(req, sc, eps: float, q_max: float):
    """(layout, c, blocks) of ``_build_structured(req, sc)`` without dropped groups (chapter 3),
    or of chapter 4's ``_build(req, sc)`` in the exactly decoupled form below.

    Chapter 4 (Kraiem 2022 (4.27) as ``lmi._build`` states it; scaled units of ``lmi._scale``).
    The full performance LMI per linearisation k is Θ_k ⪯ −εI with rows [z; ε_e; ε_d; γ-rows]::

        Θ_k = [[(A_zQ + B_zW)^s, [0; B_ε],  B_zd,k Q_d,  QC_zᵀ],
               [*,               (PA_e − W_eC_e)^s, D◇_xᵀ,  0],
               [*,               *,     −2Q_d + D◇_sym,    0],
               [*,               *,     *,              −γ̃²I]]

    With z ordered per actuator the (ε_c,i, ε̇_c,i, γ_i) rows form one 3×3 block Γ_i (as in
    chapter 3), coupled to the rest only through the ε̇_c,i row h_i,k = [b_i,k, (B̂_k Q_d)_i]
    (b_i,k: row i of B_ε; B̂_k = −M◇_k⁻¹ scaled, the ε̇_c rows of B_zd,k). The Schur complement on
    the Γ_i gives Ψ_k + Σ_i τ_i h_i,kᵀh_i,k ⪯ 0 with τ_i = −[(Γ_i + εI)⁻¹]_{ε̇ε̇} > 0 and
    Ψ_k = [[(PA_e − W_eC_e)^s, D◇_xᵀ], [D◇_x, −2Q_d + D◇_sym]] + εI. Because h_i,k depends on Q_d,
    the chapter 3 slack (s_i ≥ τ_i, term Σ s_i h_iᵀh_i) would be bilinear in (s, Q_d). Instead
    σ_i ≤ 1/τ_i, which is the Schur complement of −(Γ_i + εI) on its ε̇ entry, i.e.::

        −Γ_i − εI₃ − σ_i e₂e₂ᵀ ⪰ 0                       (3×3, per actuator, shared by all k)
        −[[Ψ_k, H_kᵀ], [H_k, −diag(σ)]] ⪰ 0,  H_k = [B_ε,k, B̂_kQ_d]   (n_e + 2n_q, per k)

    (the second is Ψ_k + H_kᵀdiag(σ)⁻¹H_k ⪯ 0 by Schur). Both are affine in every variable, and
    the pair is equivalent to Θ_k ⪯ −εI (the optimal σ_i = 1/τ_i does not depend on k): no
    term of (4.27) is dropped, unlike (4.41), which neglects the ε_d → z coupling B_zdQ_d. The
    largest cone is the observer disk (2n_e) or this block (n_e + 2n_q) instead of Θ's 4n_q + n_e.
    The other chapter 4 groups are ``_build``'s unchanged: Q_z's bounds, the pole regions,
    2Q̃_d − Ẽ_d⁻¹ ⪰ M̃◇_j and αM̃◇_j ⪯ Q̃_d ⪯ rM̃◇_j at every linearisation and sample, the
    budget c_e + Σc_z ≤ 1 − C_D, P ⪰ εI, Q_i ⪰ εI, Q_d ⪰ εI.
    """
    from sms_cli.synthesis.lmi import C_D, _bzd

    ndo = req.variant == "ndi_observer_ndo"
    m0 = sc.models[0]
    n_q, n_e, n_y = m0.n_q, m0.n_e, m0.n_y
    lay = Layout()
    for nm in ("q11", "q12", "q22", "wp", "wv"):
        lay.add(nm, "vec", (n_q,))
    lay.add("P", "sym", (n_e,))
    lay.add("We", "mat", (n_e, n_y))
    lay.add("g", "vec", (1,))
    lay.add("s", "vec", (n_q,))
    lay.add("c_e", "vec", (1,))
    track = req.tracking is not None
    if track:
        lay.add("c_z", "vec", (n_q,))
    if ndo:
        lay.add("Qd", "sym", (n_q,))
    creg = req.controller_region.scaled(sc.omega_c)
    oreg = req.observer_region.scaled(sc.omega_c)
    blocks: list[LmiBlock] = []
    ctrl = ["q11", "q12", "q22", "wp", "wv"]
    for i in range(n_q):
        ci = float(sc.d[i] / sc.c_s)

        def qn(V, i=i):
            B = V["q11"].shape[0]
            q11, q12, q22 = V["q11"][:, i], V["q12"][:, i], V["q22"][:, i]
            wp, wv = V["wp"][:, i], V["wv"][:, i]
            Q = _mat([[q11, q12], [q12, q22]], B)
            N = _mat([[q12, q22], [-wp, -wv]], B)  # A_z,i Q_i + B_z,i W_i
            return B, Q, N, wp, wv

        def perf(V, i=i, ci=ci):
            B, Q, N, _, _ = qn(V)
            q11, q12, g, s = V["q11"][:, i], V["q12"][:, i], V["g"][:, 0], V["s"][:, i]
            Gi = np.zeros((B, 3, 3))
            Gi[:, :2, :2] = N + np.swapaxes(N, 1, 2)
            Gi[:, 2, :2] = Gi[:, :2, 2] = ci * np.stack([q11, q12], axis=1)
            Gi[:, 2, 2] = -g
            if ndo:  # −Γ_i − εI − σ_i e₂e₂ᵀ ⪰ 0
                Mi = -Gi - eps * np.eye(3)
                Mi[:, 1, 1] -= s
                return [Mi]
            Mi = np.zeros((B, 4, 4))
            Mi[:, :3, :3] = -Gi - eps * np.eye(3)
            Mi[:, 1, 3] = Mi[:, 3, 1] = 1.0
            Mi[:, 3, 3] = s
            return [Mi]

        blocks += _blocks_of(lay, ctrl + ["g", "s"], perf, "performance")

        def ctrl_blocks(V):
            B, Q, N, _, _ = qn(V)
            return [q_max * np.eye(2) - Q] + ([Q - eps * np.eye(2)] if ndo else []) + region_blocks(N, Q, creg, eps)

        blocks += _blocks_of(lay, ctrl, ctrl_blocks, "controller_region")
        if req.accel_limit is not None and np.isfinite(req.accel_limit[i]):
            a = float(req.accel_limit[i]) / sc.omega_c**2 / sc.d[i]

            def auth(V, a=a):
                B, Q, N, wp, wv = qn(V)
                Mi = np.zeros((B, 3, 3))
                Mi[:, 0, 0] = a * a
                Mi[:, 0, 1:] = Mi[:, 1:, 0] = np.stack([wp, wv], axis=1)
                Mi[:, 1:, 1:] = Q
                return [Mi]

            blocks += _blocks_of(lay, ctrl, auth, "actuator_authority")
        if track:
            e, ed = float(req.tracking[i, 0]) / sc.d[i], float(req.tracking[i, 1]) / sc.omega_c / sc.d[i]
            corners = ([e, ed], [e, -ed]) if ed > 0 else ([e, 0.0],)

            def box(V, i=i, corners=corners):
                B, Q, N, _, _ = qn(V)
                out = []
                for v in corners:
                    Mc = np.zeros((B, 3, 3))
                    Mc[:, 0, 0] = V["c_z"][:, i]
                    Mc[:, 0, 1:] = Mc[:, 1:, 0] = v
                    Mc[:, 1:, 1:] = Q
                    out.append(Mc)
                return out

            blocks += _blocks_of(lay, ctrl + ["c_z"], box, "initial_conditions")
    Ee = np.diag(sc.T) @ req.E_e @ np.diag(sc.T)
    I_e = np.eye(n_e)
    blocks += _blocks_of(lay, ["P", "c_e"], lambda V: [V["c_e"][:, :, None] * Ee - V["P"]], "initial_conditions",
                         terms=[{"P": [(I_e, -I_e / 2)]}])
    budget = ["c_e"] + (["c_z"] if track else [])
    total = 1.0 - C_D if ndo else 1.0
    blocks += _blocks_of(lay, budget, lambda V: [(total - V["c_e"][:, 0] - (np.sum(V["c_z"], axis=1) if track else 0))
                                                 [:, None, None]], "initial_conditions")
    if ndo:
        blocks += _ndo_blocks(req, sc, lay, eps)
        blocks += _blocks_of(lay, ["P"], lambda V: [V["P"] - eps * np.eye(n_e)], "positivity",
                             terms=[{"P": [(I_e, I_e / 2)]}])
    # nonnegative variables (cvxpy's nonneg=True): g, s, c_e, c_z
    for nm in ("g", "s", "c_e") + (("c_z",) if track else ()):
        blocks += _blocks_of(lay, [nm], lambda V, nm=nm: [V[nm][:, k, None, None] for k in range(V[nm].shape[1])],
                             "positivity")
    for mdl in sc.models:
        def obs(V, mdl=mdl):
            P, We, s = V["P"], V["We"], V["s"]
            PA = P @ mdl.A_e - We @ mdl.C_e
            PAt = np.swapaxes(PA, 1, 2)
            region = region_blocks(PAt, P, oreg, eps)
            if ndo:
                return [_ndo_performance(V, PA + PAt, mdl, _bzd(mdl, sc) / sc.d[:, None], eps)] + region
            Phi = PA + PAt + np.einsum("ka,bk,kc->bac", mdl.B_eps, s, mdl.B_eps)
            return [-Phi - eps * np.eye(n_e)] + region

        terms = ([_ndo_terms(mdl, _bzd(mdl, sc) / sc.d[:, None])] if ndo else []) + _observer_region_terms(mdl, oreg)
        if not ndo:  # chapter 3's performance block: P and W_e as in (P A_e − W_e C_e)^s, sign −
            terms = [{"P": [(I_e, -mdl.A_e)], "We": [(I_e, mdl.C_e)]}] + terms
        blk = _blocks_of(lay, ["P", "We", "s"] + (["Qd"] if ndo else []), obs, "observer_region", terms=terms)
        blk[0].group = "performance"
        blocks += blk
    c = np.zeros(lay.m)
    c[lay.slots["g"][2]] = 1.0
    return lay, c, blocks


def _observer_region_terms(mdl, oreg) -> list[dict]:
    """Matrix-variable declarations of the observer's region blocks (``region_pattern`` with
    N = (P A_e − W_e C_e)ᵀ = A_eᵀP − C_eᵀW_eᵀ, X = P): c·N in (p, q) is P's term
    (c A_e in column block p, I in q) and W_e's term (−c I in q, C_e in p), which puts
    −c W_eC_e in (q, p) and its transpose in (p, q); c·X in (p, p) is P's (I, c/2·I) in p."""
    n_e = mdl.A_e.shape[0]
    I_e = np.eye(n_e)
    out = []
    for nsub, entries in region_pattern(oreg):
        P, We = [], []
        for kind, c, p, q in entries:
            if kind == "X":
                P.append((_emb(n_e, nsub, n_e, p, I_e), _emb(n_e, nsub, n_e, p, c / 2 * I_e)))
            else:
                P.append((_emb(n_e, nsub, n_e, p, c * mdl.A_e), _emb(n_e, nsub, n_e, q, I_e)))
                We.append((_emb(n_e, nsub, n_e, q, -c * I_e), _emb(mdl.C_e.shape[0], nsub, n_e, p, mdl.C_e)))
        out.append({"P": P, "We": We})
    return out


def _ndo_terms(mdl, Bhat) -> dict:
    """Matrix-variable declarations of ``_ndo_performance``'s block (rows ε_e, ε_d, ε̇_c): P as
    −(P A_e)^s and W_e as +(W_e C_e)^s in (ε_e, ε_e); Q_d as 2Q_d in (ε_d, ε_d) and as B̂_kQ_d in
    (ε̇_c, ε_d) with its transpose."""
    n_e, n_q = mdl.A_e.shape[0], Bhat.shape[0]
    n = n_e + 2 * n_q
    Le = np.zeros((n_e, n))
    Le[:, :n_e] = np.eye(n_e)
    Re_P = np.zeros((n_e, n))
    Re_P[:, :n_e] = -mdl.A_e
    Re_W = np.zeros((mdl.C_e.shape[0], n))
    Re_W[:, :n_e] = mdl.C_e
    Ed = np.zeros((n_q, n))
    Ed[:, n_e:n_e + n_q] = np.eye(n_q)
    Lc = np.zeros((n_q, n))
    Lc[:, n_e + n_q:] = Bhat.T
    return {"P": [(Le, Re_P)], "We": [(Le, Re_W)], "Qd": [(Ed, Ed), (Lc, Ed)]}


def _ndo_performance(V, PAs, mdl, Bhat, eps: float) -> np.ndarray:
    """−[[Ψ_k, H_kᵀ], [H_k, −diag(σ)]] (rows ε_e, ε_d, ε̇_c) for a stack of variables: the chapter 4
    performance block of ``structured_problem`` (PAs = (PA_e − W_eC_e)^s; Bhat = B̂_k, the ε̇_c
    rows of −B_zd,k: M̃◇_k⁻¹ in scaled units)."""
    Qd, s = V["Qd"], V["s"]
    B, n_e = PAs.shape[0], PAs.shape[1]
    n_q = Qd.shape[1]
    n = n_e + 2 * n_q
    Ds = mdl.D_sym if mdl.D_sym is not None else np.zeros((n_q, n_q))
    out = np.zeros((B, n, n))
    e, d, c = slice(0, n_e), slice(n_e, n_e + n_q), slice(n_e + n_q, n)
    out[:, e, e] = PAs
    out[:, d, e] = mdl.D_x
    out[:, e, d] = mdl.D_x.T
    out[:, d, d] = -2 * Qd + Ds
    H_d = -(Bhat @ Qd)  # B_zd,k Q_d on the ε̇_c rows
    out[:, c, e] = mdl.B_eps
    out[:, e, c] = mdl.B_eps.T
    out[:, c, d] = H_d
    out[:, d, c] = np.swapaxes(H_d, 1, 2)
    out[:, c, c] = -s[:, :, None] * np.eye(n_q)
    out[:, :n_e + n_q, :n_e + n_q] += eps * np.eye(n_e + n_q)
    return -out


def _ndo_blocks(req, sc, lay: Layout, eps: float) -> list[LmiBlock]:
    """``_build``'s NDO constraints: Q̃_d ⪰ εI, and at every linearisation and sample j
    2Q̃_d − (C_DẼ_d)⁻¹ ⪰ M̃◇_j (initial conditions) and αM̃◇_j ⪯ Q̃_d ⪯ rM̃◇_j (NDO poles)."""
    from sms_cli.synthesis.lmi import _ed_inv

    n_q = sc.models[0].n_q
    Edinv = _ed_inv(req, sc)
    ra = req.observer_region.scaled(sc.omega_c)
    out = _blocks_of(lay, ["Qd"], lambda V: [V["Qd"] - eps * np.eye(n_q)], "positivity")
    for m in sc.models + sc.samples:
        Ms = (m.M + m.M.T) / 2
        out += _blocks_of(lay, ["Qd"], lambda V, Ms=Ms: [2 * V["Qd"] - Edinv - Ms], "initial_conditions")
        out += _blocks_of(lay, ["Qd"], lambda V, Ms=Ms: [V["Qd"] - ra.alpha * Ms, ra.radius * Ms - V["Qd"]],
                          "observer_region")
    return out


def solve_structured(req, sc, eps: float, q_max: float, tol: float = 1e-8):
    """Solve the structured problem with ``sdp.solve_lmi``: ({name: value}, SdpResult, n_vars)."""
    with single_thread_blas():
        lay, c, blocks = structured_problem(req, sc, eps, q_max)
        res = solve_lmi(c, blocks, tol=tol)
    vals = {k: v[0] for k, v in lay.unpack(res.x[None, :]).items()}
    vals["g"] = float(vals["g"][0])
    return vals, res, lay.m
