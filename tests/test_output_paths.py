"""Output paths through the CLI (issue 17 items 7 and 9): every path a command writes is checked
before any work starts, a file-system failure that still happens is exit 2 (3 for a full disk)
with the path, the reason and a fix, and no exception name, traceback or source path reaches
the user. Tests run as root, where chmod does not stop writes: a read-only folder is /sys (root
may not create files there) or a monkeypatched probe; "a folder that cannot be created" is a
path under a regular file; a full disk is a monkeypatched writer raising ENOSPC."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

import pytest

from conftest import EXCEPTION_TEXT, MISSIONS, assert_clean, run_cli

LEO = MISSIONS / "hipparcos_leo.yaml"
EXC_NAME = EXCEPTION_TEXT


def stray(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*") if p.name.endswith(".part") or p.name.startswith(".sms-probe-")]


@pytest.fixture(scope="module")
def leo_results(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("leo") / "leo"
    r = run_cli("run", LEO, "-o", out, "--no-progress", "--no-report")
    assert r.exit_code == 0, r.output
    return out


#: The output check comes before any work: with a mission that does not exist, the error must
#: still be the one about the output path (loading the mission would fail with another).
NO_MISSION = Path("/nonexistent-sms/mission.yaml")


MISSION_COMMANDS = ["budget", "analyze", "synthesize", "simulate", "run", "compile"]


def _mission_cmd(cmd: str, out: Path) -> list:
    return [cmd, NO_MISSION, "-o", out] + (["--write"] if cmd == "compile" else [])


@pytest.mark.parametrize("cmd", MISSION_COMMANDS)
def test_results_folder_that_is_a_file(tmp_path, cmd):
    f = tmp_path / "afile"
    f.write_text("keep me\n")
    r = run_cli(*_mission_cmd(cmd, f))
    assert_clean(r, 2, f, "is a file", "fix:")
    assert f.read_text() == "keep me\n" and not stray(tmp_path)


@pytest.mark.parametrize("cmd", MISSION_COMMANDS)
def test_results_folder_under_a_file(tmp_path, cmd):
    """A folder that cannot be created: its parent is a regular file."""
    f = tmp_path / "afile"
    f.write_text("x")
    r = run_cli(*_mission_cmd(cmd, f / "out"))
    assert_clean(r, 2, f / "out", f"{f} is a file, not a folder", "fix:")
    assert not stray(tmp_path)


@pytest.mark.skipif(not Path("/sys/kernel").is_dir(), reason="needs sysfs")
def test_results_folder_in_a_folder_root_cannot_write():
    """/sys refuses new files even to root: the honest read-only folder of a root test run."""
    assert not os.path.exists("/sys/sms-out")
    r = run_cli("budget", NO_MISSION, "-o", "/sys/sms-out")
    assert_clean(r, 2, "/sys/sms-out", "you may not write in /sys", "fix:")


@pytest.mark.skipif(not Path("/sys/kernel").is_dir(), reason="needs sysfs")
@pytest.mark.parametrize("args", [["schema", "-o"], ["report", "RESULTS", "-o"], ["check", "RESULTS", "--junit"],
                                  ["check", "RESULTS", "--write-baseline"]])
def test_output_file_in_a_folder_root_cannot_write(leo_results, args):
    target = "/sys/sms-out.file"
    r = run_cli(*[leo_results if a == "RESULTS" else a for a in args], target)
    assert_clean(r, 2, target, "you may not write in /sys", "fix:")
    assert "PASS" not in r.output and not stray(leo_results)  # refused before the check ran


@pytest.mark.parametrize("command, err, code, words", [
    ("budget", OSError(errno.EROFS, "Read-only file system"), 2, "read-only file system"),  # a read-only mount
    ("run", OSError(errno.ENOSPC, "No space left on device"), 3, "the disk is full"),  # disk full at the check
])
def test_the_probe_file_cannot_be_created(tmp_path, monkeypatch, command, err, code, words):
    """The up-front check of the output folder fails to create its probe file (simulated)."""
    def fail(*a, **k):
        raise err

    monkeypatch.setattr("sms_cli.outputs.tempfile.mkstemp", fail)
    r = run_cli(command, NO_MISSION, "-o", tmp_path / "out")
    assert_clean(r, code, tmp_path / "out", words)
    assert not (tmp_path / "out").exists()


def test_simulate_recording_under_a_file(tmp_path):
    f = tmp_path / "afile"
    f.write_text("x")
    r = run_cli("simulate", NO_MISSION, "-o", f / "run.mcap")
    assert_clean(r, 2, f / "run.mcap", "is a file, not a folder")


@pytest.mark.parametrize("opt,example", [("--junit", "junit.xml"), ("--write-baseline", "baseline.json")])
def test_check_output_file_is_a_folder(tmp_path, leo_results, opt, example):
    d = tmp_path / "dir"
    d.mkdir()
    r = run_cli("check", leo_results, opt, d)
    assert_clean(r, 2, d, "is a folder", f"e.g. {d / example}")
    assert list(d.iterdir()) == [] and not stray(leo_results)


def test_check_baseline_is_a_folder(tmp_path, leo_results):
    r = run_cli("check", leo_results, "--baseline", tmp_path)
    assert_clean(r, 2, tmp_path, "is a folder, not the baseline", "--write-baseline")


def test_report_and_schema_into_a_folder(tmp_path, leo_results):
    r = run_cli("report", leo_results, "-o", tmp_path)
    assert_clean(r, 2, tmp_path, "is a folder", f"e.g. {tmp_path / 'report.html'}")
    r = run_cli("schema", "-o", tmp_path)
    assert_clean(r, 2, tmp_path, "is a folder", "mission.schema.json")
    (leo_results / "report.html").mkdir()
    try:
        r = run_cli("report", leo_results)  # the default target is a folder
        assert_clean(r, 2, leo_results / "report.html", "is a folder")
    finally:
        (leo_results / "report.html").rmdir()
    assert list(tmp_path.iterdir()) == [] and not stray(leo_results)


def test_report_pdf_path_checked_before_the_html_is_written(tmp_path, leo_results):
    (tmp_path / "r.pdf").mkdir()
    r = run_cli("report", leo_results, "-o", tmp_path / "r.html", "--pdf")
    assert_clean(r, 2, tmp_path / "r.pdf", "is a folder")
    assert not (tmp_path / "r.html").exists()


def test_output_onto_a_pipe_is_refused_not_replaced(tmp_path):
    """An atomic write renames onto its target: onto a device or a pipe it would replace it."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    r = run_cli("schema", "-o", fifo)
    assert_clean(r, 2, fifo, "not an ordinary file")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


