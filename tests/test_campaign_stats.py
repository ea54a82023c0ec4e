"""Campaign statistics, campaign requirements and figures on synthetic results folders.

Each test writes the folder itself (campaign.json, manifest.jsonl, metrics/part-*.parquet) as the
campaign store lays it out, so the numbers are known in advance.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from statistics import NormalDist

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from pydantic import ValidationError

from sms_cli.campaign import plots
from sms_cli.campaign import stats as S
from sms_cli.campaign.plots import write_plots
from sms_cli.campaign.requirements import CampaignRequirementSpec, evaluate
from sms_cli.report.figstyle import HALF_PX, png_info

SETTLE = "simulate.overall.settling_time_s"


def write_campaign(folder: Path, columns: dict, parts: list[slice] | None = None, requirements: list | None = None,
                   runs: int | None = None, manifest: list[dict] | None = None) -> Path:
    """A campaign results folder: ``columns`` (run, status, param.*, metric.*, req.*) written as the
    parts ``parts`` (slices of the rows, in order), campaign.json, and a manifest (default: one ok
    attempt per row)."""
    n = len(columns["run"])
    columns = {"exit_status": [0] * n, **columns}
    table = pa.table(columns)
    (folder / "metrics").mkdir(parents=True, exist_ok=True)
    for k, sl in enumerate(parts or [slice(0, n)]):
        pq.write_table(table.slice(sl.start, (sl.stop or n) - sl.start), folder / "metrics" / f"part-{k:05d}.parquet")
    (folder / "campaign.json").write_text(json.dumps({
        "mission_name": "synthetic", "runs": runs if runs is not None else len(set(columns["run"])),
        "parameters": [{"name": c[6:]} for c in columns if c.startswith("param.")],
        "requirements": requirements or []}), encoding="utf-8")
    lines = manifest if manifest is not None else [{"run": r, "attempt": 1, "status": s}
                                                  for r, s in zip(columns["run"], columns["status"])]
    (folder / "manifest.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines), encoding="utf-8")
    return folder


def mass_campaign(folder: Path, n: int = 200, slope: float = -0.5, requirements: list | None = None,
                  noise: float = 2.0) -> Path:
    """Settling time falling (``slope`` s/kg) with a body mass of 90-110 kg; run 3 invalid, run 5 diverged."""
    rng = np.random.default_rng(1)
    mass = rng.uniform(90, 110, n)
    settle = 150 + slope * (mass - 100) + rng.normal(0, noise, n)
    status = ["ok"] * n
    status[3], status[5] = "invalid", "diverged"
    settle[3] = np.nan
    return write_campaign(folder, {"run": list(range(n)), "status": status, "param.body_mass": mass,
                                   "param.fixed": np.ones(n), f"metric.{SETTLE}": settle,
                                   "metric.simulate.overall.attitude_error_deg.final": rng.normal(0.01, 0.002, n)},
                          requirements=requirements)


def wilson_closed_form(k: int, n: int, confidence: float) -> tuple[float, float]:
    """Wilson (1927) score interval written out: centre and half-width from p̂ and z."""
    z = NormalDist().inv_cdf(0.5 + confidence / 2)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return centre - half, centre + half


# ----------------------------------------------------------------- intervals and correlations


@pytest.mark.parametrize("k,n,conf", [(0, 10, 0.95), (3, 10, 0.95), (99, 100, 0.95), (100, 100, 0.9), (7, 40, 0.99)])
def test_wilson_interval_matches_its_closed_form(k, n, conf):
    low, high = S.wilson(k, n, conf)
    lo_ref, hi_ref = wilson_closed_form(k, n, conf)
    assert low == pytest.approx(max(lo_ref, 0.0), abs=1e-12)
    assert high == pytest.approx(min(hi_ref, 1.0), abs=1e-12)


def test_wilson_interval_of_newcombes_example():
    """Newcombe 1998 (Statistics in Medicine 17, 857-872), table I: 81 of 263 → 0.2553 to 0.3662."""
    low, high = S.wilson(81, 263)
    assert (round(low, 4), round(high, 4)) == (0.2553, 0.3662)
    assert S.wilson(0, 0) is None


def test_spearman_of_monotone_and_hand_checked_samples():
    x = np.arange(10.0)
    assert S.spearman(x, x ** 3)["rho"] == pytest.approx(1.0)
    assert S.spearman(x, -np.exp(x))["rho"] == pytest.approx(-1.0)
    # d = rank differences (1, -1, 1, -1, 0): ρ = 1 - 6·Σd² / (n (n² - 1)) = 1 - 24/120
    r = S.spearman(np.array([1.0, 2, 3, 4, 5]), np.array([2.0, 1, 4, 3, 5]))
    assert r["rho"] == pytest.approx(0.8) and r["n"] == 5
    half = NormalDist().inv_cdf(0.975) * math.sqrt(1.06 / (5 - 3))
    assert (r["low"], r["high"]) == pytest.approx((math.tanh(math.atanh(0.8) - half), math.tanh(math.atanh(0.8) + half)))


def test_spearman_drops_nan_pairs_and_refuses_constant_or_short_samples():
    x = np.array([1.0, 2, np.nan, 4, 5, 6])
    y = np.array([1.0, 2, 3, 4, np.nan, 6])
    r = S.spearman(x, y)
    assert r["n"] == 4 and r["rho"] == pytest.approx(1.0)
    assert S.spearman(np.ones(10), np.arange(10.0)) is None
    assert S.spearman(np.arange(3.0), np.arange(3.0)) is None


# ----------------------------------------------------------------- the folder and its section


def _ten_runs(tmp_path: Path, **kw) -> Path:
    """Runs 0-9 in two parts; run 4 is in both (first with 999 s, then 14 s); run 2 lacks the settling
    time; run 7 invalid, run 8 diverged."""
    runs = [0, 1, 2, 3, 4, 4, 5, 6, 7, 8, 9]
    settle = [10.0, 11, np.nan, 13, 999, 14, 15, 16, np.nan, 30, 19]
    status = ["ok"] * 8 + ["invalid", "diverged", "ok"]
    req = [True, True, True, True, False, True, False, None, None, False, True]
    mass = [100.0, 101, 102, 103, 104, 104, 105, 106, 107, 108, 109]
    manifest = ([{"run": r, "attempt": 1, "status": "timeout"} for r in (2, 6)]
                + [{"run": r, "attempt": 2 if r in (2, 6) else 1, "status": s} for r, s in zip(runs, status) if r != 4]
                + [{"run": 4, "attempt": 1, "status": "ok"}, {"run": 4, "attempt": 2, "status": "ok"}]
                + [{"run": 10, "attempt": 1, "status": "crashed"}])
    return write_campaign(tmp_path, {"run": runs, "status": status, "param.body_mass": mass, f"metric.{SETTLE}": settle,
                                     "req.settles": pa.array(req, pa.bool_())},
                          parts=[slice(0, 5), slice(5, None)], runs=12, manifest=manifest, **kw)


def test_read_runs_keeps_a_run_of_two_parts_once_from_the_last_part(tmp_path):
    t = S.read_runs(_ten_runs(tmp_path))
    assert t.column("run").to_pylist() == list(range(10))
    assert S.column(t, f"metric.{SETTLE}")[4] == 14.0


def test_read_runs_orders_parts_by_number_not_by_text(tmp_path):
    cols = {"run": [1, 1], "status": ["ok", "ok"], f"metric.{SETTLE}": [5.0, 6.0]}
    write_campaign(tmp_path, cols, parts=[slice(0, 1), slice(1, 2)])
    (tmp_path / "metrics" / "part-00001.parquet").rename(tmp_path / "metrics" / "part-10.parquet")
    (tmp_path / "metrics" / "part-00000.parquet").rename(tmp_path / "metrics" / "part-9.parquet")
    assert S.column(S.read_runs(tmp_path), f"metric.{SETTLE}").tolist() == [6.0]


def test_campaign_section_counts(tmp_path):
    n = S.campaign_section(_ten_runs(tmp_path))["runs"]
    assert n == {"total": 12, "finished": 10, "ok": 8, "invalid": 1, "diverged": 1, "unfinished": 2,
                 "attempts": 14, "retried": 3}


def test_metric_statistics_and_the_runs_of_the_extremes(tmp_path):
    st = S.campaign_section(_ten_runs(tmp_path))["metrics"][SETTLE]
    ran = np.array([10.0, 11, 13, 14, 15, 16, 30, 19])  # run 4 once (14 s), run 2 and invalid run 7 out, diverged run 8 in
    assert st["n"] == 8 and st["unit"] == "s"
    assert st["mean"] == pytest.approx(ran.mean()) and st["std"] == pytest.approx(ran.std(ddof=1))
    assert st["p50"] == pytest.approx(14.5) and st["p99"] == pytest.approx(np.percentile(ran, 99))
    assert st["min"] == {"value": 10.0, "run": 0}
    assert st["max"] == {"value": 30.0, "run": 8}


def test_mission_pass_rates_leave_out_invalid_runs_and_fail_diverged_and_missing(tmp_path):
    (rate,) = S.campaign_section(_ten_runs(tmp_path))["pass_rates"]
    # counted: runs 0-6, 8, 9 (7 is invalid); passed: 0-4 and 9 (5 false, 6 missing, 8 diverged)
    assert (rate["name"], rate["passed"], rate["n"]) == ("settles", 6, 9)
    assert (rate["low"], rate["high"]) == pytest.approx(wilson_closed_form(6, 9, 0.95))


def test_sensitivities_skip_constant_parameters_and_sort_by_strength(tmp_path):
    sec = S.campaign_section(mass_campaign(tmp_path))
    pairs = [(s["metric"], s["parameter"]) for s in sec["sensitivities"]]
    assert pairs[0] == (SETTLE, "body_mass") and sec["sensitivities"][0]["rho"] < -0.7
    assert all(p != "fixed" for _, p in pairs)
    assert [abs(s["rho"]) for s in sec["sensitivities"]] == sorted((abs(s["rho"]) for s in sec["sensitivities"]), reverse=True)
    assert sec["sensitivities"][0]["n"] == 199  # the invalid run has no settling time
    json.dumps(sec, allow_nan=False)  # results.json material


# ----------------------------------------------------------------- campaign requirements


def _spec(**kw) -> CampaignRequirementSpec:
    return CampaignRequirementSpec(name="r", metric=SETTLE, **kw)


def _settle_runs(tmp_path: Path, times: list[float], status: list[str] | None = None) -> pa.Table:
    n = len(times)
    return S.read_runs(write_campaign(tmp_path, {"run": list(range(n)), "status": status or ["ok"] * n,
                                                 "param.body_mass": np.linspace(90, 110, n), f"metric.{SETTLE}": times}))


def test_pass_rate_met_by_the_point_estimate_but_not_by_the_wilson_lower_bound_fails(tmp_path):
    t = _settle_runs(tmp_path, [150.0] * 99 + [170.0])
    v = evaluate(_spec(max="160 s", pass_rate_min=0.98), t)
    assert v.status == "fail"  # 99/100 = 0.99 ≥ 0.98, but the Wilson lower bound is 0.946
    assert v.value == pytest.approx(wilson_closed_form(99, 100, 0.95)[0])
    assert v.margin == pytest.approx(v.value - 0.98)
    assert evaluate(_spec(max="160 s", pass_rate_min=0.9), t).status == "pass"


def test_pass_rate_bounds_in_other_units_and_lower_bounds(tmp_path):
    t = _settle_runs(tmp_path, [150.0] * 100)
    assert evaluate(_spec(max="2.6 min", pass_rate_min=0.9), t).status == "pass"
    assert evaluate(_spec(max="2.4 min", pass_rate_min=0.9), t).status == "fail"
    assert evaluate(_spec(max=2.6, unit="min", pass_rate_min=0.9), t).status == "pass"
    assert evaluate(_spec(min="155 s", pass_rate_min=0.9), t).status == "fail"


def test_pass_rate_leaves_out_invalid_runs_and_fails_diverged_ones(tmp_path):
    times = [150.0] * 60 + [np.nan] * 40
    t = _settle_runs(tmp_path, times, ["ok"] * 60 + ["invalid"] * 40)
    v = evaluate(_spec(max="160 s", pass_rate_min=0.9), t)
    assert v.status == "pass" and v.value == pytest.approx(S.wilson(60, 60)[0])
    t = _settle_runs(tmp_path, [150.0] * 100, ["ok"] * 60 + ["diverged"] * 40)
    v = evaluate(_spec(max="160 s", pass_rate_min=0.5), t)
    assert v.value == pytest.approx(S.wilson(60, 100)[0])


def test_pass_rate_counts_a_missing_metric_as_a_failure_and_names_an_unknown_one(tmp_path):
    t = _settle_runs(tmp_path, [150.0] * 50 + [np.nan] * 50)
    assert evaluate(_spec(max="160 s", pass_rate_min=0.4), t).value == pytest.approx(S.wilson(50, 100)[0])
    v = evaluate(CampaignRequirementSpec(name="r", metric="simulate.overall.settling_tim_s", max="1 s",
                                         pass_rate_min=0.5), t)
    assert v.status == "missing" and "did you mean 'simulate.overall.settling_time_s'" in v.message


def test_correlation_verdicts_on_the_fisher_z_bound(tmp_path):
    falling = S.read_runs(mass_campaign(tmp_path / "a", slope=-0.5))
    rising = S.read_runs(mass_campaign(tmp_path / "b", slope=+0.5))
    weak = S.read_runs(mass_campaign(tmp_path / "c", n=40, slope=-0.05, noise=5))
    spec = _spec(correlation_with="body_mass", rho_max=0)
    v = evaluate(spec, falling)
    assert v.status == "pass" and v.value < 0
    # the invalid run has no settling time: its pair drops out; the diverged run counts
    assert v.value == pytest.approx(S.spearman(S.column(falling, "param.body_mass"), S.column(falling, f"metric.{SETTLE}"))["high"])
    assert evaluate(spec, rising).status == "fail"
    assert evaluate(_spec(correlation_with="body_mass", rho_min=0), rising).status == "pass"
    weak_rising = S.read_runs(mass_campaign(tmp_path / "d", n=40, slope=+0.3, noise=5))
    r = S.spearman(S.column(weak_rising, "param.body_mass"), S.column(weak_rising, f"metric.{SETTLE}"))
    assert r["low"] < 0 < r["rho"]
    assert evaluate(_spec(correlation_with="body_mass", rho_min=0), weak_rising).status == "fail"
    r = S.spearman(S.column(weak, "param.body_mass"), S.column(weak, f"metric.{SETTLE}"))
    assert r["rho"] < 0 < r["high"]  # the point estimate has the sign, the interval does not
    assert evaluate(spec, weak).status == "fail"
    assert evaluate(_spec(correlation_with="body_mass", rho_min=-0.9, rho_max=-0.5), falling).status == "pass"
    assert evaluate(_spec(correlation_with="body_mas", rho_max=0), falling).status == "missing"


def test_campaign_requirement_spec_accepts_the_two_kinds_and_refuses_mixtures():
    assert _spec(max="160 s", pass_rate_min=0.99).kind == "pass_rate"
    assert _spec(correlation_with="body_mass", rho_max=0).kind == "correlation"
    assert _spec(correlation_with="m", rho_max=0).confidence == 0.95
    bad = [{}, {"max": "160 s"}, {"pass_rate_min": 0.9}, {"max": "1 kg", "pass_rate_min": 0.9},
           {"max": 1, "pass_rate_min": 0.0}, {"max": 1, "pass_rate_min": 1.2}, {"correlation_with": "m"},
           {"max": 1, "pass_rate_min": 0.9, "rho_max": 0}, {"correlation_with": "m", "rho_min": 0.5, "rho_max": 0.1},
           {"correlation_with": "m", "rho_max": 1.5}, {"correlation_with": "m", "rho_max": 0, "confidence": 1.0},
           {"max": 1, "pass_rate_min": 0.9, "typo": 1}]
    for kw in bad:
        with pytest.raises(ValidationError):
            _spec(**kw)
    schema = CampaignRequirementSpec.model_json_schema()["properties"]
    assert all(p.get("description") for p in schema.values())


# ----------------------------------------------------------------- figures


def test_a_correlation_requirement_gets_its_scatter_beyond_the_strongest_pairs(tmp_path, monkeypatch):
    weak = "simulate.overall.attitude_error_deg.final"
    folder = mass_campaign(tmp_path, requirements=[{"name": "w", "metric": weak, "correlation_with": "body_mass",
                                                    "rho_max": 0.5}])
    monkeypatch.setattr(plots, "TOP_PAIRS", 1)
    files = [p.file for p in plots.plan(folder, S.campaign_section(folder))]
    assert files == [f"plots/hist--{SETTLE}.png", f"plots/hist--{weak}.png", f"plots/scatter--{weak}--body_mass.png",
                     f"plots/scatter--{SETTLE}--body_mass.png"]


def test_figures_of_the_requirement_metrics_and_the_strongest_pairs(tmp_path):
    reqs = [{"name": "settles", "metric": SETTLE, "max": "160 s", "pass_rate_min": 0.9},
            {"name": "sign", "metric": SETTLE, "correlation_with": "body_mass", "rho_max": 0}]
    folder = mass_campaign(tmp_path, requirements=reqs)
    section = S.campaign_section(folder)
    names = write_plots(folder, section)
    assert f"plots/hist--{SETTLE}.png" in names and f"plots/scatter--{SETTLE}--body_mass.png" in names
    assert "plots/hist--simulate.overall.attitude_error_deg.final.png" in names
    for n in names:
        info = png_info((folder / n).read_bytes())
        assert info["width"] == HALF_PX and float(info["text"]["sms:text-overlaps"]) == 0


def test_perfectly_ordered_ranks_do_not_make_a_sign_significant_from_four_runs():
    """|ρ| = 1 from 4 runs happens by chance 1 time in 12 (two-sided): its interval must include 0;
    from 8 runs (1 in 20160) it must not. Without the half-step, atanh(1) = ∞ gives [1, 1] for any n."""
    four = S.spearman(np.arange(4.0), np.arange(4.0) ** 2)
    eight = S.spearman(np.arange(8.0), -np.arange(8.0) ** 3)
    assert four["rho"] == 1.0 and four["low"] < 0.0 < four["high"] <= 1.0
    assert eight["rho"] == -1.0 and eight["high"] < 0.0
