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

Why a dedicated solver: the synthesis LMIs have few variables (m ≈ 450 for pulsar_simple) and
a few dense blocks of up to 2 n_e rows whose coefficient matrices A_ji have rank ≤ 4 (P enters
as PA + AᵀP). Each A_ji is factored once, A_ji = Σ_r λ_r u_r u_rᵀ, so that the scaled
GᵀA_jiG = Σ_r λ_r ũ_rũ_rᵀ (ũ = Gᵀu) costs O(n²) per variable instead of O(n³). A general conic
solver (Clarabel) factors a KKT system with a dense (n(n+1)/2)² block per PSD cone instead,
which is what made the synthesis take tens of seconds.

Matrix variables in Kronecker form (``matvar``): where a block declares that some variables are
the entries of a matrix variable X entering as Σ_s (L_sᵀXR_s + R_sᵀXᵀL_s) (the chapter 4 LMI's
P_ε, W_e and Q_d, declared by ``direct``), those variables' part of M is built from the
products L_sG, R_sG without any scaled matrix GᵀA_iG: for P_ε (n_e(n_e+1)/2 = 1128 variables at
Kraiem 2022's size) O(n_e⁴) per variable pair instead of O(n_e⁴ n²) through S. The products
with S (residuals, the scaled adjoint) are applied matrix-free as Gᵀ(Σ_s L_sᵀXR_s + …)G. The
declared variables' dense coefficients are never stored (``LmiBlock.F`` holds the others'): the
scalings, A(x), its adjoint, the Farkas measure and the final positivity check use the Kronecker
form too, so memory grows with the blocks' sizes, not with (declared variables) × n² per block
(13.7 GB at |T| = 20 on chapter 4 before).

Accuracy of the Newton system (``_Schur``): M = SᵀS with S the scaled coefficients. While M
is well conditioned it is formed and Cholesky-factored; once the step's own residual
h − Sᵀ(SΔy) (evaluated through S, it is the primal residual the step leaves) exceeds a tenth
of the current primal residual (or 1e-6 ‖b‖), the solver switches to a QR factorisation of S
for the rest of the run. With declared matrix variables the formed M's Cholesky factor (shifted
until it factors) instead preconditions conjugate gradients on SᵀSΔy = h, whose products go
through the blocks; only a system whose CG misses the target takes the QR route (CG preconditioned
by the R of a random sketch of S, ``sketch``; then S's own QR if that misses too), and CG is tried
again at the next iteration (chapter 4 at the thesis's size: no QR step at
|T| = 1; QR for 8 of about 60 systems at |T| = 3). Near the optimum of the synthesis problems
the NT scaling of the observer blocks (lightly damped flexible modes) reaches cond(G) ~ 1e3,
cond(M) ~ 1e16: the formed M is then indefinite in floating point, and the Cholesky-only version stalled at a primal residual of
~1e-3 from LMI size 37 on (with γ̃² 1 % above the optimum).

Where even the QR route saturates (cond(S) ~ 1e15: from LMI size ~99 the gap stalls near 7e-7),
the multiplier step is shortened so that the certificate's residual cannot grow (it used to
jump to 1e2), and the run stops after four iterations without halving the gap, returning the
best iterate (smallest gap among those with feasible residuals) with status 'failed'.

When μ grows at five iterations in a row without the gap halving, the run is diverging (what an
infeasible LMI does: the chapter 4 test data at the thesis size with too loose observer
initial-error bounds ran for minutes with γ̃² → 1e5); it stops with status 'failed' and the
multipliers' Farkas measure (``SdpResult.farkas``), which bounds from below the size of any
feasible point.

The solver does not certify infeasibility: it returns status 'optimal' only when the relative
gap and the LMI (dual) residual are below ``tol`` and the multipliers' residual and objective
mismatch below OPT_TOL; anything else is 'failed' (``gap`` says how close it came), and the
caller falls back to a general solver (and, in every case, verifies the result itself).
Units: whatever the caller's data are in.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
# imported here, not lazily, so that scipy's own OpenBLAS is loaded before single_thread_blas
# looks for the loaded BLAS libraries (a library loaded inside the block keeps its threads)
from scipy.linalg import cho_factor, cho_solve, qr, solve_triangular

from sms_cli.synthesis.matvar import MatrixTerm, PairSum, Stacked, coefficients, sq_norms, value


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


_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc mallopt parameters
_GLIBC_DEFAULT = 128 * 1024  # both thresholds' glibc default (bytes)


@contextmanager
def reuse_freed_memory(mmap_max: int = 32 * 2**20, trim: int = 256 * 2**20):
    """Run the block with glibc's malloc serving allocations below ``mmap_max`` bytes from the
    heap and keeping up to ``trim`` bytes of freed heap for reuse, then set both back to glibc's
    defaults (fixed from then on, not glibc's adaptive mmap threshold). The solver allocates and
    frees the same few-MB temporaries every iteration; served by mmap, each is page-faulted in
    afresh (at n_e 31, 1.34 s CPU against 1.05 s with reuse). No-op where glibc is not found."""
    import ctypes

    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):
        yield
        return
    mallopt(_M_MMAP_THRESHOLD, mmap_max)
    mallopt(_M_TRIM_THRESHOLD, trim)
    try:
        yield
    finally:
        mallopt(_M_MMAP_THRESHOLD, _GLIBC_DEFAULT)
        mallopt(_M_TRIM_THRESHOLD, _GLIBC_DEFAULT)


