"""Workspace sampling, streamed statistics and the analysis schema."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from pydantic import ValidationError

from sms_cli.analysis.sampling import JointRange, Progress, Sampler
from sms_cli.analysis.schema import AnalysisSpec
from sms_cli.analysis.summary import Comparison, Reservoir, StudyStats


def test_grid_covers_every_combination_once():
    r = [JointRange("a", 0, 1), JointRange("b", -1, 1), JointRange("c", 0, 2)]
    s = Sampler(r, "grid", 5, chunk=7)
    rows = np.vstack(list(s.chunks()))
    assert s.total == 125 and rows.shape == (125, 3)
    assert len({tuple(x) for x in rows}) == 125
    np.testing.assert_allclose(np.unique(rows[:, 1]), np.linspace(-1, 1, 5))
    assert np.all(np.diff(rows[:, 0]) >= 0)  # first joint varies slowest


def test_periodic_joint_grid_skips_duplicate_end():
    g = JointRange("yaw", -math.pi, math.pi, periodic=True).grid(8)
    assert len(g) == 8 and g[-1] < math.pi - 1e-9


def test_symmetry_halves_a_range():
    r = JointRange("yaw", -math.pi, math.pi, periodic=True).halved("upper", 0.0)
    assert (r.lower, r.upper, r.periodic) == (0.0, math.pi, False)
    assert len(r.grid(19)) == 19 and r.grid(19)[-1] == pytest.approx(math.pi)  # Kraiem 2022: 19 values on [0, pi]
    with pytest.raises(ValueError):
        JointRange("x", 0, 1).halved("lower", 2.0)


def test_sobol_is_deterministic_in_range_and_chunk_independent():
    r = [JointRange("a", -2, 3), JointRange("b", 0, 0.5)]
    a = np.vstack(list(Sampler(r, "sobol", 1000, seed=4, chunk=128).chunks()))
    b = np.vstack(list(Sampler(r, "sobol", 1000, seed=4, chunk=1000).chunks()))
    np.testing.assert_array_equal(a, b)
    assert a.shape == (1000, 2) and a[:, 0].min() >= -2 and a[:, 0].max() <= 3
    # low discrepancy: every tenth of [lo, hi] gets close to 10 % of the points
    counts = np.histogram(a[:, 0], bins=10, range=(-2, 3))[0]
    assert counts.min() >= 90 and counts.max() <= 110


def test_a_million_samples_stream_in_bounded_chunks():
    s = Sampler([JointRange("a", 0, 1), JointRange("b", 0, 1)], "grid", 1000, chunk=4096)
    assert s.total == 1_000_000
    sizes = [len(c) for c in s.chunks()]
    assert sum(sizes) == 1_000_000 and max(sizes) == 4096


def test_progress_writes_to_its_stream():
    buf = io.StringIO()
    p = Progress(10, "x", stream=buf, enabled=True, min_interval=0)
    p.update(5)
    assert "50.0%" in buf.getvalue()
    p.update(5)
    p.close()
    assert "10/10" in buf.getvalue() and buf.getvalue().endswith("\n")


def test_reservoir_is_exact_until_full_then_uniform():
    r = Reservoir(100, 1, seed=0)
    r.add(np.arange(60.0)[:, None])
    np.testing.assert_array_equal(r.rows[:, 0], np.arange(60.0))
    for start in range(60, 20060, 500):
        r.add(np.arange(start, start + 500.0)[:, None])
    assert r.rows.shape == (100, 1) and len(np.unique(r.rows)) == 100
    assert 5000 < r.rows.mean() < 15000  # a uniform subset of 0..20059 (mean 10030)


def test_stats_min_max_percentiles_best_and_slices():
    rng = np.random.default_rng(0)
    samples = rng.uniform(0, 1, size=(1000, 2))
    vals = {"ee_x": samples[:, 0], "ee_y": samples[:, 1], "ee_z": 0 * samples[:, 0],
            "K_m": samples[:, 0] * samples[:, 1], "mu_gjm": samples[:, 0] + 1.0}
    vals["mu_gjm"][3] = np.nan
    st = StudyStats(list(vals), ["a", "b"], [(0, 1), (0, 1)], None, best=3, bins=4)
    for k in range(0, 1000, 250):
        st.add(samples[k:k + 250], {c: v[k:k + 250] for c, v in vals.items()}, k)
    s = st.summary()
    assert s["indices"]["K_m"]["max"] == pytest.approx(vals["K_m"].max())
    assert s["indices"]["K_m"]["p50"] == pytest.approx(np.percentile(vals["K_m"], 50))
    assert s["indices"]["mu_gjm"]["nan"] == 1
    assert s["best"]["K_m"][0]["value"] == pytest.approx(vals["K_m"].min())  # lower K_m is better
    assert s["best"]["mu_gjm"][0]["value"] == pytest.approx(np.nanmax(vals["mu_gjm"]))
    sl = st.slices()[0]
    ci = st.columns.index("K_m")
    in_bin = samples[:, 0] < 0.25
    assert sl["max"][0, ci] == pytest.approx(vals["K_m"][in_bin].max())


def test_comparison_counts():
    c = Comparison(["K_m"])
    c.add({"K_m": np.array([0.5, 0.6, np.nan])}, {"K_m": np.array([0.4, 0.7, 0.1])})
    s = c.summary()["K_m"]
    assert s["fraction_lower"] == 0.5 and s["samples"] == 2 and s["min_change"] == pytest.approx(-0.1)


def test_schema_accepts_units_and_rejects_typos():
    a = AnalysisSpec.model_validate({"sampling": {"method": "grid", "n": 19, "symmetry": {"joint": "j1", "about": "0 deg"},
                                                  "ranges": {"rail": ["0 m", "2 m"], "j2": ["-90 deg", "90 deg"]}},
                                     "limits": {"joint_speed": "0.5 rpm", "wheel_speed": {"rw1": "2800 rpm"}}})
    assert a.limits.joint_speed == pytest.approx(0.5 * 2 * math.pi / 60)
    assert a.sampling.ranges["j2"][0] == pytest.approx(-math.pi / 2)
    with pytest.raises(ValidationError):
        AnalysisSpec.model_validate({"sampling": {"methd": "grid"}})
    with pytest.raises(ValidationError):
        AnalysisSpec.model_validate({"sampling": {"ranges": {"j": [1, 0]}}})
    with pytest.raises(ValidationError):
        AnalysisSpec.model_validate({"variants": [{"name": "nominal"}]})


def test_stats_streamed_in_blocks_equal_one_block_and_a_brute_force_best():
    """Block by block (the slices accumulated per cell in row order, the best kept per block)
    gives what one block gives, and the best configurations are the sorted top of all samples."""
    rng = np.random.default_rng(3)
    n = 600
    samples = rng.random((n, 2))
    cols = {"mu_gjm": np.round(np.sin(4 * samples[:, 0]) * samples[:, 1], 2),  # many ties
            "K_m": np.where(rng.random(n) < 0.1, np.nan, samples[:, 0] * samples[:, 1]), "ee_x": samples[:, 0]}

    def stats(block: int) -> StudyStats:
        st = StudyStats(list(cols), ["a", "b"], [(0.0, 1.0), (0.0, 1.0)], None, best=5)
        for s in range(0, n, block):
            st.add(samples[s:s + block], {c: v[s:s + block] for c, v in cols.items()}, s)
        return st

    one, many = stats(n), stats(16)
    s1, s2 = one.summary(), many.summary()
    assert repr(s1["best"]) == repr(s2["best"])
    for c in cols:  # sums are added per block: the means agree to rounding, the rest exactly
        m1, m2 = s1["indices"][c].pop("mean"), s2["indices"][c].pop("mean")
        assert m1 == pytest.approx(m2, rel=1e-12) and s1["indices"][c] == s2["indices"][c]
    for a, b in zip(one.slices(), many.slices()):
        np.testing.assert_array_equal(a["min"], b["min"])
        np.testing.assert_array_equal(a["max"], b["max"])
        np.testing.assert_allclose(a["mean"], b["mean"], rtol=1e-12, equal_nan=True)
    for c, higher in (("mu_gjm", True), ("K_m", False)):
        v = cols[c]
        order = sorted((i for i in range(n) if np.isfinite(v[i])), key=lambda i: -v[i] if higher else v[i])  # stable
        assert [b["sample"] for b in many.summary()["best"][c]] == order[:5], c


def test_slices_accumulate_like_ufunc_at_to_the_bit():
    """The compiled slice pass (summary._slice_add) gives the bits of NumPy's sequential per-cell
    accumulation: np.minimum.at / np.maximum.at / np.add.at in row order, non-finite values counted
    out (+inf / -inf / 0 / 0), -0.0 sums included."""
    rng = np.random.default_rng(11)
    n, cols = 3000, ["a", "b", "K_m", "z", "w"]
    samples = rng.random((n, 2))
    vals = {c: rng.normal(size=n) * 10.0 ** rng.integers(-8, 8, size=n) for c in cols}
    vals["a"][::7], vals["b"][::11], vals["K_m"][::5] = np.nan, np.inf, -0.0
    vals["z"] = np.where(rng.random(n) < 0.5, -0.0, 0.0)  # signed zeros: ties of min / max, -0.0 sums
    vals["z"][::9] = np.nan
    vals["w"] = np.full(n, -0.0)  # sums start at +0.0: -0.0 values and NaN rows leave +0.0
    vals["w"][::9] = np.nan
    st = StudyStats(cols, ["p", "q"], [(0.0, 1.0), (0.0, 1.0)], None, best=0, bins=6)
    for s in range(0, n, 700):
        st.add(samples[s:s + 700], {c: v[s:s + 700] for c, v in vals.items()}, s)
    X = np.column_stack([vals[c] for c in cols])
    fin = np.isfinite(X)
    for j, (_, inner) in enumerate(st.edges):
        b = np.searchsorted(inner, samples[:, j])
        ref = [np.full((6, 5), np.inf), np.full((6, 5), -np.inf), np.zeros((6, 5)), np.zeros((6, 5), np.int64)]
        for s in range(0, n, 700):  # the blocks, then row by row as the reference ufunc.at calls go
            rows = np.arange(s, min(s + 700, n))
            cell = (b[rows][:, None] * 5 + np.arange(5)).ravel()
            np.minimum.at(ref[0].reshape(-1), cell, np.where(fin[rows], X[rows], np.inf).ravel())
            np.maximum.at(ref[1].reshape(-1), cell, np.where(fin[rows], X[rows], -np.inf).ravel())
            np.add.at(ref[2].reshape(-1), cell, np.where(fin[rows], X[rows], 0.0).ravel())
            np.add.at(ref[3].reshape(-1), cell, fin[rows].astype(np.int64).ravel())
        for got, want in zip((st.s_min[j], st.s_max[j], st.s_sum[j], st.s_cnt[j]), ref):
            assert got.tobytes() == want.tobytes()


def test_reservoir_keeps_the_rows_of_algorithm_r_to_the_bit():
    """Reservoir.add (rows copied by a compiled loop, extra columns as parts) keeps the rows that the
    fancy assignment data[j[keep]] = rows[keep] of algorithm R keeps, with the same draws."""
    rng = np.random.default_rng(2)
    size, seen = 40, 0
    r = Reservoir(size, 3, seed=7)
    draws = np.random.default_rng(7)
    ref = np.empty((size, 3))
    for _ in range(30):
        k = int(rng.integers(1, 60))
        a, b = rng.normal(size=(k, 2)), rng.normal(size=(k, 1))
        r.add(a, b)
        rows = np.column_stack([a, b])
        free = max(0, min(size - seen, k))
        ref[seen:seen + free] = rows[:free]
        if free < k:
            idx = np.arange(seen + free, seen + k)
            j = (draws.random(len(idx)) * (idx + 1)).astype(np.int64)
            keep = j < size
            ref[j[keep]] = rows[free:][keep]
        seen += k
    assert r.seen == seen and r.rows.tobytes() == ref.tobytes()
