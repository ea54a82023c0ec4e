"""A small primal–dual interior-point solver for LMI-form semidefinite programs.

Problem (the "LMI form", SDPT3's dual form)::

    minimise cᵀx   subject to   F_j(x) = F_j0 + Σ_i x_i F_ji ⪰ 0   for every block j

with x ∈ Rᵐ free. Written as max bᵀy, Z_j = C_j − Σ_i y_i A_ji ⪰ 0 (y = x, b = −c, C = F0,
A = −F) and its primal min Σ⟨C_j, X_j⟩ s.t. Σ_j ⟨A_ji, X_j⟩ = b_i, X_j ⪰ 0.

Method: infeasible-start path following with the Nesterov–Todd direction and Mehrotra's
predictor–corrector (Todd, Toh & Tütüncü, SIAM J. Optim. 8 (1998); Toh, Todd & Tütüncü,
SDPT3, Optim. Methods Softw. 11 (1999)). With the NT scaling G of each block (GᵀZG = G⁻¹XG⁻ᵀ
= D diagonal) every step solves the m×m Schur complement system M Δy = h with
M_ik = Σ_j ⟨GᵀA_jiG, GᵀA_jkG⟩.

Why a dedicated solver: the synthesis LMIs have few variables (m ≈ 450) and a few dense blocks
of 46 rows whose coefficient matrices A_ji have rank ≤ 4 (P enters as PA + AᵀP). Each A_ji is
stored factored, A_ji = Σ_r λ_r u_r u_rᵀ, so that ⟨GᵀA_iG, GᵀA_kG⟩ = Σ_rs λ_rλ_s (ũ_rᵀũ_s)²
with ũ = Gᵀu: one n×R matrix product per block and per iteration. A general conic solver
(Clarabel) factors a KKT system with a dense (n(n+1)/2)² block per PSD cone instead, which is
what made the synthesis take tens of seconds.

The solver does not certify infeasibility: it returns status 'optimal' only when the relative
gap and the primal and dual residuals are below ``tol``; anything else is 'failed', and the
caller falls back to a general solver (and, in every case, verifies the result itself).
Units: whatever the caller's data are in.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np


_BLAS_NAMES = [("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
               ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
               ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
               ("openblas_set_num_threads", "openblas_get_num_threads")]


@contextmanager
def single_thread_blas():
    """Run the block with every loaded OpenBLAS on one thread, then restore.

    The solver's products are many small (≤ 46×46) matrices: on a loaded 2-core machine,
    OpenBLAS threading made the pulsar solve 5× slower (12.2 s against 2.3 s). No-op where
    no OpenBLAS is found (e.g. not Linux)."""
    import ctypes

    handles = []
    try:
        paths = set()
        with open("/proc/self/maps") as fh:
            for line in fh:
                part = line.split()
                if len(part) >= 6 and "openblas" in part[-1].lower():
                    paths.add(part[-1])
        for path in sorted(paths):
            lib = ctypes.CDLL(path)
            for set_name, get_name in _BLAS_NAMES:
                if hasattr(lib, set_name) and hasattr(lib, get_name):
                    setter, getter = getattr(lib, set_name), getattr(lib, get_name)
                    handles.append((setter, int(getter())))
                    setter(1)
                    break
    except OSError:
        pass
    try:
        yield
    finally:
        for setter, n in handles:
            setter(n)


OPT_TOL = 1e-3  # relative optimality of cᵀx estimated from the multipliers (γ² to 0.1 %)


@dataclass
class LmiBlock:
    """F(x) = F0 + Σ_i x[idx[i]] F[i] ⪰ 0 (F0 n×n, F k×n×n, all symmetric)."""

    idx: np.ndarray
    F0: np.ndarray
    F: np.ndarray
    group: str = ""


@dataclass
class SdpResult:
    x: np.ndarray
    status: str  # 'optimal' | 'failed'
    iterations: int
    gap: float  # relative duality gap
    pinf: float  # relative primal (X) residual
    dinf: float  # relative dual (LMI) residual
    min_eig: float  # smallest eigenvalue of F_j(x) / ‖F_j‖ over the blocks, at the returned x
    time: float


class _Group:
    """Blocks of equal size n and variable count k, stacked: C (nb, n, n), A (nb, k, n, n) in the
    dual sign (Z = C − Σ_i y_idx[i] A_i), idx (nb, k)."""

    def __init__(self, blks: list[LmiBlock], rows: list[float], col: np.ndarray):
        self.n = blks[0].F0.shape[0]
        self.nb = len(blks)
        self.k = len(blks[0].idx)
        self.idx = np.stack([b.idx for b in blks]).astype(int)
        self.C = np.stack([r * (b.F0 + b.F0.T) / 2 for b, r in zip(blks, rows)])
        self.A = np.stack([-r * (b.F + np.transpose(b.F, (0, 2, 1))) / 2 * col[b.idx][:, None, None]
                           for b, r in zip(blks, rows)])
        self.iu, self.ju = np.triu_indices(self.n)
        self.w = np.where(self.iu == self.ju, 1.0, np.sqrt(2.0))  # svec: ⟨X, Y⟩ = svec(X)·svec(Y)

    def adjoint(self, y: np.ndarray, A: np.ndarray | None = None) -> np.ndarray:
        """(nb, n, n): Σ_i y_i A_i per block (A: the scaled Ã when given)."""
        A = self.A if A is None else A
        return np.einsum("bk,bkij->bij", y[self.idx], A)

    def apply(self, X: np.ndarray, S: np.ndarray | None = None) -> np.ndarray:
        """(nb, k): ⟨A_i, X_b⟩ (with S = svec(Ã) when given)."""
        if S is None:
            return np.einsum("bkij,bij->bk", self.A, X)
        return np.einsum("bkp,bp->bk", S, X[:, self.iu, self.ju] * self.w)

    def scaled(self, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ã = GᵀAG (nb, k, n, n) and svec(Ã) (nb, k, n(n+1)/2)."""
        nb, k, n = self.nb, self.k, self.n
        T = (self.A.reshape(nb, k * n, n) @ G).reshape(nb, k, n, n)
        T = np.matmul(np.transpose(G, (0, 2, 1))[:, None], T)
        return T, T[:, :, self.iu, self.ju] * self.w

    def scatter(self, M: np.ndarray, Mb: np.ndarray) -> None:
        if self.k * self.k * self.nb <= 4096:
            np.add.at(M, (self.idx[:, :, None], self.idx[:, None, :]), Mb)
        else:
            for b in range(self.nb):
                M[np.ix_(self.idx[b], self.idx[b])] += Mb[b]