OPT_TOL = 1e-3  # relative optimality of cᵀx estimated from the multipliers (γ² to 0.1 %)
# A run that stops short of tol returns its best iterate as 'optimal_inaccurate' when that iterate meets the reduced
# tolerances of Clarabel 0.11's AlmostSolved (reduced_tol_gap_rel 5e-5, reduced_tol_feas 1e-4), which the Clarabel
# path (cvxpy's 'optimal_inaccurate') already accepts; every result is verified independently of its status anyway.
NEAR_GAP = 5e-5
NEAR_FEAS = 1e-4


@dataclass
class LmiBlock:
    """F(x) = F0 + Σ_i x[idx[i]] F_i ⪰ 0 (F0 n×n, all symmetric) over the k variables idx.
    ``terms``: optional declarations that some of the variables (positions ``t.pos`` in idx) are a
    matrix variable's entries (``matvar``); their coefficients are never stored, the solver
    handles them in Kronecker form. F (k − declared, n, n) holds the coefficients of the other
    variables, at the positions ``rest()`` in order (all k when nothing is declared)."""

    idx: np.ndarray
    F0: np.ndarray
    F: np.ndarray
    group: str = ""
    terms: list[MatrixTerm] = field(default_factory=list)

    def __post_init__(self):
        if len(self.F) != len(self.rest()):
            raise ValueError(f"LmiBlock: F holds {len(self.F)} coefficient matrices, the undeclared "
                             f"variables are {len(self.rest())}")

    def rest(self) -> np.ndarray:
        """Positions (in idx) of the variables no term declares, in order: F's rows."""
        free = np.ones(len(self.idx), dtype=bool)
        for t in self.terms:
            free[t.pos] = False
        return np.flatnonzero(free)

    def sq_norms(self) -> np.ndarray:
        """(k,): ‖F_i‖_F² per variable (declared ones from the Kronecker form)."""
        out = np.zeros(len(self.idx))
        out[self.rest()] = np.sum(self.F**2, axis=(1, 2))
        for t in self.terms:
            out[t.pos] += sq_norms(t)
        return out

    def value(self, x: np.ndarray) -> np.ndarray:
        """F(x) (n×n) at the global variables x (declared ones in Kronecker form)."""
        xb = x[self.idx]
        out = self.F0 + np.tensordot(xb[self.rest()], self.F, axes=1)
        for t in self.terms:
            out = out + value(t, xb[t.pos])
        return out

    def dense(self) -> np.ndarray:
        """(k, n, n): every variable's coefficients, the declared ones formed (``matvar.coefficients``:
        for the solver's dense methods and tests only); F itself when nothing is declared."""
        if not self.terms:
            return self.F
        out = np.empty((len(self.idx),) + self.F0.shape)
        out[self.rest()] = self.F
        for t in self.terms:
            out[t.pos] = coefficients(t)
        return out


@dataclass
class SdpResult:
    x: np.ndarray
    status: str  # 'optimal' | 'optimal_inaccurate' (the best iterate within NEAR_GAP, NEAR_FEAS) | 'failed'
    iterations: int
    gap: float  # relative duality gap
    pinf: float  # relative primal (X) residual
    dinf: float  # relative dual (LMI) residual
    min_eig: float  # smallest eigenvalue of F_j(x) / ‖F_j‖ over the blocks, at the returned x
    time: float
    # runs that did not converge: ‖AX̂‖ of the last multipliers (``_farkas``): no point y of the
    # LMIs (solver's scaled variables) has ‖y‖ < 1/farkas; inf when X proves nothing
    farkas: float = np.inf
    qr_steps: int = 0  # iterations whose Newton systems took the QR route (S's own QR, or its sketch's: QR_ROUTE)


