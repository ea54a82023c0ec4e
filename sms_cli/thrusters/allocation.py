"""Thrust allocation: a commanded base wrench w (6, base joint frame, [f; n] about the base-link origin,
N and N m) to thrusts 0 ≤ x ≤ x_max (N) with B x = w, minimising the total thrust 1ᵀx (which is the
propellant flow when every Isp is equal), solved by HiGHS (``scipy.optimize.linprog``).

A wrench outside the set's capability is scaled down along its own direction: the largest s ∈ [0, 1]
with B x = s w feasible (the reach LP in (x, s): max s, B x − s w = 0), then the minimum-thrust x for
s (1 − δ) w (``Allocation.scale`` = s (1 − δ) < 1, ``saturated``), δ = 1e-9 (then 1e-7, 1e-5 if that LP
fails). Why δ: s is a vertex of the reach LP, on the boundary of the reachable set, where {x : B x = s w}
shrinks to a point or a face of the box, feasible only to HiGHS's primal tolerance (1e-7). HiGHS does
accept s w itself in practice (300 of 300 random saturated cube commands, warm and linprog, and 175 of
them even at s (1 + 1e-9) w), but the minimum total thrust is steep in s there (on a random 14-thruster
set it is 1.4e-7 higher, relative, at s w than at s (1 − 1e-9) w): δ makes the target strictly reachable,
so the minimum is that of a genuinely feasible LP, and keeps the previous implementation's results. It
costs nothing (one solve either way); the larger steps are a safety net, never taken in the tests.

Speed: ``linprog`` builds and presolves the LP at every call (about 1 ms for 24 thrusters). The
allocator keeps two HiGHS instances instead (the HiGHS that scipy bundles, ``scipy.optimize._highspy``,
the solver behind ``linprog(method="highs")``): the minimum-thrust LP, of which only the six row bounds
change between solves, and the reach LP, of which only the s column's six coefficients (−w) change; the
dual simplex restarts from each one's last basis (60 to 110 µs per solve, the fewer simplex iterations the
closer successive commands; a saturated command takes three: the minimum-thrust LP (infeasible), the reach
LP and the minimum-thrust LP at s (1 − δ) w, 0.2 to 0.3 ms against 3.3 ms with fresh linprog calls;
benches/bench_thrusters.py). Without that module (another scipy) it falls back to ``linprog``;
``Allocator(..., warm=False)`` forces it. Both give the same optimum (scale and total thrust;
tests/test_thrusters.py and tests/test_allocation_saturated.py compare them and the LP duals), though not
always the same thrusts: the cube's LP is degenerate (thrusts of equal total on a face of optima), and a
warm-started simplex may stop at another vertex of it than a fresh one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

SHRINKS = (1e-9, 1e-7, 1e-5)  # relative pull-back from the reach LP's boundary s (module docstring)


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
        self._highs = _persistent_highs(self.B, self.fmax, reach=False) if warm else None
        self._reach_highs = _persistent_highs(self.B, self.fmax, reach=True) if self._highs is not None else None

    def _min_thrust(self, w: np.ndarray) -> np.ndarray | None:
        """argmin 1ᵀx, B x = w, 0 ≤ x ≤ x_max; None when infeasible."""
        h = self._highs
        if h is not None:
            for i in range(6):
                h.changeRowBounds(i, float(w[i]), float(w[i]))
            status = _run(h)
            if status == "Optimal":
                return np.array(h.getSolution().col_value)
            if status == "Infeasible":
                return None
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
        for shrink in SHRINKS:
            x = self._min_thrust(s * (1 - shrink) * w)
            if x is not None:
                return Allocation(np.clip(x, 0.0, self.fmax), s * (1 - shrink), True)
        return Allocation(self._zero.copy(), 0.0, True)

    def reach(self, w: np.ndarray) -> float:
        """Largest s ∈ [0, 1] such that s w = B x for some 0 ≤ x ≤ x_max (LP in (x, s): max s, B x − s w = 0)."""
        w = np.asarray(w, float)
        h = self._reach_highs
        if h is not None:
            for i in range(6):
                h.changeCoeff(i, self.n, -float(w[i]))
            status = _run(h)
            if status == "Optimal":
                return float(h.getSolution().col_value[self.n])
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


def _run(h) -> str:
    """Run the persistent instance ``h``; its model status as HiGHS spells it ("Optimal", "Infeasible", …)."""
    h.run()
    return h.modelStatusToString(h.getModelStatus())


def _persistent_highs(B: np.ndarray, fmax: np.ndarray, reach: bool):
    """A HiGHS instance holding either (reach=False) min 1ᵀx, B x = w, 0 ≤ x ≤ fmax, with w the six row
    bounds set per solve (0 here), or (reach=True) the reach LP in (x, s): max s, B x + s c = 0,
    0 ≤ x ≤ fmax, 0 ≤ s ≤ 1, with the s column c = −w set per solve (ones here); None when scipy's
    bundled HiGHS module is not there."""
    try:
        from scipy.optimize._highspy import _core as hc
    except ImportError:
        return None
    try:
        m, n = B.shape
        fmax = np.asarray(fmax, float)
        cols = n + 1 if reach else n
        cost = np.concatenate([np.zeros(n), [-1.0]]) if reach else np.ones(n)
        upper = np.concatenate([fmax, [1.0]]) if reach else fmax.copy()
        values = np.ascontiguousarray(B.T).ravel()
        if reach:  # the s column, dense (its six entries are then changed in place)
            values = np.concatenate([values, np.ones(m)])
        h = hc._Highs()
        h.setOptionValue("output_flag", False)
        lp = hc.HighsLp()
        lp.num_col_, lp.num_row_ = cols, m
        lp.col_cost_, lp.col_lower_, lp.col_upper_ = cost, np.zeros(cols), upper
        lp.row_lower_, lp.row_upper_ = np.zeros(m), np.zeros(m)
        a = lp.a_matrix_
        a.format_ = hc.MatrixFormat.kColwise
        a.num_col_, a.num_row_ = cols, m
        a.start_ = np.arange(0, m * cols + 1, m, dtype=np.int32)  # dense columns
        a.index_ = np.tile(np.arange(m, dtype=np.int32), cols)
        a.value_ = values
        if str(h.passModel(lp)) != "HighsStatus.kOk":
            return None
        return h
    except (AttributeError, TypeError):  # a scipy whose private HiGHS module differs
        return None