def solve_lmi(c: np.ndarray, blocks: list[LmiBlock], tol: float = 1e-8, max_iter: int = 100,
              verbose: bool = False) -> SdpResult:
    """Minimise cᵀx subject to every block ⪰ 0 (see the module docstring)."""
    t0 = time.perf_counter()
    m = len(c)
    # exact rescalings: each block by a positive factor, each variable by a positive factor
    row = [1.0 / max(np.sqrt(np.sum(b.F0**2) + np.sum(b.F**2)), 1e-300) for b in blocks]
    col2 = np.zeros(m)
    for b, r in zip(blocks, row):
        np.add.at(col2, b.idx, r * r * np.sum(b.F**2, axis=(1, 2)))
    if np.any(col2 <= 0):
        raise ValueError("a variable appears in no LMI block")
    col = 1.0 / np.sqrt(col2)
    by_shape: dict[tuple[int, int], list[int]] = {}
    for j, b in enumerate(blocks):
        by_shape.setdefault((b.F0.shape[0], len(b.idx)), []).append(j)
    gs = [_Group([blocks[j] for j in js], [row[j] for j in js], col) for js in by_shape.values()]
    bvec = -np.asarray(c, dtype=float) * col
    bscale = max(1.0, float(np.linalg.norm(bvec)))
    bvec = bvec / bscale
    normC = 1.0 + np.sqrt(sum(np.sum(g.C**2) for g in gs))
    normb = 1.0 + np.linalg.norm(bvec)
    N = sum(g.n * g.nb for g in gs)
    X = [np.broadcast_to(np.eye(g.n) * max(10.0, np.sqrt(g.n)), g.C.shape).copy() for g in gs]
    Z = [x.copy() for x in X]
    y = np.zeros(m)
    status, it = "failed", 0
    gap = pinf = dinf = np.inf
    ng = len(gs)
    tr = lambda a: np.transpose(a, (0, 2, 1))  # noqa: E731
    for it in range(1, max_iter + 1):
        AX = np.zeros(m)
        Rd = []
        for q, g in enumerate(gs):
            np.add.at(AX, g.idx, g.apply(X[q]))
            Rd.append(g.C - Z[q] - g.adjoint(y))
        Rp = bvec - AX
        xz = sum(float(np.sum(X[q] * Z[q])) for q in range(ng))
        mu = xz / N
        pobj = sum(float(np.sum(g.C * X[q])) for q, g in enumerate(gs))
        dobj = float(bvec @ y)
        gap = xz / (1.0 + abs(pobj) + abs(dobj))
        pinf = float(np.linalg.norm(Rp)) / normb
        dinf = float(np.sqrt(sum(np.sum(r**2) for r in Rd))) / normC
        if verbose:
            print(f"{it:3d} pobj {pobj:+.6e} dobj {dobj:+.6e} gap {gap:.1e} pinf {pinf:.1e} dinf {dinf:.1e} mu {mu:.1e}")
        # y (the LMI point) must be feasible to tol and centred (gap < tol). The multipliers X
        # only estimate how far bᵀy is from the optimum: their residual stalls (1e-7 to 1e-5)
        # when the optimum is not strictly complementary, so they are held to OPT_TOL
        rel_obj = abs(pobj - dobj) / (1.0 + abs(pobj) + abs(dobj))
        if gap < tol and dinf < tol and pinf < OPT_TOL and rel_obj < OPT_TOL:
            status = "optimal"
            break
        if not np.all(np.isfinite([gap, pinf, dinf])) or np.linalg.norm(y) > 1e12:
            break
        # NT scaling per block: X = L Lᵀ, Z = R Rᵀ, RᵀL = U S Vᵀ, G = L V S^-½ (GᵀZG = G⁻¹XG⁻ᵀ = S)
        try:
            G, D = [], []
            for q in range(ng):
                L = np.linalg.cholesky(X[q])
                R = np.linalg.cholesky(Z[q])
                _, sv, Vt = np.linalg.svd(tr(R) @ L)
                G.append((L @ tr(Vt)) / np.sqrt(sv)[:, None, :])
                D.append(sv)
        except np.linalg.LinAlgError:
            break
        At, St = [], []
        M = np.zeros((m, m))
        for q, g in enumerate(gs):
            T, S = g.scaled(G[q])
            At.append(T)
            St.append(S)
            g.scatter(M, S @ tr(S))
        Rdt = [tr(G[q]) @ Rd[q] @ G[q] for q in range(ng)]
        try:
            from scipy.linalg import cho_factor, cho_solve

            Mr = M.copy()
            Mr[np.diag_indices(m)] += 1e-15 * np.max(np.diag(M))
            cf = cho_factor(Mr, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            break

        def direction(Rct):
            h = Rp.copy()
            for q, g in enumerate(gs):
                np.add.at(h, g.idx, -g.apply(Rct[q] - Rdt[q], St[q]))
            dy = cho_solve(cf, h, check_finite=False)
            for _ in range(2):  # iterative refinement: M is ill-conditioned near the optimum
                dy = dy + cho_solve(cf, h - M @ dy, check_finite=False)
            dZt = [Rdt[q] - g.adjoint(dy, At[q]) for q, g in enumerate(gs)]
            dXt = [Rct[q] - dZt[q] for q in range(ng)]
            return dy, dXt, dZt

        def max_step(dl):
            a = np.inf
            for q in range(ng):
                isd = 1.0 / np.sqrt(D[q])
                lmin = float(np.min(np.linalg.eigvalsh(dl[q] * isd[:, :, None] * isd[:, None, :])))
                if lmin < 0:
                    a = min(a, -1.0 / lmin)
            return a

        diagD = [np.einsum("bi,ij->bij", D[q], np.eye(gs[q].n)) for q in range(ng)]
        # predictor (σ = 0): R̃c = −D
        dy, dXt, dZt = direction([-d for d in diagD])
        ap = min(1.0, max_step(dXt))
        ad = min(1.0, max_step(dZt))
        xz_aff = sum(float(np.sum((diagD[q] + ap * dXt[q]) * (diagD[q] + ad * dZt[q]))) for q in range(ng))
        expo = max(1.0, 3.0 * min(ap, ad) ** 2)
        sigma = min(1.0, (xz_aff / xz) ** expo)
        # corrector: R̃c = (2σμI − 2D² − (ΔX̃ΔZ̃ + ΔZ̃ΔX̃)) ∘ Ω, Ω_ab = 1/(d_a + d_b)
        Rct = []
        for q in range(ng):
            d = D[q]
            corr = dXt[q] @ dZt[q]
            T = -(corr + tr(corr)) + 2 * (sigma * mu) * np.eye(gs[q].n) - 2 * diagD[q] * d[:, :, None]
            Rct.append(T / (d[:, :, None] + d[:, None, :]))
        dy, dXt, dZt = direction(Rct)
        ap = max_step(dXt)
        ad = max_step(dZt)
        step = 0.9 + 0.09 * min(min(ap, 1.0), min(ad, 1.0))
        ap = min(1.0, step * ap)
        ad = min(1.0, step * ad)
        for q, g in enumerate(gs):
            X[q] = X[q] + ap * (G[q] @ dXt[q] @ tr(G[q]))
            X[q] = (X[q] + tr(X[q])) / 2
            Z[q] = Z[q] + ad * (Rd[q] - g.adjoint(dy))
            Z[q] = (Z[q] + tr(Z[q])) / 2
        y = y + ad * dy
        if verbose:
            print(f"    steps {ap:.3f} {ad:.3f} sigma {sigma:.2e}")
        if max(ap, ad) < 1e-8:
            break
    x = y * col
    worst = np.inf
    for b in blocks:
        Fx = b.F0 + np.einsum("k,kab->ab", x[b.idx], b.F)
        nrm = max(np.linalg.norm(b.F0), 1e-300) if len(b.idx) == 0 else max(np.linalg.norm(Fx), 1e-300)
        worst = min(worst, float(np.min(np.linalg.eigvalsh((Fx + Fx.T) / 2))) / nrm)
    return SdpResult(x, status, it, gap, pinf, dinf, worst, time.perf_counter() - t0)
