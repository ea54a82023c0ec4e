"""LMI pole regions (Chilali & Gahinet 1996) and their membership test.

A region D = {Re s ≤ −α} ∩ {damping ratio ≥ ζ_min} ∩ {|s| ≤ r}. A matrix A has all its
eigenvalues in D if (and, for each single region, only if) there is X ≻ 0 with
``L ⊗ X + M ⊗ (A X) + Mᵀ ⊗ (A X)ᵀ ≺ 0`` for the region's characteristic (L, M).
Here the LMIs are written on ``N = A X`` so that synthesis can substitute ``N = A X + B W``
(controller, variable X = Q) or ``N = (P A − W C)ᵀ`` (observer, variable X = P: Aᵀ has the same
eigenvalues and the regions are symmetric about the real axis).
Rates are in rad/s (or in the scaled time of the caller, consistently).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def damping_ratios(eigs: np.ndarray) -> np.ndarray:
    """ζ = −Re s/|s| of each eigenvalue (1 at s = 0)."""
    eigs = np.asarray(eigs, dtype=complex)
    mag = np.abs(eigs)
    return np.where(mag > 0, -eigs.real / np.where(mag > 0, mag, 1.0), 1.0)


@dataclass(frozen=True)
class PoleRegion:
    """Re s ≤ −alpha, damping ≥ zeta_min, |s| ≤ radius (rad/s)."""

    alpha: float
    zeta_min: float
    radius: float

    def scaled(self, omega_c: float) -> "PoleRegion":
        """The same region in time scaled by ω_c (s̃ = s/ω_c)."""
        return PoleRegion(self.alpha / omega_c, self.zeta_min, self.radius / omega_c)

    def margins(self, eigs: np.ndarray) -> dict[str, np.ndarray]:
        """Signed distances (≥ 0 inside) of each eigenvalue to each boundary."""
        eigs = np.asarray(eigs, dtype=complex)
        return {
            "decay": -eigs.real - self.alpha,
            "damping": damping_ratios(eigs) - self.zeta_min,
            "disk": self.radius - np.abs(eigs),
        }

    def contains(self, eigs: np.ndarray, rtol: float = 1e-6) -> np.ndarray:
        """True for each eigenvalue inside the region (with a relative tolerance)."""
        m = self.margins(eigs)
        tol_r = rtol * max(self.radius, 1.0)
        return (m["decay"] >= -tol_r) & (m["damping"] >= -rtol) & (m["disk"] >= -tol_r)

    def on_or_beyond(self, eigs: np.ndarray, rtol: float = 1e-6) -> dict[str, np.ndarray]:
        """Per boundary ('decay', 'damping', 'disk'): True for each eigenvalue outside it or within a relative margin
        ``rtol`` of it (an eigenvalue no gain moves that sits there leaves the region's LMI no strictly feasible point)."""
        m = self.margins(eigs)
        tol_r = rtol * max(self.radius, 1.0)
        return {"decay": m["decay"] <= tol_r, "damping": m["damping"] <= rtol, "disk": m["disk"] <= tol_r}

    def strictly_contains(self, eigs: np.ndarray, rtol: float = 1e-6) -> np.ndarray:
        """True for each eigenvalue inside the region by more than ``rtol`` from every boundary (``on_or_beyond``)."""
        out = self.on_or_beyond(eigs, rtol)
        return ~(out["decay"] | out["damping"] | out["disk"])

    def as_dict(self) -> dict[str, float]:
        return {"decay_rate": self.alpha, "min_damping": self.zeta_min, "max_frequency": self.radius}


def region_lmis(cp, N, X, region: PoleRegion, eps: float) -> list:
    """cvxpy constraints placing eig(A) in ``region`` where ``N = A X`` (affine) and X ≻ 0.

    ``cp`` is the cvxpy module (passed in so importing this file stays cheap).
    """
    n = X.shape[0]
    cons = []
    # half plane: N + Nᵀ + 2αX ≺ 0
    cons.append(_sym(cp, N + N.T + 2 * region.alpha * X) << -eps * np.eye(n))
    # disk centred at 0: [[−rX, N], [Nᵀ, −rX]] ≺ 0
    disk = cp.bmat([[-region.radius * X, N], [N.T, -region.radius * X]])
    cons.append(_sym(cp, disk) << -eps * np.eye(2 * n))
    if region.zeta_min > 0:
        theta = math.acos(region.zeta_min)
        s, c = math.sin(theta), math.cos(theta)
        cone = cp.bmat([[s * (N + N.T), c * (N - N.T)], [c * (N.T - N), s * (N + N.T)]])
        cons.append(_sym(cp, cone) << -eps * np.eye(2 * n))
    return cons


def region_pattern(region: PoleRegion) -> list[tuple[int, list[tuple[str, float, int, int]]]]:
    """The blocks of ``region_blocks`` (before −εI) as (number of n×n sub-blocks, entries): entry
    ('N', c, p, q) puts c·N in sub-block (p, q) and c·Nᵀ in (q, p) (both in (p, p) when p = q),
    ('X', c, p, p) puts c·X in (p, p)."""
    out = [(1, [("N", -1.0, 0, 0), ("X", -2.0 * region.alpha, 0, 0)]),      # −(N + Nᵀ + 2αX)
           (2, [("X", region.radius, 0, 0), ("X", region.radius, 1, 1),   # −[[−rX, N], [Nᵀ, −rX]]
                ("N", -1.0, 0, 1)])]
    if region.zeta_min > 0:  # −[[s(N + Nᵀ), c(N − Nᵀ)], [c(Nᵀ − N), s(N + Nᵀ)]]
        theta = math.acos(region.zeta_min)
        s, c = math.sin(theta), math.cos(theta)
        out.append((2, [("N", -s, 0, 0), ("N", -s, 1, 1), ("N", -c, 0, 1), ("N", c, 1, 0)]))
    return out


def region_blocks(N: np.ndarray, X: np.ndarray, region: PoleRegion, eps: float) -> list[np.ndarray]:
    """The matrices of ``region_lmis`` as plain numpy, each required ⪰ 0, for stacks of N and X
    (shape (..., n, n)): −(N + Nᵀ + 2αX) − εI, −[[−rX, N], [Nᵀ, −rX]] − εI and, when ζ_min > 0,
    −[[s(N + Nᵀ), c(N − Nᵀ)], [c(Nᵀ − N), s(N + Nᵀ)]] − εI (``region_pattern``)."""
    n = X.shape[-1]
    Nt = np.swapaxes(N, -1, -2)
    out = []
    for nsub, entries in region_pattern(region):
        B = np.zeros(np.broadcast_shapes(N.shape, X.shape)[:-2] + (nsub * n, nsub * n))
        for kind, c, p, q in entries:
            if kind == "X":
                B[..., p * n:(p + 1) * n, p * n:(p + 1) * n] += c * X
            else:
                B[..., p * n:(p + 1) * n, q * n:(q + 1) * n] += c * N
                B[..., q * n:(q + 1) * n, p * n:(p + 1) * n] += c * Nt
        out.append(B - eps * np.eye(nsub * n))
    return out


def _sym(cp, M):
    return (M + M.T) / 2


def region_feasible(A: np.ndarray, region: PoleRegion, part: str = "all") -> bool:
    """Analysis LMI: is there one X ≻ 0 certifying eig(A) ⊂ region? (``part`` restricts
    the test to one sub-region: 'decay', 'disk', 'damping' or 'all'.)"""
    import cvxpy as cp

    n = A.shape[0]
    X = cp.Variable((n, n), symmetric=True)
    N = A @ X
    eps = 1e-7
    sub = region
    cons = [X >> np.eye(n)]
    if part == "decay":
        cons.append(_sym(cp, N + N.T + 2 * region.alpha * X) << -eps * np.eye(n))
    elif part == "disk":
        disk = cp.bmat([[-region.radius * X, N], [N.T, -region.radius * X]])
        cons.append(_sym(cp, disk) << -eps * np.eye(2 * n))
    elif part == "damping":
        theta = math.acos(region.zeta_min)
        s, c = math.sin(theta), math.cos(theta)
        cone = cp.bmat([[s * (N + N.T), c * (N - N.T)], [c * (N.T - N), s * (N + N.T)]])
        cons.append(_sym(cp, cone) << -eps * np.eye(2 * n))
    else:
        cons += region_lmis(cp, N, X, sub, eps)
    cons.append(X << 1e6 * np.eye(n))
    prob = cp.Problem(cp.Minimize(0), cons)
    prob.solve(solver=cp.CLARABEL)
    return prob.status in ("optimal", "optimal_inaccurate")


def unobservable_eigenvalues(A: np.ndarray, C: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """The eigenvalues λ of A (Im λ ≥ 0) that no output injection A − L C moves: [A − λI; C] loses rank (the
    Popov–Belevitch–Hautus test, its smallest singular value below ``rtol`` times its largest; on the full PULSAR the
    base-rate-unobservable beam modes sit at 1e-19, the least observable other mode at 3e-10). Repeated eigenvalues
    are caught too (a rank drop of the stacked matrix, whatever basis ``eig`` returns), and listed once."""
    n = A.shape[0]
    out = []
    for lam in np.linalg.eigvals(A):
        if lam.imag < 0 or any(abs(lam - o) <= 1e-9 * max(1.0, abs(lam)) for o in out):
            continue
        sv = np.linalg.svd(np.vstack([A - lam * np.eye(n), C]), compute_uv=False)
        if sv[-1] <= rtol * sv[0]:
            out.append(lam)
    return np.asarray(out, dtype=complex)