class _Group:
    """Blocks of equal size n and variable count k, stacked: C (nb, n, n), idx (nb, k). The
    variables declared as matrix variables by every block alike (``mv``, ``matvar.Stacked``) are
    kept in Kronecker form; the others ("rest", positions ``rest``, global ``ridx`` (nb, kr)) as
    A (nb, kr, n, n) in the dual sign (Z = C − Σ_i y_idx[i] A_i)."""

    def __init__(self, blks: list[LmiBlock], rows: list[float], col: np.ndarray):
        self.n = blks[0].F0.shape[0]
        self.nb = len(blks)
        self.k = len(blks[0].idx)
        self.idx = np.stack([b.idx for b in blks]).astype(int)
        self.C = np.stack([r * (b.F0 + b.F0.T) / 2 for b, r in zip(blks, rows)])
        self.mv = self._common_terms(blks, rows, col)
        rest = np.ones(self.k, dtype=bool)
        for t in self.mv:
            rest[t.pos] = False
        self.rest = np.flatnonzero(rest)
        self.ridx = self.idx[:, self.rest]
        self.kr = len(self.rest)
        self.fac: list = [(None, None)] * len(self.mv)  # (L G, R G) per matrix variable, set by ``scaled``
        # the rest's coefficients: the blocks' F when the declarations are kept (F is then exactly
        # the rest), else every variable's (formed from any declarations the group cannot keep)
        Fr = [b.F if self.mv else b.dense() for b in blks]
        self.A = np.stack([-r * (F + np.transpose(F, (0, 2, 1))) / 2 * col[b.idx[self.rest]][:, None, None]
                           for b, r, F in zip(blks, rows, Fr)])
        self.iu, self.ju = np.triu_indices(self.n)
        self.w = np.where(self.iu == self.ju, 1.0, np.sqrt(2.0))  # svec: ⟨X, Y⟩ = svec(X)·svec(Y)
        # low-rank factors A_i = Σ_r λ_r u_r u_rᵀ (P enters the observer blocks as PA + AᵀP:
        # rank ≤ 4 for any n), used by ``scaled`` when the rank is small against n
        self.lam = self.U = None
        if self.n >= 8 and self.kr:
            lam, vec = np.linalg.eigh(self.A)
            big = np.abs(lam) > 1e-12 * np.max(np.abs(lam), axis=-1, keepdims=True)
            R = int(np.max(np.sum(big, axis=-1)))
            if 4 * R <= self.n:
                order = np.argsort(-np.abs(lam), axis=-1)[..., :R]
                self.lam = np.take_along_axis(lam, order, axis=-1)  # (nb, k, R)
                self.U = np.swapaxes(np.take_along_axis(vec, order[..., None, :], axis=-1), -1, -2)  # (nb, k, R, n)

    def _common_terms(self, blks: list[LmiBlock], rows: list[float], col: np.ndarray) -> list[Stacked]:
        """The matrix variables every block of the group declares alike (same entries, same
        global variables, same term count); none otherwise (all variables then stay dense)."""
        b0 = blks[0]
        for b in blks[1:]:
            if len(b.terms) != len(b0.terms):
                return []
            for t, t0 in zip(b.terms, b0.terms):
                if (t.sym != t0.sym or t.L.shape != t0.L.shape or t.R.shape != t0.R.shape
                        or not np.array_equal(t.pos, t0.pos) or not np.array_equal(t.a, t0.a)
                        or not np.array_equal(t.b, t0.b) or not np.array_equal(b.idx[t.pos], b0.idx[t0.pos])):
                    return []
        return [Stacked([b.terms[j] for b in blks], rows, col, b0.idx[t.pos].astype(int))
                for j, t in enumerate(b0.terms)]

    def adjoint(self, y: np.ndarray, A: np.ndarray | None = None) -> np.ndarray:
        """(nb, n, n): Σ_i y_i A_i per block (scaled, Σ_i y_i Ã_i, when A = Ã of the rest is given;
        the matrix variables' then from ``fac``)."""
        nb, kr, n = self.nb, self.kr, self.n
        out = np.zeros((nb, n, n))
        if kr:
            out = (y[self.ridx][:, None, :] @ (self.A if A is None else A).reshape(nb, kr, n * n)).reshape(nb, n, n)
        if self.mv:
            out = out + sum(t.adjoint(y, None if A is None else f) for t, f in zip(self.mv, self.fac))
        return out

    def apply(self, X: np.ndarray, S: np.ndarray | None = None) -> np.ndarray:
        """(nb, k): ⟨A_i, X_b⟩ (⟨Ã_i, X_b⟩ with S = svec(Ã) of the rest given; the matrix
        variables' then from ``fac``)."""
        out = np.empty((self.nb, self.k))
        if not self.kr:
            pass
        elif S is None:
            out[:, self.rest] = (self.A.reshape(self.nb, self.kr, -1) @ X.reshape(self.nb, -1, 1))[:, :, 0]
        else:
            out[:, self.rest] = (S @ (X[:, self.iu, self.ju] * self.w)[:, :, None])[:, :, 0]
        for t, f in zip(self.mv, self.fac):
            out[:, t.pos] = t.apply(X, None if S is None else f)
        return out

    def add_terms(self, M: np.ndarray, At: np.ndarray, sums: dict) -> None:
        """The matrix variables' part of Σ_b S_b S_bᵀ: their pairs into ``sums`` (``PairSum`` per
        pair of variables, shared by the groups, added to M by ``schur_matrix``), their cross
        products with the rest's scaled At into M."""
        fac = self.fac
        for u, (tu, fu) in enumerate(zip(self.mv, fac)):
            for tv, fv in zip(self.mv[u:], fac[u:]):
                key = (int(tu.gidx[0]), int(tv.gidx[0]))
                if key not in sums:
                    sums[key] = PairSum(tu, tv)
                sums[key].add(fu, fv)
            if self.kr:
                X = tu.cross(*fu, At)  # (nb, p, kr)
                np.add.at(M, (tu.gidx[None, :, None], self.ridx[:, None, :]), X)
                np.add.at(M, (self.ridx[:, :, None], tu.gidx[None, None, :]), np.swapaxes(X, 1, 2))

    def scaled(self, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ã = GᵀAG (nb, kr, n, n) and svec(Ã) (nb, kr, n(n+1)/2) of the rest; the matrix
        variables' scaled factors (L G, R G) are kept as ``fac`` for this G."""
        self.fac = [t.scaled_factors(G) for t in self.mv]
        nb, k, n = self.nb, self.kr, self.n
        if self.U is not None:  # Ã_i = Σ_r λ_r ũ_r ũ_rᵀ, ũ = Gᵀu: O(n²R) per variable, not O(n³)
            R = self.U.shape[2]
            Ut = (self.U.reshape(nb, k * R, n) @ G).reshape(nb, k, R, n)
            T = np.swapaxes(Ut * self.lam[..., None], -1, -2) @ Ut
        else:
            T = (self.A.reshape(nb, k * n, n) @ G).reshape(nb, k, n, n)
            T = np.matmul(np.transpose(G, (0, 2, 1))[:, None], T)
        return T, T[:, :, self.iu, self.ju] * self.w

    def add_gram(self, M: np.ndarray, S: np.ndarray) -> None:
        """M[ridx_b, ridx_b] += S_b S_bᵀ for every block b (S = svec(Ã) of the rest, (nb, kr, p))."""
        if self.kr * self.kr * self.nb <= 4096:
            np.add.at(M, (self.ridx[:, :, None], self.ridx[:, None, :]), S @ np.transpose(S, (0, 2, 1)))
            return
        for b in range(self.nb):
            M[np.ix_(self.ridx[b], self.ridx[b])] += S[b] @ S[b].T  # numpy calls syrk for A Aᵀ


def schur_matrix(gs: list[_Group], St: list[np.ndarray], m: int, At: list[np.ndarray]) -> np.ndarray:
    """The formed M = SᵀS (m×m): Gram matrices of the rest's svec(Ã) plus, per group with matrix
    variables, their Kronecker-form part (At/St: the rest's Ã and svec(Ã) from ``_Group.scaled``)."""
    M = np.zeros((m, m))
    sums: dict = {}
    for q, (g, S) in enumerate(zip(gs, St)):
        g.add_gram(M, S)
        if g.mv:
            g.add_terms(M, At[q], sums)
    for ps in sums.values():
        Muv = ps.matrix()
        M[np.ix_(ps.u.gidx, ps.v.gidx)] += Muv
        if ps.u.gidx[0] != ps.v.gidx[0]:
            M[np.ix_(ps.v.gidx, ps.u.gidx)] += Muv.T
    return M


class _Schur:
    """The Newton system M Δy = h, M = SᵀS, S the (Σ n(n+1)/2) × m matrix whose column i
    stacks svec(G_jᵀA_jiG_j) over the blocks j (kept per group, for the dense "rest" variables
    only; for 'qr', formed a chunk of blocks at a time, ``_qr_factor``).

    Residuals h − Sᵀ(SΔy) are always evaluated through the scaled blocks (``matvec``), never
    through a formed M. Method 'chol': Cholesky of the formed M (the matrix variables' part in
    Kronecker form, ``_Group.add_terms``). Method 'qr': S = QR (Householder, R only) and the
    corrected semi-normal equations RᵀR Δy = h, whose accuracy depends on cond(S) = cond(M)^½
    (about twice the cost of forming M; the matrix variables' columns of S are formed for it
    only, one block at a time). Method 'sketch': R of a random sketch Ω S (``_sketch_factor``), as
    accurate a preconditioner as S's own R for a fraction of its cost. Each is refined through S
    (``solve``): 'qr' by plain iterative refinement; 'chol' with matrix variables and 'sketch' by
    conjugate gradients preconditioned with the factor."""

    def __init__(self, gs: list[_Group], St: list[np.ndarray], m: int, method: str,
                 At: list[np.ndarray] | None = None):
        self.gs, self.St, self.m, self.method, self.At = gs, St, m, method, At
        self.cg = any(g.mv for g in gs)
        if method in ("qr", "sketch"):
            self.R = (_qr_factor if method == "qr" else _sketch_factor)(gs, St, m)
            d = np.diag(self.R)
            if not np.all(np.isfinite(d)):
                raise np.linalg.LinAlgError("non-finite Schur complement")
            # a (numerically) dependent column: floor its pivot (a tiny Tikhonov term on that
            # direction); the refinement through S then recovers what S determines
            floor = 1e-15 * float(np.max(np.abs(d)))
            small = np.abs(d) < floor
            self.R[small, small] = floor
        else:
            M = schur_matrix(gs, St, m, At)
            top = np.max(np.diag(M))
            M[np.diag_indices(m)] += 1e-15 * top
            if not self.cg:
                self.cf = cho_factor(M, check_finite=False)
                return
            # the formed M is only the preconditioner here: when round-off makes it indefinite,
            # shift it until it factors (CG through S recovers the accuracy)
            for shift in (0.0, 1e-13, 1e-11, 1e-9, 1e-7):
                try:
                    if shift:
                        M[np.diag_indices(m)] += shift * top
                    self.cf = cho_factor(M, check_finite=False)
                    return
                except np.linalg.LinAlgError:
                    continue
            raise np.linalg.LinAlgError("Schur complement not positive definite")

    def matvec(self, v: np.ndarray) -> np.ndarray:
        """SᵀS v, group by group."""
        out = np.zeros(self.m)
        for q, (g, S) in enumerate(zip(self.gs, self.St)):
            if g.mv:  # ⟨Ã_i, Σ_k v_k Ã_k⟩ through the blocks (the matrix variables' S is never formed)
                Zt = g.adjoint(v, self.At[q])
                np.add.at(out, g.idx, g.apply(Zt, S))
                continue
            u = v[g.ridx][:, None, :] @ S
            np.add.at(out, g.ridx, (S @ np.transpose(u, (0, 2, 1)))[:, :, 0])
        return out

    def _base(self, h: np.ndarray) -> np.ndarray:
        if self.method in ("qr", "sketch"):
            w = solve_triangular(self.R, h, trans="T", check_finite=False)
            return solve_triangular(self.R, w, check_finite=False)
        return cho_solve(self.cf, h, check_finite=False)

    def solve(self, h: np.ndarray, target: float = 0.0, refine: int = 2,
              cg_target: float = 0.0) -> tuple[np.ndarray, float]:
        """(Δy, ‖h − SᵀSΔy‖), refined through S until the residual is below ``target`` (at most
        ``refine`` times); with matrix variables ('chol'), conjugate-gradient steps (at most
        ``CG_MAX``, each two products with S, so stopped at the looser ``cg_target``)."""
        dy = self._base(h)
        r = h - self.matvec(dy)
        err = float(np.linalg.norm(r))
        if self.cg and self.method == "chol":
            return self._pcg(h, dy, r, err, max(target, cg_target))
        if self.method == "sketch":  # R of a sketch of S: a preconditioner only
            return self._pcg(h, dy, r, err, target)
        for _ in range(refine):
            if err <= target:
                break
            dy = dy + self._base(r)
            r = h - self.matvec(dy)
            err = float(np.linalg.norm(r))
        return dy, err

    def _pcg(self, h, dy, r, err, target):
        """Conjugate gradients on SᵀSΔy = h from dy, preconditioned by the formed M's Cholesky
        factor; returns the iterate with the smallest true residual (recomputed through S)."""
        best = (err, dy)
        z = self._base(r)
        p = z.copy()
        rz = float(r @ z)
        for k in range(CG_MAX):
            if err <= target or rz <= 0:
                break
            w = self.matvec(p)
            pw = float(p @ w)
            if not pw > 0:
                break
            alpha = rz / pw
            dy = dy + alpha * p
            r = r - alpha * w  # recursive residual; the true one (through S) when it looks done
            err = float(np.linalg.norm(r))
            if err <= target or k % 10 == 9 or k == CG_MAX - 1:
                r = h - self.matvec(dy)
                err = float(np.linalg.norm(r))
                if err < best[0]:
                    best = (err, dy)
            z = self._base(r)
            rz_new = float(r @ z)
            p = z + (rz_new / rz) * p
            rz = rz_new
        return best[1], best[0]


CG_MAX = 60  # conjugate-gradient steps per Newton system (matrix variables only)
QR_ROUTE = "sketch"  # when Cholesky of the formed M is not accurate enough: "sketch" (then "qr" if it misses) or "qr"
QR_CHUNK_BYTES = 256 * 2**20  # rows of S factored together by ``_qr_factor`` (bytes of one chunk)


def _block_rows(g: _Group, S: np.ndarray, b: int, m: int) -> np.ndarray:
    """(n(n+1)/2, m): block b's rows of S, svec(G_bᵀA_iG_b) in column i (the rest's from S, the
    matrix variables' formed here from the scaled factors ``fac``, one block at a time)."""
    rows = np.zeros((S.shape[2], m))
    rows[:, g.ridx[b]] = S[b].T
    for t, (LG, RG) in zip(g.mv, g.fac):
        At_b = coefficients(MatrixTerm(t.pos, t.a, t.b, t.sym, LG[b], RG[b]))
        rows[:, t.gidx] = (At_b[:, g.iu, g.ju] * g.w * t.col[:, None]).T
    return rows


def _row_chunks(gs: list[_Group], St: list[np.ndarray], m: int):
    """S's rows (``_block_rows``), block by block, in chunks of about QR_CHUNK_BYTES (each (rows, m)): S is never
    formed whole (at Kraiem 2022's size S has ~7300 rows per linearisation: 3.4 GB at |T| = 40)."""
    per = max(2 * m, QR_CHUNK_BYTES // (8 * m))
    chunk: list[np.ndarray] = []
    size = 0
    for g, S in zip(gs, St):
        for b in range(g.nb):
            chunk.append(_block_rows(g, S, b, m))
            size += chunk[-1].shape[0]
            if size >= per:
                yield np.concatenate(chunk)
                chunk, size = [], 0
    if chunk:
        yield np.concatenate(chunk)


def _qr_factor(gs: list[_Group], St: list[np.ndarray], m: int) -> np.ndarray:
    """R (m×m) of S = QR (Householder, R only), S's rows taken in chunks (``_row_chunks``): R of [R_prev; chunk] is
    R of every row so far (Q orthogonal). A problem whose S fits in one chunk is factored in one go."""
    R = np.zeros((0, m))
    for chunk in _row_chunks(gs, St, m):
        R = qr(np.concatenate([R, chunk]), mode="r", overwrite_a=True, check_finite=False)[0][:m]
    return R


SKETCH_ROWS = 4  # rows of the sketch of S per column (s = SKETCH_ROWS·m)
SKETCH_SLICE = 512  # sketch rows formed together (the matrix variables' products are (2S, r, SKETCH_SLICE) per block)
SKETCH_BUDGET = 2**22  # doubles of the rest's products Ã_i H formed together, (blocks, kr·n, SKETCH_SLICE)


def _sketch_factor(gs: list[_Group], St: list[np.ndarray], m: int, seed: int = 0) -> np.ndarray:
    """R (m×m) of the QR of Ω S (``sketch``, s = SKETCH_ROWS·m rows): S R⁻¹ is then well conditioned whatever
    cond(S) (up to 1/ε), so R is a preconditioner of SᵀS for conjugate gradients (Blendenpik's idea, Avron,
    Maymounkov & Toledo 2010) at the cost of a QR of s instead of all of S's rows."""
    s = SKETCH_ROWS * m
    if sum(g.nb * S.shape[2] for g, S in zip(gs, St)) <= 2 * s:  # S itself is hardly taller: its own QR
        return _qr_factor(gs, St, m)
    rng = np.random.default_rng(seed)
    SK = sketch(gs, St, m, s, lambda shape: (_signs(rng, shape), _signs(rng, shape)))
    return qr(SK.T, mode="r", overwrite_a=True, check_finite=False)[0][:m]


def _signs(rng: np.random.Generator, shape: tuple) -> np.ndarray:
    """Independent random signs ±1 (Rademacher), from the generator's bytes (ten times cheaper than normals)."""
    n = int(np.prod(shape))
    return np.unpackbits(np.frombuffer(rng.bytes((n + 7) // 8), np.uint8), count=n).reshape(shape) * 2.0 - 1.0


def sketch(gs: list[_Group], St: list[np.ndarray], m: int, s: int, draw) -> np.ndarray:
    """(m, s): (Ω S)ᵀ for the bilinear sketch Ω: row q of Ω takes each block's part of a column of S, svec(Ã_i),
    to g_qᵀ Ã_i h_q / √s, with g_q, h_q independent random n-vectors of unit covariance drawn per block
    (``draw(shape)`` returns the pair G, H, each ``shape`` = (blocks, n, rows); ``_sketch_factor`` draws random
    signs). For independent g, h with E[ggᵀ] = E[hhᵀ] = I, E[(gᵀAh)(gᵀBh)] = tr(AB) = ⟨A, B⟩,
    so E[ΩᵀΩ] = I: an isotropic sketch, like a Gaussian one, whose rows need no coefficient matrix. A declared
    matrix variable's entries give gᵀÃ_jh as products of the rows of L G g, L G h, R G g, R G h
    (``Stacked.add_bilinear``: O(S (r + c) n) per sketch row and block, against the n² entries of each Ã_j that a
    sketch of S's formed rows needs); the rest's from their svec rows St. Kraiem 2022's chapter 4 problem at
    |T| = 4, a late Newton system: cond(S R⁻¹) 2.98 with random signs (3.04 with the sparse sign sketch of S's
    formed rows that this replaced, 8 nonzeros per column, at the same s)."""
    SK = np.zeros((m, s))
    for g, S in zip(gs, St):
        per = max(1, SKETCH_BUDGET // (g.kr * g.n * SKETCH_SLICE)) if g.kr else g.nb
        # a variable whose entries are consecutive (direct.Layout's slots are) is summed into SK's rows in place
        contiguous = [bool(np.all(np.diff(t.gidx) == 1)) for t in g.mv]
        for b0 in range(0, g.nb, per):
            blocks = range(b0, min(b0 + per, g.nb))
            if g.kr:  # the rest's Ã_i from their svec rows (a row is w ∘ the upper triangle)
                A = np.zeros((len(blocks), g.kr, g.n, g.n))
                A[..., g.iu, g.ju] = S[b0:b0 + len(blocks)] / g.w
                A[..., g.ju, g.iu] = A[..., g.iu, g.ju]
                A = A.reshape(len(blocks), g.kr * g.n, g.n)
            for q0 in range(0, s, SKETCH_SLICE):
                q = slice(q0, min(q0 + SKETCH_SLICE, s))
                G, H = draw((len(blocks), g.n, q.stop - q.start))
                if g.kr:  # gᵀÃ_ih = Σ (Ã_i H) ∘ G over the block's rows
                    rest = np.einsum("bkiq,biq->bkq", (A @ H).reshape(len(blocks), g.kr, g.n, -1), G)
                    for i, b in enumerate(blocks):
                        SK[g.ridx[b], q] += rest[i]
                for t, (LG, RG), inplace in zip(g.mv, g.fac, contiguous):  # the group's blocks share the entries
                    out = SK[t.gidx[0]:t.gidx[-1] + 1, q] if inplace else np.zeros((len(t.gidx), q.stop - q.start))
                    for i, b in enumerate(blocks):
                        t.add_bilinear(LG[b], RG[b], G[i], H[i], out)
                    if not inplace:
                        SK[t.gidx, q] += out
    return SK / np.sqrt(s)


def groups(blocks: list[LmiBlock], m: int, declared: bool = True) -> tuple[list[_Group], np.ndarray]:
    """The blocks grouped by (size, variable count) after the exact rescalings (each block by a
    positive factor, each variable by a positive factor ``col``); ``declared``: use the blocks'
    matrix-variable declarations (else every variable is dense)."""
    # exact rescalings: each block by a positive factor, each variable by a positive factor
    norms = [b.sq_norms() for b in blocks]
    row = [1.0 / max(np.sqrt(np.sum(b.F0**2) + np.sum(nb)), 1e-300) for b, nb in zip(blocks, norms)]
    col2 = np.zeros(m)
    for b, r, nb in zip(blocks, row, norms):
        np.add.at(col2, b.idx, r * r * nb)
    if np.any(col2 <= 0):
        raise ValueError("a variable appears in no LMI block")
    col = 1.0 / np.sqrt(col2)
    if not declared:
        blocks = [LmiBlock(b.idx, b.F0, b.dense(), b.group) for b in blocks]
    by_shape: dict[tuple[int, int], list[int]] = {}
    for j, b in enumerate(blocks):
        by_shape.setdefault((b.F0.shape[0], len(b.idx)), []).append(j)
    gs = [_Group([blocks[j] for j in js], [row[j] for j in js], col) for js in by_shape.values()]
    return gs, col


STALL_ITERATIONS = 15  # an interior-point run that has halved none of its measures in this many iterations has stalled


def stalled(*measures: list[float]) -> bool:
    """None of the progress measures (each a list over the iterations so far, last = current: the relative gap, μ,
    the primal and dual residuals) has halved over STALL_ITERATIONS. The relative gap alone is not enough: while the
    objective shrinks towards zero, ⟨X, Z⟩/(1 + |pobj| + |dobj|) can sit near 1 for tens of iterations in which μ and
    both residuals fall by orders of magnitude (Table 4.3's |T| = 20 problem: μ 0.49 → 0.015, residuals 2e-2 → 1e-6
    over iterations 12-23, relative gap 1.7 → 1.0)."""
    return all(len(x) > STALL_ITERATIONS and x[-1] > 0.5 * x[-1 - STALL_ITERATIONS] for x in measures)


def solve_lmi(c: np.ndarray, blocks: list[LmiBlock], tol: float = 1e-8, max_iter: int = 100,
              verbose: bool = False, method: str = "auto") -> SdpResult:
    """Minimise cᵀx subject to every block ⪰ 0 (see the module docstring).

    method: 'auto' (Cholesky of the Schur complement, QR of its factor from the first step
    whose residual is too large; with blocks declaring matrix variables, their part of the
    Schur complement in Kronecker form and conjugate gradients instead of QR), 'dense' (as
    'auto' with the declarations ignored) or 'qr' (QR throughout, declarations ignored). On an
    infeasible problem the iterates
    grow without bound; the run stops on non-finite residuals with status 'failed', so numpy's
    overflow warnings on the way are silenced rather than shown to the user."""
    with np.errstate(over="ignore"), reuse_freed_memory():
        return _solve_lmi(c, blocks, tol, max_iter, verbose, method)


def _solve_lmi(c, blocks, tol, max_iter, verbose, method) -> SdpResult:
    if method not in ("auto", "dense", "qr"):
        raise ValueError(f"unknown method {method!r}")
    t0 = time.perf_counter()
    m = len(c)
    gs, col = groups(blocks, m, declared=method == "auto")
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
    use_qr = method == "qr"
    qr_route = "qr" if method == "qr" else QR_ROUTE  # 'qr': S's own QR in every iteration
    qr_steps = 0
    endgame: int | None = None  # the iteration from which the QR route takes every Newton system
    schur_cg = any(g.mv for g in gs)  # matrix variables: CG through S before any QR
    best: tuple = (np.inf, np.inf, np.inf, 0, None)  # (gap, pinf, dinf, iteration, y) of the best iterate
    history: list[float] = []
    mus: list[float] = []
    pinfs: list[float] = []
    dinfs: list[float] = []
    farkas = np.inf
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
        if dinf < tol and pinf < OPT_TOL and rel_obj < OPT_TOL and gap < best[0]:
            best = (gap, pinf, dinf, it, y.copy())
        history.append(gap)
        mus.append(mu)
        pinfs.append(max(pinf, tol))  # a residual already within tol is no longer a measure of progress
        dinfs.append(max(dinf, tol))
        # lack of progress near the optimum: with matrix variables, CG's Newton directions may no longer be accurate
        # enough, so the QR route takes every remaining iteration (the endgame); when even that makes no progress
        # (the Newton system too ill-conditioned for the QR route), stop: the best iterate so far is returned
        if len(history) > 4 and gap > 0.5 * history[-5] and best[4] is not None and gap < 1e-3:
            if schur_cg and method != "qr" and endgame is None:
                endgame, use_qr = len(history), True
            elif endgame is None or len(history) - endgame >= 5:
                break
        # a stall at any gap: STALL_ITERATIONS without halving the gap, μ or a residual (the full PULSAR's chapter 3
        # and 4 problems stalled at gaps of 4e-2 and 5e-3 with steps of 1e-6 and ran on to max_iter, minutes, with
        # nothing to gain)
        if stalled(history, mus, pinfs, dinfs):
            break
        # divergence: μ grew at each of the last five iterations without the gap halving. On an
        # infeasible LMI (no y with every Z ⪰ 0) the multipliers' objective ⟨C, X⟩ runs to −∞ while
        # AX stays bounded: X/|⟨C, X⟩| tends to a Farkas certificate (see ``SdpResult.farkas``)
        if len(mus) > 5 and all(mus[-j] > mus[-j - 1] for j in range(1, 6)) and gap > 0.5 * history[-6]:
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
        for q, g in enumerate(gs):
            T, S = g.scaled(G[q])
            At.append(T)
            St.append(S)
        Rdt = [tr(G[q]) @ Rd[q] @ G[q] for q in range(ng)]
        try:
            schur = _Schur(gs, St, m, qr_route if use_qr else "chol", At)
        except (np.linalg.LinAlgError, ValueError):
            if use_qr:
                break
            use_qr = True
            try:
                schur = _Schur(gs, St, m, qr_route, At)
            except (np.linalg.LinAlgError, ValueError):
                break

        def direction(Rct):
            nonlocal schur, use_qr
            h = Rp.copy()
            for q, g in enumerate(gs):
                np.add.at(h, g.idx, -g.apply(Rct[q] - Rdt[q], St[q]))
            # the residual is exactly the primal residual the step leaves: keep it below a tenth
            # of the current one (or far below OPT_TOL), else switch to the QR factorisation
            target = max(0.1 * float(np.linalg.norm(Rp)), 1e-3 * OPT_TOL * normb)
            dy, err = schur.solve(h, 1e-3 * target, cg_target=0.1 * target)
            if not use_qr and err > target:
                use_qr = True
                schur = _Schur(gs, St, m, qr_route, At)
                dy, err = schur.solve(h, 1e-3 * target)
            if schur.method == "sketch" and err > target:
                schur = _Schur(gs, St, m, "qr", At)
                dy, err = schur.solve(h, 1e-3 * target)
            dZt = [Rdt[q] - g.adjoint(dy, At[q]) for q, g in enumerate(gs)]
            dXt = [Rct[q] - dZt[q] for q in range(ng)]
            return dy, dXt, dZt, err

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
        dy, dXt, dZt, _ = direction([-d for d in diagD])
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
        dy, dXt, dZt, err = direction(Rct)
        ap = max_step(dXt)
        ad = max_step(dZt)
        step = 0.9 + 0.09 * min(min(ap, 1.0), min(ad, 1.0))
        ap = min(1.0, step * ap)
        ad = min(1.0, step * ad)
        # the primal residual after the step is at most (1 − α_p)‖R_p‖ + α_p·err: when even the
        # QR solve is inaccurate (the last iterations of the largest problems), shorten the
        # multiplier step so that the certificate's residual stays far below OPT_TOL; while ‖R_p‖ is
        # still large, only so far that the step still halves its own share of it (an absolute cap alone
        # cut |T| = 100's steps from ~0.5 to ~0.05 from iteration 12 on, at ‖R_p‖ 0.3–0.5 ‖b‖ and err
        # 1e-4 ‖b‖, and the run never converged)
        cap = max(1e-2 * OPT_TOL * normb, 0.5 * ap * float(np.linalg.norm(Rp)))
        if err * ap > cap:
            ap = cap / err
        for q, g in enumerate(gs):
            X[q] = X[q] + ap * (G[q] @ dXt[q] @ tr(G[q]))
            X[q] = (X[q] + tr(X[q])) / 2
            Z[q] = Z[q] + ad * (Rd[q] - g.adjoint(dy))
            Z[q] = (Z[q] + tr(Z[q])) / 2
        y = y + ad * dy
        qr_steps += use_qr
        if verbose:  # the route this iteration's Newton systems took (before CG is re-armed below)
            how = {"chol": "chol+cg" if schur_cg else "chol", "qr": "qr", "sketch": "sketch+pcg"}[schur.method]
            print(f"    steps {ap:.3f} {ad:.3f} sigma {sigma:.2e} schur {how}")
        if schur_cg and method != "qr" and endgame is None:  # with matrix variables QR is per iteration: CG is retried
            use_qr = False
        if max(ap, ad) < 1e-8:
            break
    if status != "optimal":
        farkas = _farkas(gs, X, m)
    if status != "optimal" and best[4] is not None:
        gap, pinf, dinf, _, y = best
        if gap <= NEAR_GAP and pinf <= NEAR_FEAS and dinf <= NEAR_FEAS:
            status = "optimal_inaccurate"
    x = y * col
    worst = np.inf
    for b in blocks:
        Fx = b.value(x)
        nrm = max(np.linalg.norm(b.F0), 1e-300) if len(b.idx) == 0 else max(np.linalg.norm(Fx), 1e-300)
        worst = min(worst, float(np.min(np.linalg.eigvalsh((Fx + Fx.T) / 2))) / nrm)
    return SdpResult(x, status, it, gap, pinf, dinf, worst, time.perf_counter() - t0, farkas, qr_steps)


def _farkas(gs: list[_Group], X: list[np.ndarray], m: int) -> float:
    """‖AX̂‖ for X̂ = X/(−⟨C, X⟩) (X ⪰ 0, ⟨C, X⟩ < 0; inf otherwise), in the solver's scaled
    variables. For every y with all Z_j(y) = C_j − Σ_i y_iA_ji ⪰ 0: 0 ≤ Σ_j⟨Z_j, X̂_j⟩ = −1 − yᵀAX̂,
    so ‖y‖ ≥ 1/‖AX̂‖: a small value proves that no point of moderate size satisfies the LMIs."""
    cx = sum(float(np.sum(g.C * X[q])) for q, g in enumerate(gs))
    if not cx < 0 or not np.isfinite(cx):
        return np.inf
    AX = np.zeros(m)
    for q, g in enumerate(gs):
        np.add.at(AX, g.idx, g.apply(X[q]))
    return float(np.linalg.norm(AX)) / -cx