# ---------------------------------------------------------------- failures during the write


def _raise_in_fsync(monkeypatch, err: int, text: str) -> None:
    def fsync(fd):
        raise OSError(err, text)  # as a write() on a full disk: no file name

    monkeypatch.setattr("sms_cli.results.os.fsync", fsync)


@pytest.mark.parametrize("err,words", [(errno.ENOSPC, "the disk is full"), (errno.EDQUOT, "quota")])
def test_disk_full_while_writing_is_exit_3(tmp_path, monkeypatch, err, words):
    target = tmp_path / "schema.json"
    target.write_text("old\n")
    _raise_in_fsync(monkeypatch, err, os.strerror(err))
    r = run_cli("schema", "-o", target)
    assert_clean(r, 3, target, words, "fix:")
    assert target.read_text() == "old\n" and not stray(tmp_path)


def test_disk_full_writing_a_baseline(tmp_path, monkeypatch, leo_results):
    _raise_in_fsync(monkeypatch, errno.ENOSPC, "No space left on device")
    b = tmp_path / "b.json"
    r = run_cli("check", leo_results, "--write-baseline", b)
    assert_clean(r, 3, b, "the disk is full")
    assert not b.exists() and not stray(tmp_path)


@pytest.mark.parametrize("call", ["replace", "chmod"])
def test_os_error_that_escapes_names_the_target_not_the_temporary(tmp_path, monkeypatch, call):
    """A failure after the checks (a permission changed meanwhile): exit 2, the user's path, not
    the temporary ``.NAME.XXXX.part`` (a rename names both, a chmod only the temporary)."""
    def replace(src, dst):
        raise PermissionError(errno.EACCES, "Permission denied", os.fspath(src), None, os.fspath(dst))

    def chmod(path, mode):
        raise PermissionError(errno.EACCES, "Permission denied", os.fspath(path))

    monkeypatch.setattr(f"sms_cli.results.os.{call}", replace if call == "replace" else chmod)
    target = tmp_path / "s.json"
    r = run_cli("schema", "-o", target)
    assert_clean(r, 2, target, "permission denied", "fix:")
    assert ".part" not in r.output and not target.exists() and not stray(tmp_path)


# ---------------------------------------------------------------- CLI-wide: warnings, numeric and internal errors


def _schema_does(monkeypatch, fn) -> None:
    monkeypatch.setattr("sms_cli.mission.load.mission_json_schema", fn)


def test_warnings_are_one_plain_line_numeric_ones_silent(monkeypatch):
    import warnings

    import numpy as np

    def noisy():
        np.array([0.0, 1.0]) / np.array([0.0, 0.0])  # invalid value / divide by zero
        warnings.warn("the mesh is ignored\nsecond line", UserWarning)
        return {}

    _schema_does(monkeypatch, noisy)
    r = run_cli("schema")
    assert_clean(r, 0, "warning: the mesh is ignored")
    assert "second line" not in r.output and "invalid value" not in r.output and "divide" not in r.output


def test_numerical_failure_exit_3_without_the_class_name(monkeypatch):
    import numpy as np

    def singular():
        raise np.linalg.LinAlgError("Singular matrix")

    _schema_does(monkeypatch, singular)
    r = run_cli("schema")
    assert_clean(r, 3, "numerical failure: Singular matrix", "fix:")


def test_a_bug_is_still_exit_4(monkeypatch):
    def bug():
        raise KeyError("oops")

    _schema_does(monkeypatch, bug)
    r = run_cli("schema")
    assert r.exit_code == 4 and "internal error" in r.output and "please report it" in r.output
