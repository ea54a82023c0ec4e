"""Joint-space samples of the arm, generated chunk by chunk (bounded memory for 10^6 samples).

A sample is one row of joint coordinates (rad for revolute, m for prismatic joints) over the
sampled joints, in the order of ``JointRange`` list. ``grid`` takes ``n`` values per joint
(the first joint varies slowest); ``sobol`` takes ``n`` scrambled Sobol points (scipy.stats.qmc).
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass
from typing import Iterator, TextIO

import numpy as np


@dataclass(frozen=True)
class JointRange:
    """The sampled interval of one joint. ``periodic``: a full turn (the upper end is the lower one)."""

    name: str
    lower: float
    upper: float
    periodic: bool = False

    def halved(self, keep: str, about: float | None) -> "JointRange":
        """The half range kept by a symmetry plane through ``about`` (default: the middle)."""
        mid = 0.5 * (self.lower + self.upper) if about is None else float(about)
        if not self.lower < mid < self.upper:
            raise ValueError(f"symmetry point {mid:g} is not inside the range [{self.lower:g}, {self.upper:g}] of {self.name}")
        if keep == "upper":
            return JointRange(self.name, mid, self.upper, False)
        return JointRange(self.name, self.lower, mid, False)

    def grid(self, n: int) -> np.ndarray:
        """``n`` evenly spaced values; a full turn excludes its duplicate end point."""
        if n == 1:
            return np.array([0.5 * (self.lower + self.upper)])
        return np.linspace(self.lower, self.upper, n, endpoint=not self.periodic)


class Sampler:
    """Chunked generator of joint samples: ``for block in sampler.chunks(): ...`` (block: k × n_joints)."""

    def __init__(self, ranges: list[JointRange], method: str, n: int, *, seed: int = 0, chunk: int = 4096):
        if not ranges:
            raise ValueError("no joint to sample")
        if method not in ("grid", "sobol"):
            raise ValueError(f"unknown sampling method {method!r}")
        self.ranges = list(ranges)
        self.method = method
        self.n = int(n)
        self.seed = seed
        self.chunk = int(chunk)
        if method == "grid":
            self._axes = [r.grid(self.n) for r in self.ranges]
            self.shape: tuple[int, ...] = tuple(len(a) for a in self._axes)
            self.total = math.prod(self.shape)
        else:
            self.shape = ()
            self.total = self.n
        self.names = [r.name for r in self.ranges]

    def chunks(self) -> Iterator[np.ndarray]:
        """Blocks of at most ``chunk`` samples, in a fixed order (same samples on every call)."""
        if self.method == "grid":
            yield from self._grid_chunks()
        else:
            yield from self._sobol_chunks()

    def _grid_chunks(self) -> Iterator[np.ndarray]:
        for start in range(0, self.total, self.chunk):
            flat = np.arange(start, min(start + self.chunk, self.total))
            idx = np.unravel_index(flat, self.shape)
            yield np.column_stack([ax[i] for ax, i in zip(self._axes, idx)])

    def _sobol_chunks(self) -> Iterator[np.ndarray]:
        from scipy.stats import qmc

        lo = np.array([r.lower for r in self.ranges])
        span = np.array([r.upper - r.lower for r in self.ranges])
        engine = qmc.Sobol(d=len(self.ranges), scramble=True, seed=self.seed)
        done = 0
        while done < self.total:
            k = min(self.chunk, self.total - done)
            with warnings.catch_warnings():  # balance warning: n need not be a power of 2
                warnings.simplefilter("ignore", UserWarning)
                u = engine.random(k)
            done += k
            yield lo + u * span


class Progress:
    """A one-line progress display on stderr (only when stderr is a terminal, unless forced)."""

    def __init__(self, total: int, label: str, *, stream: TextIO | None = None, enabled: bool | None = None,
                 min_interval: float = 0.2):
        self.total = max(int(total), 1)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = (hasattr(self.stream, "isatty") and self.stream.isatty()) if enabled is None else enabled
        self.min_interval = min_interval
        self.done = 0
        self._t0 = time.perf_counter()
        self._last = -1.0

    def update(self, n: int) -> None:
        self.done += int(n)
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < self.min_interval and self.done < self.total:
            return
        self._last = now
        self._draw(now)

    def _draw(self, now: float) -> None:
        elapsed = now - self._t0
        rate = self.done / elapsed if elapsed > 0 else 0.0
        frac = min(self.done / self.total, 1.0)
        bar = "#" * int(24 * frac)
        eta = (self.total - self.done) / rate if rate > 0 else 0.0
        self.stream.write(f"\r{self.label} [{bar:<24}] {100 * frac:5.1f}% {self.done}/{self.total} "
                          f"{rate:,.0f}/s eta {eta:,.0f} s ")
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self._draw(time.perf_counter())
            self.stream.write("\n")
            self.stream.flush()
