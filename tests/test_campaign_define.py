"""sms campaign: the definition of the runs (seeding, designs, distributions) and what a run applies.

Oracles: the declared distribution itself (Kolmogorov–Smirnov against scipy's CDF), the stream
independence numpy's SeedSequence documents (a parameter's draws depend on its name and the run
only), and the built model read back after the run's mission is compiled.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from sms_cli.campaign.dispersions import draws, grid_levels, run_count
from sms_cli.campaign.runner import _build, read_back
from sms_cli.campaign.schema import CampaignSpec
from sms_cli.campaign.stage import define
from sms_cli.errors import InputError
from sms_cli.mission.load import load_mission, load_mission_text

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "tests" / "data" / "campaign" / "basilisk_small.yaml"


def spec(dispersions: list[dict], **kw) -> CampaignSpec:
    return CampaignSpec.model_validate({"runs": kw.pop("runs", 64), "dispersions": dispersions, **kw})


U = {"name": "a", "path": "x.a", "distribution": "uniform", "low": -0.1, "high": 0.1}
N = {"name": "b", "path": "x.b", "distribution": "normal", "std": 0.05}
C = {"name": "c", "path": "x.c", "distribution": "choice", "values": [1, 2, 5], "mode": "absolute"}


# ------------------------------------------------------------------ seeding
@pytest.mark.parametrize("design", ["monte_carlo", "lhs"])
def test_adding_or_reordering_a_dispersion_leaves_the_other_draws_unchanged(design):
    before = draws(spec([U, N], design=design), 1234)
    after = draws(spec([C, N, U], design=design), 1234)
    for r in before:
        assert before[r]["a"] == after[r]["a"] and before[r]["b"] == after[r]["b"]


def test_a_run_is_drawn_the_same_alone_as_in_the_whole_campaign():
    s = spec([U, N, C])
    whole = draws(s, 99)
    assert all(draws(s, 99, [r])[r] == whole[r] for r in (0, 17, 63))


def test_other_entropy_other_draws_and_names_key_the_streams():
    s = spec([U])
    assert draws(s, 1)[0]["a"] != draws(s, 2)[0]["a"]
    renamed = spec([{**U, "name": "a2"}])
    assert draws(renamed, 1)[0]["a2"] != draws(s, 1)[0]["a"]


# ------------------------------------------------------------------ distributions
@pytest.mark.parametrize("design", ["monte_carlo", "lhs", "sobol"])
def test_draws_follow_the_declared_distribution(design):
    d = [U, N, {"name": "t", "path": "x.t", "distribution": "truncated_normal", "mean": 0.01, "std": 0.1,
                "low": -0.05, "high": 0.2}]
    x = draws(spec(d, runs=1024, design=design), 7)
    col = lambda k: np.array([x[r][k] for r in x])  # noqa: E731
    assert stats.kstest(col("a"), stats.uniform(-0.1, 0.2).cdf).pvalue > 1e-3
    assert stats.kstest(col("b"), stats.norm(0, 0.05).cdf).pvalue > 1e-3
    t = col("t")
    assert t.min() >= -0.05 and t.max() <= 0.2  # truncated by declaration, never beyond
    assert stats.kstest(t, stats.truncnorm((-0.05 - 0.01) / 0.1, (0.2 - 0.01) / 0.1, 0.01, 0.1).cdf).pvalue > 1e-3


def test_lhs_puts_one_draw_in_each_stratum():
    x = draws(spec([U], runs=50, design="lhs"), 3)
    u = (np.array([x[r]["a"] for r in x]) + 0.1) / 0.2
    assert sorted(np.floor(u * 50).astype(int)) == list(range(50))


def test_choice_draws_every_value_at_its_weight():
    x = draws(spec([{**C, "weights": [1, 2, 1]}], runs=4000), 5)
    v = np.array([x[r]["c"] for r in x])
    assert set(v) == {1.0, 2.0, 5.0}
    assert abs(np.mean(v == 2.0) - 0.5) < 0.03


def test_grid_is_the_cartesian_product_of_the_levels():
    s = CampaignSpec.model_validate({"design": "grid", "dispersions": [{**U, "levels": 3}, C]})
    assert run_count(s) == 9
    np.testing.assert_allclose(grid_levels(s.dispersions[0]), [-0.1, 0.0, 0.1])
    pts = {(v["a"], v["c"]) for v in draws(s, 0).values()}
    assert pts == {(a, c) for a in (-0.1, 0.0, 0.1) for c in (1.0, 2.0, 5.0)}


@pytest.mark.parametrize("bad, words", [
    ({**U, "low": 0.2}, "below high"),
    ({**N, "std": -0.1}, "std must be positive"),
    ({"name": "t", "path": "x.t", "distribution": "truncated_normal", "std": 0.1, "low": 0.1, "high": 0.2},
     "within [low, high]"),
    ({**C, "weights": [1, 2]}, "one non-negative weight per value"),
    ({"name": "z", "path": "x..z", "distribution": "uniform", "low": 0, "high": 1}, "empty part"),
])
def test_distribution_parameters_out_of_range_are_refused(bad, words):
    with pytest.raises(Exception, match=words.replace("[", r"\[").replace("]", r"\]")):
        spec([bad])


# ------------------------------------------------------------------ what a run applies
def _campaign(extra: str) -> object:
    text = SMALL.read_text().replace("extends: ../../../missions/", f"extends: {ROOT}/missions/")
    return define(load_mission_text(text + extra, base_dir=SMALL.parent, name="c.yaml"))


def test_the_value_that_ran_equals_the_declared_sample_for_every_kind():
    """Uniform/truncated-normal relative, normal relative on a list item named by its name, an offset
    on a vector component, an absolute choice on a phase named by its name: read back after the run's
    mission is validated and compiled."""
    c = define(load_mission(SMALL))
    nominal_total = _build(c.tasks([0])[0].__class__(**{**c.tasks([0])[0].__dict__, "samples": {}}))[1].total_mass
    for task in c.tasks([0, 3, 5]):
        loaded, sm = _build(task)
        applied = read_back(loaded, sm, task)
        assert applied == {name: value for name, (_, value) in task.samples.items()}
        assert sm.wheels[0].max_torque == task.samples["rw1_torque"][1]  # the built actuator, not the spec only
        nominal_hub = c.parameters[[p.name for p in c.parameters].index("hub_mass")].nominal
        assert sm.total_mass - nominal_total == pytest.approx(task.samples["hub_mass"][1] - nominal_hub, abs=1e-9)


def test_relative_dispersion_multiplies_the_nominal_si_value():
    c = define(load_mission(SMALL))
    x = draws(c.spec, c.entropy, [2])[2]
    s = c.samples([2])[2]
    assert s["K"][1] == pytest.approx(3.5 * (1 + x["K"]), rel=1e-15)
    assert s["rw1_torque"][1] == pytest.approx(0.2 * (1 + x["rw1_torque"]), rel=1e-15)  # "0.2 N m" → SI
    assert s["wz0"][1] == pytest.approx(0.03 + x["wz0"], rel=1e-15)
    assert s["duration"][1] in (400.0, 600.0)


def test_a_vector_path_scales_every_component_by_one_draw():
    mission = (ROOT / "missions" / "pulsar_simple.yaml")
    text = f"extends: {mission}\ncampaign:\n  runs: 2\n  entropy: 1\n  dispersions:\n" \
           "    - {name: tile_inertia, path: payloads.0.inertia, distribution: uniform, low: -3 %, high: 3 %}\n" \
           "    - {name: tile_mass, path: payloads.0.mass, distribution: uniform, low: -10 %, high: 10 %}\n"
    c = define(load_mission_text(text, base_dir=mission.parent, name="p.yaml"))
    task = c.tasks([1])[0]
    loaded, sm = _build(task)
    nominal = np.asarray(c.parameters[0].nominal)
    applied = np.asarray(read_back(loaded, sm, task)["tile_inertia"])
    ratio = applied[nominal != 0] / nominal[nominal != 0]
    assert np.ptp(ratio) < 1e-15 and ratio[0] != 1.0
    name = loaded.mission.payloads[0].name
    assert sm.payloads[name].inertia_in_joint.mass == task.samples["tile_mass"][1]


def test_a_non_physical_draw_is_an_invalid_run_with_its_reason_never_clipped():
    from sms_cli.campaign.runner import execute_run

    c = define(load_mission(SMALL))
    task = copy.replace(c.tasks([0])[0], samples={"K": ("simulation.phases.detumble.duration", -5.0)}) \
        if hasattr(copy, "replace") else None
    if task is None:
        from dataclasses import replace

        task = replace(c.tasks([0])[0], samples={"K": ("simulation.phases.detumble.duration", -5.0)})
    o = execute_run(task)
    assert o.status == "invalid" and o.exit_status == 2
    assert "duration" in o.message


# ------------------------------------------------------------------ bad campaign input
@pytest.mark.parametrize("mission, dispersion, line, words", [
    (SMALL, "{name: K, path: simulation.attitude.KK, distribution: uniform, low: 0, high: 1}", 5,
     "did you mean simulation.attitude.K?"),
    (ROOT / "missions" / "pulsar_simple.yaml",
     "{name: b, path: simulation.sensors.gyro.bias.0, distribution: normal, std: 1e-3, mode: absolute}", 5,
     "write it in the mission as a vector"),
], ids=["did-you-mean", "component of a one-number field"])
def test_a_path_that_does_not_lead_to_a_number_names_file_line_and_the_fix(tmp_path, mission, dispersion, line, words):
    f = tmp_path / "c.yaml"
    f.write_text(f"extends: {mission}\ncampaign:\n  runs: 2\n  dispersions:\n    - {dispersion}\n")
    with pytest.raises(InputError) as e:
        define(load_mission(f))
    text = e.value.render()
    assert f"{f}:{line}" in text and words in text


def test_a_mission_without_a_campaign_section_is_refused():
    with pytest.raises(InputError, match="no campaign: section"):
        define(load_mission(ROOT / "missions" / "basilisk_rw_reference.yaml"))


def test_one_draw_written_to_several_paths_scales_them_together():
    """Ruggiero 2020's body-mass sweep scales a body's mass and inertia together: one parameter, two paths."""
    mission = ROOT / "missions" / "basilisk_rw_reference.yaml"
    text = f"extends: {mission}\ncampaign:\n  runs: 3\n  entropy: 4\n  dispersions:\n" \
           "    - {name: body, path: [robot.links.hub.mass, robot.links.hub.inertia], distribution: uniform,\n" \
           "       low: 0, high: 200 %}\n"
    c = define(load_mission_text(text, base_dir=mission.parent, name="b.yaml"))
    for task in c.tasks([0, 1, 2]):
        loaded, sm = _build(task)
        mass, _, inertia = sm.link_inertial("hub")
        m0, i0 = c.parameters[0].nominals
        factor = mass / m0
        np.testing.assert_allclose(np.asarray(inertia)[np.asarray(i0) != 0] / np.asarray(i0)[np.asarray(i0) != 0],
                                   factor, rtol=1e-14)
        assert factor == pytest.approx(1 + draws(c.spec, c.entropy, [task.run])[task.run]["body"], rel=1e-14)
        assert read_back(loaded, sm, task) == {k: v for k, (_, v) in task.samples.items()}


def test_variants_run_on_the_same_draws_and_a_paired_requirement_judges_their_difference(tmp_path):
    """Two variants (phase durations 300 s and 500 s through their overlays) on the same samples: the
    metrics of each are keyed by its name, the parameters are the same draw, and a ``minus``
    requirement sees the run-by-run difference (200 s in every run)."""
    import pyarrow as pa

    from sms_cli.campaign.requirements import CampaignRequirementSpec, evaluate
    from sms_cli.campaign.runner import execute_run
    from sms_cli.campaign.store import outcomes_table

    f = tmp_path / "v.yaml"
    f.write_text(f"extends: {SMALL}\ncampaign:\n  runs: 6\n  dispersions:\n"
                 "    - {name: K, path: simulation.attitude.K, distribution: uniform, low: -20 %, high: 20 %}\n"
                 "  variants:\n"
                 "    short: {simulation: {phases: [{name: detumble, kind: hold, duration: 300 s, "
                 "base_mode: rotation-free-floating, attitude: [0, 0, 0]}]}}\n"
                 "    long: {simulation: {phases: [{name: detumble, kind: hold, duration: 500 s, "
                 "base_mode: rotation-free-floating, attitude: [0, 0, 0]}]}}\n")
    c = define(load_mission(f))
    outcomes = [execute_run(t) for t in c.tasks(list(range(6)))]
    for o, t in zip(outcomes, c.tasks(list(range(6)))):
        assert o.status == "ok"
        assert o.metrics["short.simulate.t_end_s"] == pytest.approx(300.0)
        assert o.metrics["long.simulate.t_end_s"] == pytest.approx(500.0)
        assert o.params["K"] == t.samples["K"][1]
        assert any(k.startswith("long: ") for k in o.requirements)
    table = outcomes_table(outcomes, c.meta())
    assert isinstance(table, pa.Table)
    spec = CampaignRequirementSpec(name="long − short is 200 s", metric="long.simulate.t_end_s",
                                   minus="short.simulate.t_end_s", min="199 s", max="201 s", pass_rate_min=0.5)
    v = evaluate(spec, table)
    assert v.status == "pass" and "6/6" in v.message


def test_a_variant_that_does_not_load_is_refused_at_its_line(tmp_path):
    f = tmp_path / "v.yaml"
    f.write_text(f"extends: {SMALL}\ncampaign:\n  runs: 2\n  dispersions:\n"
                 "    - {name: K, path: simulation.attitude.K, distribution: uniform, low: -20 %, high: 20 %}\n"
                 "  variants:\n    bad: {simulation: {attitude: {law: mrp_feedback, K: -1, P: 30, Kx: 3}}}\n")
    with pytest.raises(InputError) as e:
        define(load_mission(f))
    assert f"{f}:7" in e.value.render() and "variant 'bad'" in e.value.render()
