"""Damaged results.json and baselines through the CLI (issue 17 item 8): ``sms check`` and
``sms report`` exit 2 naming the file, the line where there is one, what is wrong and a fix;
``sms report`` still renders the sections it can and names the unreadable ones in the report.
One results folder (hipparcos_leo, budget only) is made per module; each test damages a copy."""

from __future__ import annotations

import json
import random
import re
import shutil
from pathlib import Path

import pytest

from conftest import EXCEPTION_TEXT, MISSIONS, assert_clean, run_cli

EXC_NAME = EXCEPTION_TEXT


@pytest.fixture(scope="module")
def leo(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("leo") / "leo"
    r = run_cli("run", MISSIONS / "hipparcos_leo.yaml", "-o", out, "--no-progress", "--no-report")
    assert r.exit_code == 0, r.output
    r = run_cli("check", out, "--write-baseline", out.parent / "baseline.json")
    assert r.exit_code == 0, r.output
    return out


@pytest.fixture
def results(tmp_path, leo) -> Path:
    """A fresh copy of the results folder."""
    dst = tmp_path / "leo"
    shutil.copytree(leo, dst)
    return dst


def _edit(folder: Path, change) -> Path:
    f = folder / "results.json"
    data = json.loads(f.read_text())
    change(data)
    f.write_text(json.dumps(data, indent=2))
    return f


def _no_stray(folder: Path) -> None:
    assert not [p for p in folder.rglob(".*.part")]


# ---------------------------------------------------------------- results.json that is not results

RAW = {
    "a list": (b'[1, 2, 3]\n', "is a list", ""),
    "random bytes": (random.Random(17).randbytes(400), "damaged", ":1:"),
    "not UTF-8": (b'{\n  "run": {"mission": "caf\xe9"}\n}\n', "not UTF-8", ":2:26"),
    "a syntax error": (b'{\n  "run": {},\n  "budget": oops\n}\n', "not JSON", ":3:13"),
    "nested too deeply": (b"[" * 200_000, "nested too deeply", ""),
    "empty": (b"", "not JSON", ":1:1"),
}


@pytest.mark.parametrize("case", RAW)
@pytest.mark.parametrize("cmd", ["check", "report"])
def test_results_file_that_is_not_results(results, case, cmd):
    raw, what, line = RAW[case]
    f = results / "results.json"
    f.write_bytes(raw)
    r = run_cli(cmd, results)
    assert_clean(r, 2, f"{f}{line}", what, "fix:", "sms run")
    assert f.read_bytes() == raw and not (results / "report.html").exists()
    _no_stray(results)


@pytest.mark.parametrize("value,kind", [(None, "null"), ([1, 2], "a list"), ("text", "text"), (3, "a number")])
def test_check_refuses_a_damaged_section_with_its_line(results, value, kind):
    f = _edit(results, lambda d: d.__setitem__("budget", value))
    line = next(i for i, t in enumerate(f.read_text().splitlines(), 1) if t.startswith('  "budget"'))
    r = run_cli("check", results, "--baseline", results.parent.parent / "baseline.json")
    assert_clean(r, 2, f"{f}:{line}", f"section 'budget' is {kind}, not a mapping", "fix:")


def test_check_refuses_stored_requirements_that_are_not_a_list(results):
    f = _edit(results, lambda d: d["requirements"].__setitem__("specs", {"a": 1}))
    r = run_cli("check", results)
    assert_clean(r, 2, f, "requirements.specs is a mapping", "--mission")


def test_write_baseline_from_damaged_results_is_refused(results, tmp_path):
    _edit(results, lambda d: d.__setitem__("run", None))
    b = tmp_path / "b.json"
    r = run_cli("check", results, "--write-baseline", b)
    assert_clean(r, 2, "section 'run' is null")
    assert not b.exists()


# ---------------------------------------------------------------- sms report renders what it can


def test_report_renders_the_readable_sections_and_names_the_others(results):
    def damage(d):
        d["simulate"] = None
        d["analysis"] = [1, 2]
        d["budget"]["scenarios"][0].pop("steps")
        d["run"]["stages"] = [{"name": "budget"}, "junk"]
        d["requirements"]["verdicts"].append({"status": 7})

    f = _edit(results, damage)
    r = run_cli("report", results)
    assert_clean(r, 2, f, "section 'simulate' is null", "section 'analysis' is a list",
                 "section 'budget' is incomplete (it has no 'steps')", "fix:")
    html = (results / "report.html").read_text()
    assert "Results that could not be read" in html and "section &#39;simulate&#39; is null" in html
    assert "Requirement verdicts" in html and "4/4 requirements met" in html  # the readable parts are there
    assert "unreadable" in html.split('id="verdict"')[1][:200]
    _no_stray(results)


def test_report_notes_a_damaged_recording(results):
    """A recording that cannot be read costs its plots, with a note, not the report."""
    _edit(results, lambda d: d.__setitem__("simulate", {"status": "ok", "files": {"mcap": "simulation.mcap"}}))
    (results / "simulation.mcap").write_bytes(random.Random(3).randbytes(2000))
    r = run_cli("report", results)
    assert_clean(r, 0)
    html = (results / "report.html").read_text()
    assert "Nonlinear simulation" in html and "could not be read (damaged or truncated)" in html
    assert not EXC_NAME.search(html.split("<body>")[1])


def test_report_notes_damaged_artifacts_and_a_mission_that_no_longer_loads(results, tmp_path):
    """A damaged CSV or gains.yaml, or a stored mission path that no longer loads, costs a table
    or a plot with a note; the report is still written (exit 0: results.json itself is intact)."""
    broken = tmp_path / "gone.yaml"
    broken.write_text("name: [unclosed\n")
    wheel = {"name": "rw1", "spin_inertia_kgm2": 0.1, "axis_base": [1, 0, 0], "max_speed_rad_s": 600.0,
             "max_torque_Nm": 0.2}

    def damage(d):
        d["compile"] = {"name": "leo", "mission_file": str(broken), "wheels": [wheel]}
        d["simulate"] = {"status": "ok", "files": {"csv": "simulation.csv"}}
        d["synthesis"] = {"law": "pd"}

    _edit(results, damage)
    (results / "simulation.csv").write_text("t_s,wheel_speed_rw1\nabc,def\n")
    (results / "gains.yaml").write_text("- 1\n- 2\n")
    r = run_cli("report", results)
    assert_clean(r, 0)
    html = (results / "report.html").read_text()
    assert "the robot drawing is left out: " + str(broken) in html
    assert "the wheel-momentum plot is left out" in html and "gains.yaml could not be read" in html
    assert not EXC_NAME.search(html.split("<body>")[1])


def test_pdf_that_times_out_is_an_error_not_a_crash(results, monkeypatch):
    import subprocess

    def slow(cmd, **kw):
        raise subprocess.TimeoutExpired(cmd, kw.get("timeout"))

    monkeypatch.setattr("sms_cli.report.pdf.find_browser", lambda: "/usr/bin/chromium")
    monkeypatch.setattr("sms_cli.report.pdf.subprocess.run", slow)
    r = run_cli("report", results, "--pdf")
    assert_clean(r, 2, results / "report.html", "did not finish printing", "fix:")
    assert not (results / "report.pdf").exists() and not list(results.glob(".*.part"))


def test_report_of_intact_results_has_no_unreadable_part(results):
    r = run_cli("report", results)
    assert_clean(r, 0)
    assert "could not be read" not in (results / "report.html").read_text()


def test_report_of_a_file_says_to_pass_the_folder(results):
    r = run_cli("report", results / "results.json")
    assert_clean(r, 2, results / "results.json", "is a file", f"sms report {results}")


# ---------------------------------------------------------------- baselines


@pytest.fixture
def baseline(tmp_path, leo) -> Path:
    b = tmp_path / "b.json"
    shutil.copy(leo.parent / "baseline.json", b)
    return b


def _metric_line(b: Path, name: str) -> int:
    return next(i for i, t in enumerate(b.read_text().splitlines(), 1) if t.strip().startswith(json.dumps(name)))


BAD_METRICS = {
    "text value": ({"value": "abc", "rel_tol": 0, "abs_tol": 0}, "value is text ('abc'), not a finite number"),
    "null value": ({"value": None}, "value is null"),
    "no value": ({"rel_tol": 0}, 'has no "value"'),
    "a number, not a mapping": (3.5, "is a number, not"),
    "negative tolerance": ({"value": 1.0, "rel_tol": -1}, "rel_tol is -1: a tolerance is a number >= 0"),
    "text tolerance": ({"value": 1.0, "abs_tol": "1e-3"}, "abs_tol is '1e-3'"),
}


@pytest.mark.parametrize("case", BAD_METRICS)
def test_baseline_with_a_bad_metric(results, baseline, case):
    entry, what = BAD_METRICS[case]
    data = json.loads(baseline.read_text())
    name = next(iter(data["metrics"]))
    data["metrics"][name] = entry
    baseline.write_text(json.dumps(data, indent=2))
    r = run_cli("check", results, "--baseline", baseline)
    assert_clean(r, 2, f"{baseline}:{_metric_line(baseline, name)}", f"metrics.{name}", what, "--write-baseline")


def test_baseline_with_a_nan_value(results, baseline):
    text = baseline.read_text()
    baseline.write_text(re.sub(r'"value": [-0-9.e+]+', '"value": NaN', text, count=1))
    r = run_cli("check", results, "--baseline", baseline)
    assert_clean(r, 2, baseline, "not a finite number")


BAD_BASELINES = {
    "not JSON": (b'{\n  "format": "sms-baseline/1",\n  "metrics": {,}\n}\n', "not JSON", ":3:15"),
    "not UTF-8": (b'{"format": "\xff"}', "not UTF-8", ":1:13"),
    "a list": (b"[]", "not an sms baseline: it is a list", ":1"),
    "another format": (b'{"format": "x", "metrics": {}}', "has \"format\": 'x'", ":1"),
    "no metrics": (b'{"format": "sms-baseline/1", "metrics": []}', 'has no "metrics" mapping', ":1"),
}


@pytest.mark.parametrize("case", BAD_BASELINES)
def test_baseline_that_is_not_a_baseline(results, baseline, case):
    raw, what, line = BAD_BASELINES[case]
    baseline.write_bytes(raw)
    r = run_cli("check", results, "--baseline", baseline)
    assert_clean(r, 2, f"{baseline}{line}", what, "fix:", "--write-baseline")


def test_intact_baseline_still_passes(results, baseline, tmp_path):
    junit = tmp_path / "j.xml"
    r = run_cli("check", results, "--baseline", baseline, "--junit", junit)
    assert_clean(r, 0, "metrics within tolerance")
    assert junit.is_file()
