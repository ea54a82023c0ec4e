"""CLI conventions (issue #15 item 5), through the CLI: ``--json`` of ``run`` and ``check``; help
with an example per command and metavars that do not read as a set of choices; ``compile -o``
writes; shell completion; a JUnit report also when the check cannot run, valid XML whatever the
names hold; no recording left by a simulation that stops on an input error; the progress bar
ends at 100 %; the requirement table fits the terminal."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conftest import EXCEPTION_TEXT, MISSIONS, ROOT, run_cli

SMS = str(Path(sys.executable).with_name("sms"))
GEO = MISSIONS / "hipparcos_geo.yaml"
BASELINE = ROOT / "baselines" / "hipparcos_geo.json"

RUN_KEYS = {"mission", "results", "stages", "verdicts", "report", "exit_code", "passed", "verdict"}
CHECK_KEYS = {"mission", "results", "passed", "exit_code", "verdicts", "drifts", "notes", "incomplete"}
STAGE_KEYS = {"name", "status", "seconds", "exit_code", "message"}
VERDICT_KEYS = {"name", "metric", "stage", "status", "value", "bound", "unit", "message", "margin"}
DRIFT_KEYS = {"metric", "status", "value", "expected", "allowed", "message"}


def _commands() -> list[str]:
    from sms_cli.cli import app

    return [c.name for c in app.registered_commands]


@pytest.fixture(scope="module")
def geo(tmp_path_factory) -> tuple[Path, dict]:
    """hipparcos_geo run into a folder with --json: (folder, the printed summary)."""
    out = tmp_path_factory.mktemp("conv") / "hipparcos_geo"
    r = run_cli("run", GEO, "-o", out, "--no-progress", "--no-report", "--json")
    assert r.exit_code == 0, r.output
    return out, json.loads(r.stdout)


# ------------------------------------------------------------------ --json
def test_run_json_is_the_run_summary(geo):
    out, data = geo
    assert set(data) == RUN_KEYS
    assert data["mission"] == "hipparcos_geo" and Path(data["results"]) == out
    assert data["exit_code"] == 0 and data["passed"] is True and data["verdict"] == "pass" and data["report"] is None
    stages = {s["name"]: s for s in data["stages"]}
    assert all(set(s) == STAGE_KEYS for s in data["stages"])
    assert stages["budget"]["status"] == "ok" and stages["simulate"]["status"] == "not configured"
    assert len(data["verdicts"]) == 4 and all(set(v) == VERDICT_KEYS for v in data["verdicts"])
    assert all(v["status"] == "pass" for v in data["verdicts"])


def test_check_json_is_the_outcome(geo, tmp_path):
    out, _ = geo
    r = run_cli("check", out, "--baseline", BASELINE, "--json")
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    assert set(data) == CHECK_KEYS
    assert data["passed"] is True and data["exit_code"] == 0 and data["incomplete"] is None
    assert len(data["verdicts"]) == 4 and all(set(v) == VERDICT_KEYS for v in data["verdicts"])
    assert len(data["drifts"]) > 100 and all(set(d) == DRIFT_KEYS for d in data["drifts"])
    # a failing requirement: exit 1, and the JSON says which
    m = tmp_path / "tight.yaml"
    m.write_text(f"extends: {GEO}\nname: hipparcos_geo\nrequirements:\n"
                 "  - {name: wet mass cap, metric: budget.mass.required_wet_mass_kg, max: 950 kg}\n")
    r = run_cli("check", out, "-m", m, "--json", "--write-baseline", tmp_path / "b.json")
    assert r.exit_code == 1, r.output
    data = json.loads(r.stdout)
    assert data["passed"] is False and data["exit_code"] == 1 and data["drifts"] is None
    assert [v["status"] for v in data["verdicts"]] == ["fail"] and "violates" in data["verdicts"][0]["message"]
    assert len(data["notes"]) == 1 and "wrote baseline" in data["notes"][0]


# ------------------------------------------------------------------ help
@pytest.mark.parametrize("cmd", _commands())
def test_help_has_no_metavar_that_reads_as_choices(cmd):
    r = run_cli(cmd, "--help")
    assert r.exit_code == 0
    assert not re.search(r"\{[^}]*\}", r.stdout), r.stdout
    assert "<path>]" not in r.stdout and not re.search(r"-[-\w]+ <path>", r.stdout), r.stdout  # options name their kind


def _examples(cmd: str) -> list[list[str]]:
    text = run_cli(cmd, "--help").stdout
    assert "Example" in text, f"sms {cmd} --help shows no example"
    block = text.split("Example", 1)[1].split("\nArguments:", 1)[0].split("\nOptions:", 1)[0]
    return [line.split() for line in block.splitlines() if line.strip().startswith("sms ")]


@pytest.mark.parametrize("cmd", _commands())
def test_help_shows_a_real_example(cmd):
    examples = _examples(cmd)
    assert examples, f"sms {cmd} --help: no example line"
    for words in examples:
        assert words[1] == cmd, words
        for w in words[2:]:
            if w.startswith(("missions/", "baselines/", "robots/")):
                assert (ROOT / w).exists(), f"the example names {w}, which is not shipped"
        # the options parse (an unknown option is exit 2 before --help answers)
        r = run_cli(*[str(ROOT / w) if w.startswith("missions/") else w for w in words[1:]], "--help")
        assert r.exit_code == 0, (words, r.output)


def test_completion_is_installed_and_answers():
    r = run_cli("--help")
    assert "--install-completion" in r.stdout and "--show-completion" in r.stdout
    script = subprocess.run([SMS, "--show-completion", "bash"], capture_output=True, text=True, timeout=60)
    assert script.returncode == 0 and "_SMS_COMPLETE" in script.stdout
    env = {**os.environ, "_SMS_COMPLETE": "complete_bash", "COMP_WORDS": "sms che", "COMP_CWORD": "1"}
    done = subprocess.run([SMS], capture_output=True, text=True, env=env, timeout=60)
    assert done.stdout.split() == ["check"]
    env.update(COMP_WORDS="sms check --ju", COMP_CWORD="2")
    done = subprocess.run([SMS], capture_output=True, text=True, env=env, timeout=60)
    assert done.stdout.split() == ["--junit"]


# ------------------------------------------------------------------ -o
def test_compile_out_writes_the_summary(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    mission = MISSIONS / "caldera_smallsat.yaml"
    r = run_cli("compile", mission, "-o", tmp_path / "a")
    assert r.exit_code == 0, r.output
    assert "compile" in json.loads((tmp_path / "a" / "results.json").read_text())
    r = run_cli("compile", mission, "-o", tmp_path / "b", "--no-write")
    assert r.exit_code == 0 and not (tmp_path / "b").exists()
    r = run_cli("compile", mission)  # no -o, no --write: nothing written
    assert r.exit_code == 0 and list(tmp_path.iterdir()) == [tmp_path / "a"]
    r = run_cli("compile", mission, "--write")
    assert r.exit_code == 0 and (tmp_path / "results" / "caldera_smallsat" / "results.json").exists()


def test_simulate_recording_option_and_old_spelling(tmp_path):
    r = run_cli("simulate", MISSIONS / "astrobee_arm.yaml", "-o", tmp_path / "x.mcap", "--recording", tmp_path / "y.mcap")
    assert r.exit_code == 2 and "give the recording once" in r.stderr
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------ JUnit
def _junit_error(path: Path) -> ET.Element:
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites" and root.get("tests") == "1" and root.get("failures") == "1"
    (case,) = root.findall(".//testcase")
    (fail,) = case.findall("failure")
    assert fail.get("type") == "input error"
    return fail


@pytest.mark.parametrize("damage", ["results", "baseline", "mission", "no results"])
def test_check_that_cannot_run_writes_a_failing_junit(geo, tmp_path, damage):
    out, _ = geo
    args: list = []
    if damage == "results":
        out = tmp_path / "r"
        out.mkdir()
        (out / "results.json").write_text('{"budget": {"totals": ')
    elif damage == "baseline":
        (tmp_path / "b.json").write_text('{"format": "sms-baseline/1", "metrics": [')
        args = ["--baseline", tmp_path / "b.json"]
    elif damage == "mission":
        (tmp_path / "m.yaml").write_text("name: x\nrequirements: [{name: a, metrik: budget.x, max: 1}]\n")
        args = ["--mission", tmp_path / "m.yaml"]
    else:
        out = tmp_path / "none"
    junit = tmp_path / "j.xml"
    r = run_cli("check", out, *args, "--junit", junit)
    assert r.exit_code == 2, r.output
    assert not EXCEPTION_TEXT.search(r.stderr), r.stderr
    fail = _junit_error(junit)
    first = r.stderr.removeprefix("error: ").splitlines()[0]
    assert first in fail.get("message") and first in fail.text
    assert [p.name for p in tmp_path.iterdir() if ".part" in p.name or p.name.startswith(".")] == []


def test_junit_is_valid_xml_with_control_characters(geo, tmp_path):
    out, _ = geo
    m = tmp_path / "ctl.yaml"
    m.write_text(f"extends: {GEO}\nname: hipparcos_geo\nrequirements:\n"
                 '  - {name: "bell\\a and escape\\e", metric: budget.mass.required_wet_mass_kg, max: 950 kg}\n'
                 '  - {name: "nul\\0 metric", metric: "budget.mass.no\\x07such", max: 1}\n'
                 '  - {name: "tab\\t ok", metric: budget.mass.final_mass_kg, min: 700 kg}\n')
    junit = tmp_path / "j.xml"
    r = run_cli("check", out, "-m", m, "--junit", junit)
    assert r.exit_code == 1, r.output
    root = ET.parse(junit).getroot()  # raises on an invalid character
    names = [c.get("name") for c in root.iter("testcase")]
    assert names == ["bell\\x07 and escape\\x1b", "nul\\x00 metric", "tab\t ok"]
    messages = [f.get("message") for f in root.iter("failure")]
    assert len(messages) == 2 and "budget.mass.no\\x07such" in messages[1]  # the missing metric's message
    # and a check that cannot run, with a control character in its message
    bad = tmp_path / "bad\x01.json"
    bad.write_text("[")
    r = run_cli("check", out, "--baseline", bad, "--junit", junit)
    assert r.exit_code == 2
    assert "bad\\x01.json" in _junit_error(junit).get("message")


# ------------------------------------------------------------------ simulate
def test_simulate_unknown_joint_leaves_no_recording(tmp_path):
    m = tmp_path / "m.yaml"
    m.write_text(f"extends: {MISSIONS / 'caldera_s2_arm.yaml'}\nname: caldera_s2_arm\nsimulation:\n  phases:\n"
                 "    - {name: move, kind: deploy, duration: 5 s, waypoints: [{at: 1 s, joints: {joint_9: 0.1}}]}\n")
    r = run_cli("simulate", m, "-o", tmp_path / "out")
    assert r.exit_code == 2 and "joint_9" in r.stderr, r.output
    assert not (tmp_path / "out" / "simulation.mcap").exists()


def test_simulate_without_gains_leaves_no_recording(tmp_path):
    out = tmp_path / "out"
    r = run_cli("simulate", MISSIONS / "caldera_s1_synthesized.yaml", "-o", out)
    assert r.exit_code == 2 and "gains.yaml" in r.stderr, r.output
    assert not (out / "simulation.mcap").exists()


def test_progress_ends_at_100_percent(tmp_path):
    r = run_cli("simulate", MISSIONS / "astrobee_arm.yaml", "--progress", "--recording", tmp_path / "run.mcap",
                "-o", tmp_path / "out")
    assert r.exit_code in (0, 1), r.output
    last = [x for x in r.stderr.replace("\r", "\n").splitlines() if "simulating" in x][-1]
    assert last.split()[-1] == "100%" and "40.00 / 40.00 s" in last, last
    assert (tmp_path / "run.mcap").exists() and not (tmp_path / "out" / "simulation.mcap").exists()


def test_progress_counts_round_off_and_early_completion(monkeypatch, capsys):
    from sms_cli.sim.engine import Progress

    p = Progress(1.0, enabled=True)
    t = 0.0
    for _ in range(10):
        t += 0.1  # 0.9999999999999999
        p.update(t)
    p.close()
    assert capsys.readouterr().err.replace("\r", "\n").splitlines()[-1].endswith("100%")
    p = Progress(120.0, enabled=True)
    p.update(80.0)
    p.finish(80.0)  # the last phase settled early: the run is complete
    p.close()
    assert capsys.readouterr().err.replace("\r", "\n").splitlines()[-1].endswith("100%")
    p = Progress(10.0, enabled=True)
    p.update(3.0)
    p.update(3.05)  # same percentage: not drawn, but the line closes on the time reached (a diverged run)
    p.close()
    last = capsys.readouterr().err.replace("\r", "\n").splitlines()[-1]
    assert "3.05 / 10.00 s" in last and last.endswith(" 30%")


# ------------------------------------------------------------------ table width
def _numbers_whole(text: str, verdicts: list[dict]) -> None:
    for v in verdicts:
        for piece in (v["bound"].split() + [f"{v['value']:.6g}" if isinstance(v["value"], float) else ""]):
            assert piece in text, f"{piece!r} is cut in:\n{text}"


@pytest.mark.parametrize("width", [60, 80, 100])  # 60: the value and bound columns wrap too
def test_requirement_table_fits_the_width(geo, width, monkeypatch):
    out, data = geo
    monkeypatch.setenv("COLUMNS", str(width))
    r = run_cli("check", out)
    assert r.exit_code == 0
    lines = r.stdout.splitlines()
    assert max(map(len, lines)) <= width, r.stdout
    _numbers_whole(r.stdout, data["verdicts"])
    column = {line.index(" status") + 1 for line in lines if line.endswith(" status")}
    column |= {line.rindex(" PASS") + 1 for line in lines if line.endswith(" PASS")}
    assert len(column) == 1, r.stdout  # the columns stay aligned
    for v in data["verdicts"]:
        assert v["name"] in r.stdout
    # a failing requirement's message wraps too
    m = out.parent / f"tight{width}.yaml"
    m.write_text(f"extends: {GEO}\nname: hipparcos_geo\nrequirements:\n"
                 "  - {name: a wet mass cap that the chaser cannot meet with its reserve, "
                 "metric: budget.mass.required_wet_mass_kg, max: 950 kg}\n")
    r = run_cli("check", out, "-m", m)
    assert r.exit_code == 1 and "980.921" in r.stdout
    assert max(map(len, r.stdout.splitlines())) <= width, r.stdout


def test_requirement_table_wide_layout_when_it_fits(geo, monkeypatch):
    out, _ = geo
    monkeypatch.setenv("COLUMNS", "200")
    lines = run_cli("check", out).stdout.splitlines()
    assert lines[0].split() == ["requirement", "metric", "value", "bound", "status"]
    assert 100 < max(map(len, lines)) <= 200


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
@pytest.mark.parametrize("width", [80, None])
def test_requirement_table_in_a_terminal_and_in_a_pipe(geo, width):
    """In a terminal of 80 columns (no COLUMNS) the table fits it; in a pipe it fits 100."""
    import fcntl
    import struct
    import termios

    out, _ = geo
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    if width is None:
        text = subprocess.run([SMS, "check", out], capture_output=True, text=True, env=env, timeout=120).stdout
        limit = 100
    else:
        leader, follower = os.openpty()
        fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, width, 0, 0))
        p = subprocess.run([SMS, "check", out], stdin=follower, stdout=follower, stderr=subprocess.PIPE, env=env,
                           timeout=120)
        os.close(follower)
        chunks = []
        while True:
            try:
                chunk = os.read(leader, 65536)
            except OSError:
                break
            if not chunk:
                break
            chunks.append(chunk)
        os.close(leader)
        assert p.returncode == 0, p.stderr
        text = b"".join(chunks).decode().replace("\r\n", "\n")
        limit = width
    lines = text.splitlines()
    assert "PASS: hipparcos_geo" in lines
    assert max(map(len, lines)) <= limit and max(map(len, lines)) > limit - 25, text


def test_run_table_fits_80_columns(tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    r = run_cli("run", GEO, "-o", tmp_path / "g", "--no-progress", "--no-report")
    assert r.exit_code == 0, r.output
    table = r.stdout.split("\n\n", 1)[1]  # after the stage table
    assert "requirements met" in table and max(map(len, table.splitlines())) <= 80, table


def test_help_still_answers_without_heavy_imports():
    code = ("import sys; from sms_cli.cli import app; from typer.testing import CliRunner; "
            "CliRunner().invoke(app, ['--help']); CliRunner().invoke(app, ['check', '--help']); "
            "print(sorted(m for m in ('numpy', 'scipy', 'pinocchio', 'matplotlib', 'cvxpy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    assert out.strip() == "[]"


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_completion_script_loads_in_bash():
    script = subprocess.run([SMS, "--show-completion", "bash"], capture_output=True, text=True, timeout=60).stdout
    r = subprocess.run(["bash", "-c", script + "\ncomplete -p sms"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "_sms_completion" in r.stdout, r.stderr


def test_simulate_compiled_engine_refusal_leaves_no_recording(tmp_path):
    m = tmp_path / "m.yaml"
    m.write_text(f"extends: {MISSIONS / 'chevallard_deploy_track.yaml'}\nname: chevallard_deploy_track\n"
                 "appendages: [{name: panel, link: base_link, modes: [{frequency: 0.5 Hz, damping: 0.005, "
                 "participation: [0, 0, 0, 0, 0, 2.0]}]}]\n"
                 "simulation: {engine: compiled}\n")  # flexible modes without NDI: refused
    out = tmp_path / "out"
    r = run_cli("simulate", m, "-o", out)
    assert r.exit_code == 2 and "the compiled engine cannot run this mission" in r.stderr, r.output
    assert not (out / "simulation.mcap").exists()
