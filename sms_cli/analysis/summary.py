"""Streaming statistics of the index columns in bounded memory.

Per column: count, NaN count, min, max, mean (exact), percentiles from a uniform reservoir of at
most ``reservoir`` rows (exact while the study is smaller), the best configurations (top-k),
slices along each sampled joint (min / mean / max per joint-value bin), and a plotting subset.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.analysis.indices import HIGHER_IS_BETTER

PERCENTILES = (1, 5, 50, 95, 99)


class Reservoir:
    """Uniform random subset of at most ``size`` rows of a stream (algorithm R, seeded)."""

    def __init__(self, size: int, ncols: int, seed: int = 0):
        self.size = size
        self.data = np.empty((size, ncols))
        self.seen = 0
        self.rng = np.random.default_rng(seed)

    def add(self, rows: np.ndarray, *more: np.ndarray) -> None:
        """Add a block of rows; ``more``: further columns of the same rows (appended after ``rows``'s)."""
        k = len(rows)
        free = max(0, min(self.size - self.seen, k))
        parts = [np.ascontiguousarray(p, dtype=float) for p in (rows,) + more]
        if free:
            self.data[self.seen:self.seen + free] = np.column_stack([p[:free] for p in parts])
        if free < k:
            idx = np.arange(self.seen + free, self.seen + k)  # global indices of the rest
            j = (self.rng.random(len(idx)) * (idx + 1)).astype(np.int64)
            col = 0
            for p in parts:  # row free + i replaces row j[i] when j[i] < size, in order (the last one stays)
                _replace_rows(self.data, col, p, free, j)
                col += p.shape[1]
        self.seen += k

    @property
    def rows(self) -> np.ndarray:
        return self.data[: min(self.seen, self.size)]


@njit(cache=True, nogil=True)
def _replace_rows(data, col, rows, first, j):
    """data[j[i], col:col + rows.shape[1]] = rows[first + i] for each i in order where j[i] < len(data)."""
    for i in range(j.shape[0]):
        if j[i] < data.shape[0]:
            for c in range(rows.shape[1]):
                data[j[i], col + c] = rows[first + i, c]


class StudyStats:
    """Statistics of one variant's columns over a streamed study."""

    def __init__(self, columns: list[str], joint_names: list[str], joint_ranges: list[tuple[float, float]],
                 grid_values: list[np.ndarray] | None, *, best: int = 5, reservoir: int = 200_000,
                 plot_points: int = 30_000, bins: int = 40, seed: int = 0):
        self.columns = list(columns)
        self.joints = list(joint_names)
        self.best_k = best
        n = len(self.columns)
        self.count = 0
        self.nan = np.zeros(n, dtype=np.int64)
        self.min = np.full(n, np.inf)
        self.max = np.full(n, -np.inf)
        self.sum = np.zeros(n)
        self.res = Reservoir(reservoir, n, seed)
        self.plot = Reservoir(plot_points, n + len(self.joints), seed + 1)
        # Slices: bin edges per joint (grid: one bin per grid value).
        self.edges = []
        for j, (lo, hi) in enumerate(joint_ranges):
            if grid_values is not None:
                g = np.asarray(grid_values[j], float)
                mids = 0.5 * (g[1:] + g[:-1]) if len(g) > 1 else np.zeros(0)
                self.edges.append((g, mids))
            else:
                e = np.linspace(lo, hi, bins + 1)
                self.edges.append((0.5 * (e[1:] + e[:-1]), e[1:-1]))
        nb = [len(c) for c, _ in self.edges]
        self.s_min = [np.full((b, n), np.inf) for b in nb]
        self.s_max = [np.full((b, n), -np.inf) for b in nb]
        self.s_sum = [np.zeros((b, n)) for b in nb]
        self.s_cnt = [np.zeros((b, n), dtype=np.int64) for b in nb]
        self.top: dict[str, list[tuple[float, int, np.ndarray, np.ndarray]]] = {c: [] for c in self.columns}

    def add(self, samples: np.ndarray, block: dict[str, np.ndarray], first_index: int) -> None:
        """Add a block: sample rows (k × n_joints) and the index columns."""
        X = np.column_stack([np.asarray(block[c], float) for c in self.columns])
        k = len(X)
        finite = np.isfinite(X)
        self.count += k
        self.nan += np.sum(np.isnan(X), axis=0)
        Xmin = np.where(finite, X, np.inf)
        Xmax = np.where(finite, X, -np.inf)
        self.min = np.minimum(self.min, Xmin.min(axis=0))
        self.max = np.maximum(self.max, Xmax.max(axis=0))
        self.sum += np.where(finite, X, 0.0).sum(axis=0)
        self.res.add(X)
        self.plot.add(X, samples)
        # Slices: per row in order, per column, the cell's running min / max / sum / count (compiled; the
        # same sequential per-cell accumulation as np.minimum.at & co., so the same values to the bit).
        for j, (_, inner) in enumerate(self.edges):
            _slice_add(np.searchsorted(inner, samples[:, j]), X, finite, self.s_min[j], self.s_max[j], self.s_sum[j],
                       self.s_cnt[j])
        if self.best_k:
            self._update_top(samples, X, finite, first_index)

    def _update_top(self, samples, X, finite, first_index) -> None:
        ee = [self.columns.index(c) if c in self.columns else None for c in ("ee_x", "ee_y", "ee_z")]
        ranked = [ci for ci, c in enumerate(self.columns) if not (c.startswith("ee_") or c == "singular")]
        if not ranked:
            return
        sign = np.array([1.0 if HIGHER_IS_BETTER.get(self.columns[ci], True) else -1.0 for ci in ranked])
        scores = np.where(finite[:, ranked], X[:, ranked] * sign, -np.inf)
        k = min(self.best_k, len(scores))
        best = np.argpartition(-scores, k - 1, axis=0)[:k]  # per column, as one call per column picks them
        for m, ci in enumerate(ranked):
            c, score, top = self.columns[ci], scores[:, m], self.top[self.columns[ci]]
            new = best[:, m][np.isfinite(score[best[:, m]])]
            if len(top) == self.best_k:  # a new one ties or loses to the k-th best: the stable sort drops it
                new = new[score[new] > top[-1][0]]
            if not new.size:
                continue
            cand = top + [(float(score[i]), first_index + int(i), samples[i].copy(),
                           np.array([X[i, e] for e in ee if e is not None])) for i in new]
            cand.sort(key=lambda t: -t[0])
            self.top[c] = cand[: self.best_k]

    def summary(self) -> dict:
        """JSON-ready: per column min/max/mean/percentiles/NaN count, and the best configurations."""
        out = {}
        R = self.res.rows
        exact = self.res.seen <= self.res.size
        for ci, c in enumerate(self.columns):
            vals = R[:, ci]
            vals = vals[np.isfinite(vals)]
            d = {"min": self.min[ci] if np.isfinite(self.min[ci]) else None,
                 "max": self.max[ci] if np.isfinite(self.max[ci]) else None,
                 "mean": self.sum[ci] / max(self.count - self.nan[ci], 1) if self.count > self.nan[ci] else None,
                 "nan": int(self.nan[ci])}
            if vals.size:
                d.update({f"p{p:02d}": float(v) for p, v in zip(PERCENTILES, np.percentile(vals, PERCENTILES))})
            out[c] = d
        best = {}
        for c, lst in self.top.items():
            if not lst:
                continue
            sign = 1.0 if HIGHER_IS_BETTER.get(c, True) else -1.0
            best[c] = [{"value": sign * s, "sample": i, "q": dict(zip(self.joints, map(float, q))),
                        "ee": [float(x) for x in ee]} for s, i, q, ee in lst]
        return {"indices": out, "percentiles_exact": bool(exact), "best": best}

    def slices(self) -> list[dict]:
        """Per sampled joint: bin centres and per-column min / mean / max arrays (NaN where empty)."""
        out = []
        for j, (centres, _) in enumerate(self.edges):
            cnt = self.s_cnt[j]
            with np.errstate(invalid="ignore", divide="ignore"):
                mean = np.where(cnt > 0, self.s_sum[j] / cnt, np.nan)
            mn = np.where(np.isfinite(self.s_min[j]), self.s_min[j], np.nan)
            mx = np.where(np.isfinite(self.s_max[j]), self.s_max[j], np.nan)
            out.append({"joint": self.joints[j], "x": centres, "min": mn, "mean": mean, "max": mx})
        return out


def warm_calls() -> list:
    """The calls of this module's kernels on throw-away arrays of the types a study passes them
    (``sms_cli.sim.compiled.warmup.KernelCall``): the reservoir's row replacement, the slices' cells."""
    from sms_cli.sim.compiled.warmup import KernelCall

    rows, cells = np.zeros((2, 3)), np.zeros((2, 3))
    return [KernelCall(f"{__name__}:_replace_rows", (np.zeros((1, 3)), 0, rows, 0, np.zeros(2, dtype=np.int64)), cost=0.2),
            KernelCall(f"{__name__}:_slice_add", (np.searchsorted(np.zeros(1), np.zeros(2)), rows, np.isfinite(rows), cells,
                                                  cells.copy(), cells.copy(), np.zeros((2, 3), dtype=np.int64)), cost=0.2)]


@njit(cache=True, nogil=True)
def _slice_add(bins, X, finite, s_min, s_max, s_sum, s_cnt):
    """Add rows X (k × n) to the slice cells (bin × column) of their bins: min / max / sum / count of
    the finite values, as np.minimum.at(s_min, cell, x) etc. row by row (minimum keeps the cell when it
    is below the value, else takes the value; a non-finite value leaves the cell, the sums starting at
    +0.0 stay unchanged by the 0 that ufunc.at added)."""
    for r in range(X.shape[0]):
        b = bins[r]
        for c in range(X.shape[1]):
            if finite[r, c]:
                x = X[r, c]
                if not s_min[b, c] < x:
                    s_min[b, c] = x
                if not s_max[b, c] > x:
                    s_max[b, c] = x
                s_sum[b, c] += x
                s_cnt[b, c] += 1


class Comparison:
    """Sample-by-sample comparison of a variant with the nominal system (same samples)."""

    def __init__(self, columns: list[str]):
        self.columns = [c for c in columns if not c.startswith("ee_") and c != "singular"]
        n = len(self.columns)
        self.lower = np.zeros(n, dtype=np.int64)
        self.higher = np.zeros(n, dtype=np.int64)
        self.valid = np.zeros(n, dtype=np.int64)
        self.dmin = np.full(n, np.inf)
        self.dmax = np.full(n, -np.inf)

    def add(self, nominal: dict[str, np.ndarray], variant: dict[str, np.ndarray]) -> None:
        for i, c in enumerate(self.columns):
            if c not in nominal or c not in variant:
                continue
            d = variant[c] - nominal[c]
            ok = np.isfinite(d)
            self.valid[i] += ok.sum()
            self.lower[i] += (d[ok] < 0).sum()
            self.higher[i] += (d[ok] > 0).sum()
            if ok.any():
                self.dmin[i] = min(self.dmin[i], d[ok].min())
                self.dmax[i] = max(self.dmax[i], d[ok].max())

    def summary(self) -> dict:
        out = {}
        for i, c in enumerate(self.columns):
            if self.valid[i] == 0:
                continue
            out[c] = {"fraction_lower": self.lower[i] / self.valid[i], "fraction_higher": self.higher[i] / self.valid[i],
                      "min_change": self.dmin[i], "max_change": self.dmax[i], "samples": int(self.valid[i])}
        return out
