"""Matrix variables of LMI blocks (``sdp.LmiBlock.terms``) and their part of the interior-point
Schur complement in Kronecker form, without the scaled coefficient matrices.

A matrix variable X (r×c, symmetric when ``sym``) enters a block of size n as

    F_X(X) = Σ_s (L_sᵀ X R_s + R_sᵀ Xᵀ L_s)          L_s (r×n), R_s (c×n)

and its scalar variables are X's entries: the basis E = e_a e_bᵀ, or e_a e_bᵀ + e_b e_aᵀ for a
symmetric X with a < b (the upper-triangle parameterisation of ``direct.Layout``). With the NT
scaling G of the block and W = G Gᵀ, for U = e_a e_bᵀ of X (terms L, R) and V = e_c e_dᵀ of Y
(terms L', R'), expanding tr(W F_X(U) W F_Y(V)) gives four products that pair up by
transposition (tr(Z) = tr(Zᵀ), W symmetric)::

    ⟨GᵀF_X(U)G, GᵀF_Y(V)G⟩ = 2 Σ_st [(R_s W L'_tᵀ)_bc (R'_t W L_sᵀ)_da + (R_s W R'_tᵀ)_bd (L'_t W L_sᵀ)_ca]

so the X–Y part of the Schur complement costs O(S² r c r' c') from the r×n products R G, L G,
instead of O(r c · r' c' · n²) through the scaled matrices GᵀF_X(E)G. Against any other
coefficient matrix (scaled Ã = GᵀAG): ⟨GᵀF_X(U)G, Ã⟩ = 2 Σ_s (R_s G Ã Gᵀ L_sᵀ)_ba.
Units: whatever the block's are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT


@dataclass
class MatrixTerm:
    """Declaration: the block variables at ``pos`` (positions in ``LmiBlock.idx``) are the entries
    (a[j], b[j]) of one matrix variable entering as Σ_s (L_sᵀ X R_s + R_sᵀ Xᵀ L_s); L (S, r, n),
    R (S, c, n); ``sym``: X symmetric with a ≤ b (basis e_a e_bᵀ + e_b e_aᵀ off the diagonal)."""

    pos: np.ndarray
    a: np.ndarray
    b: np.ndarray
    sym: bool
    L: np.ndarray
    R: np.ndarray


def matrix_of(a: np.ndarray, b: np.ndarray, sym: bool, shape: tuple[int, int], v: np.ndarray) -> np.ndarray:
    """X (…, r, c) with the entries v (…, p) at (a, b), and at (b, a) off the diagonal of a
    symmetric X (the basis of ``MatrixTerm``)."""
    X = np.zeros(v.shape[:-1] + tuple(shape))
    np.add.at(X, (..., a, b), v)
    if sym:
        off = a != b
        np.add.at(X, (..., b[off], a[off]), v[..., off])
    return X


def value(t: MatrixTerm, x: np.ndarray) -> np.ndarray:
    """(…, n, n): F_X(X) = Σ_s (L_sᵀ X R_s + R_sᵀ Xᵀ L_s) for the entries x (…, p) of X, in
    Kronecker form (O(r c n) per term, no coefficient matrix formed)."""
    X = matrix_of(t.a, t.b, t.sym, (t.L.shape[1], t.R.shape[1]), x)
    D = np.einsum("sri,...rc,scj->...ij", t.L, X, t.R, optimize=True)
    return D + np.swapaxes(D, -1, -2)


def sq_norms(t: MatrixTerm) -> np.ndarray:
    """(p,): ‖F_X(E_j)‖_F² for every declared entry, from the factors' rows alone. F_X(E_j) = T + Tᵀ
    with T = Σ_u x_u y_uᵀ (x_u = row a of L_s, y_u = row b of R_s, and for a symmetric X off the
    diagonal also row b of L_s with row a of R_s), so ‖T + Tᵀ‖² = 2 Σ_uv [(x_u·x_v)(y_u·y_v)
    + (y_u·x_v)(y_v·x_u)]: O(S² n) per entry instead of forming the n×n matrix."""
    xs, ys = np.swapaxes(t.L[:, t.a], 0, 1), np.swapaxes(t.R[:, t.b], 0, 1)  # (p, S, n)
    if t.sym:
        off = (t.a != t.b).astype(float)[:, None, None]
        xs = np.concatenate([xs, off * np.swapaxes(t.L[:, t.b], 0, 1)], axis=1)
        ys = np.concatenate([ys, np.swapaxes(t.R[:, t.a], 0, 1)], axis=1)
    gram = lambda u, v: u @ np.swapaxes(v, 1, 2)  # noqa: E731
    Gyx = gram(ys, xs)
    return 2.0 * (np.sum(gram(xs, xs) * gram(ys, ys), axis=(1, 2)) + np.sum(Gyx * np.swapaxes(Gyx, 1, 2), axis=(1, 2)))


def coefficients(t: MatrixTerm) -> np.ndarray:
    """(p, n, n): F_X(E_j) for every declared entry (the dense coefficients the term stands for:
    the dense solver path, 'dense' and 'qr', and tests)."""
    La, Rb = t.L[:, t.a], t.R[:, t.b]  # (S, p, n)
    F = np.einsum("spi,spj->pij", La, Rb)
    if t.sym:
        off = (t.a != t.b).astype(float)[:, None, None]
        F = F + off * np.einsum("spi,spj->pij", t.L[:, t.b], t.R[:, t.a])
    return F + np.swapaxes(F, 1, 2)


def check(terms: list[MatrixTerm], x: np.ndarray, D: np.ndarray, rtol: float = 1e-10) -> None:
    """Raise ValueError unless the declarations reproduce the block: D (B, n, n) is the block's
    part of the declared variables at B probe points x (B, k) of its variables (the block at x
    minus F0 and minus its other variables' part), against Σ_t F_X(X_t) in Kronecker form (a
    linear map that agrees at random points agrees everywhere, with probability 1; O(B p n²)
    and no coefficient matrix formed)."""
    Fx = sum(value(t, x[:, t.pos]) for t in terms)
    p = sum(len(t.pos) for t in terms)
    for Db, Fb in zip(D, Fx):
        scale = max(float(np.max(np.abs(Db))), 1e-300)
        err = float(np.max(np.abs(Fb - Db)))
        if err > rtol * scale * np.sqrt(p):
            raise ValueError(f"matrix-variable declaration does not match the block (error {err / scale:.1e})")


class Stacked:
    """One declared matrix variable over the nb blocks of a solver group (same entries, same
    global variables): L (nb, S, r, n), R (nb, S, c, n) with R multiplied by the block's sign and
    row scaling (the group's A = −row·col·F), col (p,) the variables' column scaling."""

    def __init__(self, terms: list[MatrixTerm], rows: list[float], col: np.ndarray, gidx: np.ndarray):
        t0 = terms[0]
        self.pos, self.a, self.b, self.sym = t0.pos, t0.a, t0.b, t0.sym
        self.r, self.c = t0.L.shape[1], t0.R.shape[1]
        self.L = np.stack([t.L for t in terms])
        self.R = np.stack([-r * t.R for t, r in zip(terms, rows)])
        self.gidx = gidx
        self.col = col[gidx]
        # entry weights: a symmetric X's diagonal entry is one ordered pair, not two
        self.half = np.where(self.sym & (self.a == self.b), 0.5, 1.0)

    def matrix(self, y: np.ndarray) -> np.ndarray:
        """X (r, c) of the variables y (solver's scaled units)."""
        return matrix_of(self.a, self.b, self.sym, (self.r, self.c), y[self.gidx] * self.col)

    def adjoint(self, y: np.ndarray, fac: tuple | None = None) -> np.ndarray:
        """(nb, n, n): Σ_j y_j A_j over this variable's entries (Σ_j y_j Ã_j with fac = (L G, R G):
        products of the scaled factors, as accurate as the scaled Ã_j themselves; Gᵀ(Σ y_jA_j)G
        would lose cond(G)²)."""
        L, R = (self.L, self.R) if fac is None else fac
        X = self.matrix(y)
        T = np.swapaxes(L, -1, -2) @ (X @ R)  # (nb, S, n, n)
        T = T.sum(axis=1)
        return T + np.swapaxes(T, 1, 2)

    def _pick(self, Y: np.ndarray) -> np.ndarray:
        """2·Y[..., b, a] (+ Y[..., a, b] off a symmetric X's diagonal) · col: the entries'
        inner products from Y = Σ_s R_s Z L_sᵀ (last two axes c×r)."""
        v = Y[..., self.b, self.a]
        if self.sym:
            v = v + (self.a != self.b) * Y[..., self.a, self.b]
        return 2.0 * v * self.col

    def apply(self, V: np.ndarray, fac: tuple | None = None) -> np.ndarray:
        """(nb, p): ⟨A_j, V_b⟩ for symmetric V (nb, n, n) (⟨Ã_j, V_b⟩ with fac = (L G, R G))."""
        L, R = (self.L, self.R) if fac is None else fac
        Y = (R @ V[:, None]) @ np.swapaxes(L, -1, -2)  # (nb, S, c, r)
        return self._pick(Y.sum(axis=1))

    def scaled_factors(self, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """L G, R G (nb, S, ·, n)."""
        return self.L @ G[:, None], self.R @ G[:, None]

    def add_bilinear(self, LG: np.ndarray, RG: np.ndarray, G: np.ndarray, H: np.ndarray, out: np.ndarray) -> None:
        """out (p, q) += g_kᵀ Ã_j h_k · col_j for the entries j and the columns k of G, H (n, q), from one block's
        scaled factors LG (S, r, n), RG (S, c, n). Ã_j = Σ_s (l_sa r_sbᵀ + r_sb l_saᵀ) (l_sa = row a of L_sG), plus
        the same with a and b swapped off a symmetric X's diagonal, so gᵀÃ_jh = Σ_s (Lg)_sa (Rh)_sb + (Lh)_sa
        (Rg)_sb: products of the rows of four n-column products, no Ã_j formed (O(S (r + c) n q) flops)."""
        A = np.concatenate([LG @ G, LG @ H])  # (2S, r, q)
        B = np.concatenate([RG @ H, RG @ G])  # (2S, c, q)
        _add_row_products(A, B, self.a, self.b, self.sym & (self.a != self.b), self.col, out)

    def cross(self, LG: np.ndarray, RG: np.ndarray, At: np.ndarray) -> np.ndarray:
        """(nb, p, k): ⟨Ã_j, Ã_k⟩ between this variable's entries and other scaled coefficient
        matrices At (nb, k, n, n)."""
        Y = np.einsum("bsxi,bkij,bsyj->bkxy", RG, At, LG, optimize=True)  # Σ_s R_sGÃGᵀL_sᵀ (c×r)
        return np.swapaxes(self._pick(Y), 1, 2)


class PairSum:
    """Σ over groups and blocks of the Kronecker products of ``pair``'s formula for the entries of
    two matrix variables u, v, kept as the two raw products (layouts [b, c, d, a] and [b, d, c, a])
    so that the rearrangement into the m×m matrix is done once per variable pair, not per group:
    the factors of every block and term pair are stacked and multiplied in one product each."""

    def __init__(self, u: "Stacked", v: "Stacked"):
        self.u, self.v = u, v
        self.f1: list = []
        self.f2: list = []

    def add(self, U: tuple, V: tuple) -> None:
        """Add one group's products; U = (L G, R G) of u (nb, S, ·, n), V of v."""
        LGu, RGu = U
        LGv, RGv = V
        tr = lambda a: np.swapaxes(a, -1, -2)  # noqa: E731
        u, v = self.u, self.v
        A1 = RGu[:, :, None] @ tr(LGv)[:, None]          # (nb, s, t, c_u, r_v): R_s W L'_tᵀ [b, c]
        A2 = RGv[:, :, None] @ tr(LGu)[:, None]          # (nb, t, s, c_v, r_u): R'_t W L_sᵀ [d, a]
        self.f1.append((A1.reshape(-1, u.c * v.r), np.swapaxes(A2, 1, 2).reshape(-1, v.c * u.r)))
        B = RGu[:, :, None] @ tr(RGv)[:, None]           # R_s W R'_tᵀ [b, d]
        C = LGv[:, :, None] @ tr(LGu)[:, None]           # (nb, t, s, r_v, r_u): L'_t W L_sᵀ [c, a]
        self.f2.append((B.reshape(-1, u.c * v.c), np.swapaxes(C, 1, 2).reshape(-1, v.r * u.r)))

    def matrix(self) -> np.ndarray:
        """(p_u, p_v): Σ ⟨Ã_i, Ã_j⟩ for the entries i of u and j of v, each entry of a symmetric
        variable summed over its two ordered pairs."""
        u, v = self.u, self.v
        T1 = np.concatenate([f[0] for f in self.f1]).T @ np.concatenate([f[1] for f in self.f1])
        T2 = np.concatenate([f[0] for f in self.f2]).T @ np.concatenate([f[1] for f in self.f2])
        T = (T1.reshape(u.c, v.r, v.c, u.r).transpose(3, 0, 1, 2)
             + T2.reshape(u.c, v.c, v.r, u.r).transpose(3, 0, 2, 1))  # [a, b, c, d]
        Tu = T[u.a, u.b]
        if u.sym:
            Tu = Tu + T[u.b, u.a]
        M = Tu[:, v.a, v.b]
        if v.sym:
            M = M + Tu[:, v.b, v.a]
        return 2.0 * M * np.outer(u.col * u.half, v.col * v.half)


@njit(**JIT)
def _add_row_products(A, B, a, b, swap, w, out):  # pragma: no cover - compiled
    """out[j] += w_j Σ_t (A[t, a_j] ∘ B[t, b_j] + [swap_j] A[t, b_j] ∘ B[t, a_j]) (rows of length q; A, B
    C-contiguous, out any layout: the sum is taken in a contiguous row first)."""
    q = A.shape[2]
    acc = np.empty(q)
    for j in range(a.shape[0]):
        acc[:] = 0.0
        for t in range(A.shape[0]):
            x, y = A[t, a[j]], B[t, b[j]]
            for k in range(q):
                acc[k] += x[k] * y[k]
            if swap[j]:
                x, y = A[t, b[j]], B[t, a[j]]
                for k in range(q):
                    acc[k] += x[k] * y[k]
        for k in range(q):
            out[j, k] += w[j] * acc[k]
