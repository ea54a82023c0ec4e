"""Thrust allocation: a commanded base wrench w (6, base joint frame, [f; n] about the base-link origin,
N and N m) to thrusts 0 ≤ x ≤ x_max (N) with B x = w, minimising the total thrust 1ᵀx (which is the
propellant flow when every Isp is equal), solved by HiGHS (``scipy.optimize.linprog``).

A wrench outside the set's capability is scaled down along its own direction: the largest s ∈ [0, 1]
with B x = s w feasible, then the minimum-thrust x for s w (``Allocation.scale`` < 1, ``saturated``).

Speed: ``linprog`` builds and presolves the LP at every call (about 1 ms for 24 thrusters). The
allocator keeps one HiGHS instance instead (the HiGHS that scipy bundles, ``scipy.optimize._highspy``,
the solver behind ``linprog(method="highs")``): only the six row bounds change between solves, and
the dual simplex restarts from the last basis (about 60 µs; benches/bench_thrusters.py). Without that
module (another scipy) it falls back to ``linprog``; ``Allocator(..., warm=False)`` forces it. Both give
the same optimum (tests/test_thrusters.py compares them and the LP dual).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog


@dataclass
class Allocation:
    thrust: np.ndarray  # (n,) N, 0 ≤ thrust ≤ max_force
    scale: float  # delivered fraction of the commanded wrench (1 unless saturated)
    saturated: bool


class Allocator:
    """Minimum-total-thrust allocation for one thruster set (see the module docstring)."""

    def __init__(self, B: np.ndarray, max_force: np.ndarray, warm: bool = True):
        self.B = np.asarray(B, float)
        self.fmax = np.asarray(max_force, float)
        self.n = self.fmax.size
        self.bounds = [(0.0, float(f)) for f in self.fmax]
        self._zero = np.zeros(self.n)
        self._highs = _persistent_highs(self.B, self.fmax) if warm else None

    def _min_thrust(self, w: np.ndarray) -> np.ndarray | None:
        """argmin 1ᵀx, B x = w, 0 ≤ x ≤ x_max; None when infeasible."""
        h = self._highs
        if h is not None:
            for i in range(6):
                h.changeRowBounds(i, float(w[i]), float(w[i]))
            h.run()
            if h.modelStatusToString(h.getModelStatus()) == "Optimal":
                return np.array(h.getSolution().col_value)
        res = linprog(np.ones(self.n), A_eq=self.B, b_eq=w, bounds=self.bounds, method="highs")
        return res.x if res.status == 0 else None

    def solve(self, wrench: np.ndarray) -> Allocation:
        """The minimum-total-thrust x for ``wrench`` (scaled down when out of reach)."""
        w = np.asarray(wrench, float)
        if not np.any(w):
            return Allocation(self._zero.copy(), 1.0, False)
        x = self._min_thrust(w)
        if x is not None:
            return Allocation(np.clip(x, 0.0, self.fmax), 1.0, False)
        s = self.reach(w)
        if s <= 0.0:
            return Allocation(self._zero.copy(), 0.0, True)
        for shrink in (1e-9, 1e-7, 1e-5):
            res = linprog(np.ones(self.n), A_eq=self.B, b_eq=s * (1 - shrink) * w, bounds=self.bounds, method="highs")
            if res.status == 0:
                return Allocation(np.clip(res.x, 0.0, self.fmax), s * (1 - shrink), True)
        return Allocation(self._zero.copy(), 0.0, True)

    def reach(self, w: np.ndarray) -> float:
        """Largest s ∈ [0, 1] such that s w = B x for some 0 ≤ x ≤ x_max (LP in (x, s))."""
        w = np.asarray(w, float)
        A = np.hstack([self.B, -w[:, None]])
        c = np.zeros(self.n + 1)
        c[-1] = -1.0
        res = linprog(c, A_eq=A, b_eq=np.zeros(6), bounds=self.bounds + [(0.0, 1.0)], method="highs")
        return float(res.x[-1]) if res.status == 0 else 0.0

    def pure_capability(self, direction: np.ndarray) -> float:
        """Largest magnitude a of a wrench a·u (u = direction / |direction|, 6-D) the set can produce."""
        u = np.asarray(direction, float)
        u = u / np.linalg.norm(u)
        big = float(np.linalg.norm(self.B, axis=0) @ self.fmax) + 1.0  # above any reachable |w|
        return self.reach(big * u) * big


def _persistent_highs(B: np.ndarray, fmax: np.ndarray):
    """A HiGHS instance holding min 1ᵀx, B x = 0, 0 ≤ x ≤ fmax (rows re-bounded per solve), or None
    when scipy's bundled HiGHS module is not there."""
    try:
        from scipy.optimize._highspy import _core as hc
    except ImportError:
        return None
    try:
        m, n = B.shape
        h = hc._Highs()
        h.setOptionValue("output_flag", False)
        lp = hc.HighsLp()
        lp.num_col_, lp.num_row_ = n, m
        lp.col_cost_, lp.col_lower_, lp.col_upper_ = np.ones(n), np.zeros(n), np.asarray(fmax, float).copy()
        lp.row_lower_, lp.row_upper_ = np.zeros(m), np.zeros(m)
        a = lp.a_matrix_
        a.format_ = hc.MatrixFormat.kColwise
        a.num_col_, a.num_row_ = n, m
        a.start_ = np.arange(0, m * n + 1, m, dtype=np.int32)  # dense columns
        a.index_ = np.tile(np.arange(m, dtype=np.int32), n)
        a.value_ = np.ascontiguousarray(B.T).ravel()
        if str(h.passModel(lp)) != "HighsStatus.kOk":
            return None
        return h
    except (AttributeError, TypeError):  # a scipy whose private HiGHS module differs
        return None
