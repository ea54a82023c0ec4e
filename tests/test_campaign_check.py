"""``sms check`` and ``sms report`` on a campaign's results folder, through the CLI."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
from conftest import run_cli
from test_campaign_stats import SETTLE, mass_campaign, write_campaign

PASSING = [{"name": "settles in 160 s", "metric": SETTLE, "max": "160 s", "pass_rate_min": 0.9},
           {"name": "heavier settles sooner", "metric": SETTLE, "correlation_with": "body_mass", "rho_max": 0}]
FAILING = PASSING + [{"name": "settles in 150 s", "metric": SETTLE, "max": "150 s", "pass_rate_min": 0.99}]


def _junit(path):
    suite = ET.parse(path).getroot().find("testsuite")
    return int(suite.get("tests")), int(suite.get("failures")) + int(suite.get("errors"))


def test_check_passes_with_met_campaign_requirements_and_writes_junit(tmp_path):
    folder = mass_campaign(tmp_path / "c", requirements=PASSING)
    r = run_cli("check", folder, "--junit", tmp_path / "j.xml")
    assert r.exit_code == 0, r.output
    assert "2/2 requirements met" in r.output and "heavier settles sooner" in r.output
    assert _junit(tmp_path / "j.xml") == (2, 0)


def test_check_fails_on_a_campaign_requirement_not_met(tmp_path):
    folder = mass_campaign(tmp_path / "c", requirements=FAILING)
    r = run_cli("check", folder, "--junit", tmp_path / "j.xml", "--json")
    assert r.exit_code == 1, r.output
    out = json.loads(r.stdout)
    assert [v["status"] for v in out["verdicts"]] == ["pass", "pass", "fail"]
    assert "Wilson" in out["verdicts"][2]["message"]
    assert _junit(tmp_path / "j.xml") == (3, 1)


def test_check_of_a_campaign_results_json_path_is_the_campaign_check(tmp_path):
    folder = mass_campaign(tmp_path / "c", requirements=FAILING)
    (folder / "results.json").write_text(json.dumps({"campaign": {"runs": {}}}), encoding="utf-8")
    assert run_cli("check", folder / "results.json").exit_code == 1


def test_check_with_nothing_to_check_exits_2_and_still_writes_junit(tmp_path):
    folder = mass_campaign(tmp_path / "c", requirements=[])
    r = run_cli("check", folder, "--junit", tmp_path / "j.xml")
    assert r.exit_code == 2, r.output
    assert "nothing to check" in r.output
    assert _junit(tmp_path / "j.xml") == (1, 1)


def test_check_refuses_single_run_options_and_a_missing_campaign_json(tmp_path):
    folder = mass_campaign(tmp_path / "c", requirements=PASSING)
    r = run_cli("check", folder, "--baseline", tmp_path / "b.json")
    assert r.exit_code == 2 and "--baseline" in r.output
    (folder / "results.json").write_text(json.dumps({"campaign": {"runs": {}}}), encoding="utf-8")
    (folder / "campaign.json").unlink()
    r = run_cli("check", folder)
    assert r.exit_code == 2 and "campaign.json is missing" in r.output


def test_check_fails_a_campaign_with_runs_not_finished(tmp_path):
    n = 50
    folder = write_campaign(tmp_path / "c", {"run": list(range(n)), "status": ["ok"] * n,
                                             "param.body_mass": np.linspace(90, 110, n),
                                             f"metric.{SETTLE}": np.full(n, 100.0)},
                            requirements=PASSING[:1], runs=80)
    r = run_cli("check", folder)
    assert r.exit_code == 1, r.output
    assert "1/1 requirements met" in r.output and "50 of 80 runs" in r.output and "--resume" in r.output


def test_report_of_a_campaign_folder_has_the_campaign_section(tmp_path):
    folder = mass_campaign(tmp_path / "c", requirements=FAILING)
    r = run_cli("report", folder)
    assert r.exit_code == 0, r.output
    html = (folder / "report.html").read_text(encoding="utf-8")
    assert 'id="campaign"' in html and "Campaign: dispersions over the runs" in html
    assert "Strongest sensitivities" in html and "Metrics over the runs that ran" in html
    assert html.count("<img ") >= 4  # histograms of the settling time and attitude error, scatters
    assert "2 of 3 requirements" not in html and "1 of 3 requirements not met" in html  # the banner
    assert "settles in 150 s" in html and 'id="requirements"' in html
