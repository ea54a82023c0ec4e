"""Faults that must not lose data (issue #17 items 8, 10–13), through the CLI.

SIGINT/SIGTERM during ``sms simulate`` and ``sms run`` (metrics, CSV and plots of what ran, exit
130), SIGKILL (the recording opens as it is, ``sms inspect --repair`` indexes it, the next run
reports the killed one and removes its temporaries), two writers into one results folder (exit 2
naming the holder), results of another mission (started afresh, not mixed), a full disk (exit 3,
the recording readable up to the failure), flipped and truncated MCAP bytes (exit 2 saying what is
readable, then repaired). The ``mcap`` package's reader is the independent oracle.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from conftest import EXCEPTION_TEXT, MISSIONS, ROOT, run_cli

EXCEPTION_NAME = EXCEPTION_TEXT


def mission(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / f"{name}.yaml"
    p.write_text(text)
    return p


def long_slew(tmp_path: Path, name: str = "long slew") -> Path:
    """The Python loop for ~15 s: caldera S1 over 2400 s, simulation only."""
    return mission(tmp_path, "long_slew", f"""\
extends: {MISSIONS / 'caldera_s1_slew.yaml'}
name: {name}
analysis: null
synthesis: null
requirements: []
simulation:
  engine: python  # the compiled loop would finish this in about 2 s
  phases:
    - {{name: slew, kind: slew, duration: 2400 s, attitude: [60 deg, 60 deg, 60 deg]}}
""")


def long_detumble(tmp_path: Path) -> Path:
    """The compiled loop for a few seconds: Basilisk's scenario over 20000 s."""
    return mission(tmp_path, "long_detumble", f"""\
extends: {MISSIONS / 'basilisk_rw_reference.yaml'}
name: long detumble
requirements: []
simulation:
  record_rate: 2 Hz
  phases:
    - {{name: detumble, kind: hold, duration: 20000 s, base_mode: rotation-free-floating, attitude: [0, 0, 0]}}
""")


def start(tmp_path: Path, *args) -> tuple[subprocess.Popen, Path]:
    err = tmp_path / f"stderr_{time.monotonic_ns()}.txt"
    proc = subprocess.Popen([sys.executable, "-m", "sms_cli", *map(str, args), "--no-progress"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=open(err, "w"), env={**os.environ, "PYTHONUNBUFFERED": "1"})
    return proc, err


def wait_for(path: Path, proc: subprocess.Popen, min_bytes: int = 300_000, timeout: float = 180) -> None:
    """Until the recording has a few chunks (first runs compile the kernels: allow for it)."""
    t0 = time.monotonic()
    while not (path.exists() and path.stat().st_size > min_bytes):
        assert proc.poll() is None, f"the run ended (exit {proc.returncode}) before its recording started"
        assert time.monotonic() - t0 < timeout, "the recording did not start"
        time.sleep(0.01)


def finish(proc: subprocess.Popen, err: Path, timeout: float = 120) -> tuple[int, str]:
    try:
        code = proc.wait(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
    return code, err.read_text()


def read_mcap(path: Path) -> tuple[int, float, dict]:
    """(messages, last log time in s, metadata) through the mcap package's reader."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        times = [m.log_time for _, _, m in reader.iter_messages(log_time_order=False)]
        f.seek(0)
        meta = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    return len(times), max(times) / 1e9, meta


def no_parts(folder: Path) -> None:
    assert not list(folder.glob(".*.part")), list(folder.glob(".*.part"))


def csv_times(path: Path) -> list[float]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows and all(len(r) == len(rows[0]) for r in rows)
    return [float(r[0]) for r in rows[1:]]


# --------------------------------------------------------------------------- items 10, 11: SIGINT, SIGTERM
@pytest.mark.parametrize("sig, engine", [(signal.SIGINT, "python"), (signal.SIGTERM, "compiled")])
def test_signal_during_simulate_writes_what_ran(tmp_path, sig, engine):
    m = long_slew(tmp_path) if engine == "python" else long_detumble(tmp_path)
    out = tmp_path / "out"
    proc, err = start(tmp_path, "simulate", m, "-o", out)
    wait_for(out / "simulation.mcap", proc)
    proc.send_signal(sig)
    code, text = finish(proc, err)
    assert code == 130, text
    assert "interrupted at t = " in text and str(out) in text and not EXCEPTION_NAME.search(text), text
    sim = json.loads((out / "results.json").read_text())["simulate"]
    assert sim["status"] == "interrupted" and 0 < sim["t_end_s"] < (2400 if engine == "python" else 20000)
    assert sim["timing"]["engine"].startswith(engine) and sim["overall"]["attitude_error_deg"]["max"] > 0
    assert sim["phases"] and sim["phases"][0]["duration_s"] == pytest.approx(sim["t_end_s"])
    times = csv_times(out / "simulation.csv")
    assert times[0] == 0 and times[-1] <= sim["t_end_s"] and times[-1] > sim["t_end_s"] - 1
    assert {p for p in sim["files"]["plots"]} <= {p.name for p in out.glob("*.png")} and sim["files"]["plots"]
    n, last, meta = read_mcap(out / "simulation.mcap")
    assert meta["run"]["status"] == "interrupted" and last == pytest.approx(sim["t_end_s"], abs=1.0)
    no_parts(out)


def test_sigterm_during_run_records_the_stage_interrupted(tmp_path):
    out = tmp_path / "out"
    proc, err = start(tmp_path, "run", long_slew(tmp_path), "-o", out)
    wait_for(out / "simulation.mcap", proc)
    proc.send_signal(signal.SIGTERM)
    code, text = finish(proc, err)
    assert code == 130 and not EXCEPTION_NAME.search(text), text
    results = json.loads((out / "results.json").read_text())
    assert results["run"]["state"] == "interrupted"
    assert [s["status"] for s in results["run"]["stages"]] == ["ok", "not configured", "not configured", "not configured",
                                                                "interrupted"]
    assert results["simulate"]["status"] == "interrupted" and (out / "simulation.csv").exists()
    no_parts(out)


def test_signal_before_the_recording_starts(tmp_path):
    """Interrupted while compiling: nothing ran; the section says so, the recording is finalised."""
    out = tmp_path / "out"
    proc, err = start(tmp_path, "simulate", long_slew(tmp_path), "-o", out)
    while not (out / "simulation.mcap").exists():
        assert proc.poll() is None
        time.sleep(0.002)
    proc.send_signal(signal.SIGINT)
    code, text = finish(proc, err)
    assert code == 130 and not EXCEPTION_NAME.search(text), text
    sim = json.loads((out / "results.json").read_text())["simulate"]
    assert sim["status"] == "interrupted"
    assert read_mcap(out / "simulation.mcap")[2]["run"]["status"] == "interrupted"
    no_parts(out)


# --------------------------------------------------------------------------- item 11: SIGKILL
def test_sigkill_leaves_a_readable_recording_and_the_next_run_says_so(tmp_path):
    from sms_cli.results import ResultsDir

    out = tmp_path / "out"
    m = long_slew(tmp_path)
    proc, err = start(tmp_path, "run", m, "-o", out)
    wait_for(out / "simulation.mcap", proc, min_bytes=1_000_000)
    proc.kill()
    proc.wait(timeout=60)
    rec = out / "simulation.mcap"
    n, last, meta = read_mcap(rec)  # the end marker: the mcap reader opens it as it is
    assert n > 10_000 and "run" not in meta  # the ≥ 1 MB of complete chunks waited for
    assert json.loads((out / "results.json").read_text())["run"]["state"] == "running"  # on disk
    assert ResultsDir(out).read()["run"]["state"] == "killed"  # what sms check / report are given

    r = run_cli("inspect", rec)
    assert r.exit_code == 0 and "status: killed" in r.output
    assert re.search(r"the run was killed at about t = [\d.]+ s; \d+ messages .*sms inspect --repair", r.output)
    r = run_cli("inspect", "--repair", rec)
    assert r.exit_code == 0, r.output
    found = re.search(r"(\d+) messages in (\d+) chunks recovered, up to t = ([\d.]+) s", r.stderr)
    assert found and int(found.group(1)) == n and float(found.group(3)) == pytest.approx(last)
    with open(rec, "rb") as f:
        stats = make_reader(f).get_summary().statistics  # now indexed
    assert stats.message_count == n and stats.chunk_count == int(found.group(2))
    assert read_mcap(rec)[2]["run"]["status"] == "killed"

    # a temporary of the dead process and one of a live process (this one)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = out / f".simulation.csv.{dead.stdout.strip()}-k1ll3d.part"
    live = out / f".report.html.{os.getpid()}-w0rk1ng.part"
    stale.write_text("half")
    live.write_text("half")
    proc, err = start(tmp_path, "simulate", MISSIONS / "caldera_s1_slew.yaml", "-o", out)
    code, text = finish(proc, err)
    assert code == 0, text
    assert f"removed 1 temporary file(s) left by a killed run: {stale.name}" in text
    assert "the previous run" in text and "was killed after stage 'compile'" in text
    assert not stale.exists() and live.exists()
    live.unlink()


# --------------------------------------------------------------------------- item 12: two writers
def test_second_writer_is_refused_naming_the_holder(tmp_path):
    out = tmp_path / "out"
    proc, err = start(tmp_path, "simulate", long_slew(tmp_path, "first mission"), "-o", out)
    try:
        wait_for(out / "simulation.mcap", proc, min_bytes=1)
        r = run_cli("inspect", out / "simulation.mcap")  # a reader is welcome, and told the file grows
        assert r.exit_code == 0 and "status: recording" in r.output and f"still being written (PID {proc.pid})" in r.output
        for cmd in (["run", MISSIONS / "basilisk_rw_reference.yaml", "-o", out],
                    ["simulate", MISSIONS / "caldera_s1_slew.yaml", "-o", out],
                    ["budget", MISSIONS / "hipparcos_leo.yaml", "-o", out],
                    ["analyze", MISSIONS / "demeter_3dof.yaml", "-o", out],
                    ["synthesize", MISSIONS / "caldera_s1_slew.yaml", "-o", out]):
            r = subprocess.run([sys.executable, "-m", "sms_cli", *map(str, cmd)], cwd=ROOT, capture_output=True, text=True,
                               timeout=120)
            assert r.returncode == 2, r.stderr
            assert str(out) in r.stderr and f"PID {proc.pid}" in r.stderr and "'first mission'" in r.stderr
            assert "-o " in r.stderr and not EXCEPTION_NAME.search(r.stderr)
        # refused before writing anything: no budget, analysis or synthesis file beside the first run's
        assert not [p.name for p in out.iterdir() if p.name.startswith(("budget", "analysis", "gains", "synthesis"))]
    finally:
        proc.send_signal(signal.SIGINT)
        code, text = finish(proc, err)
    assert code == 130, text
    assert json.loads((out / "results.json").read_text())["simulate"]["mission"] == "first mission"


def test_results_of_another_mission_are_not_mixed(tmp_path):
    out = tmp_path / "out"
    r = run_cli("simulate", MISSIONS / "caldera_s1_slew.yaml", "-o", out)
    assert r.exit_code == 0, r.output
    r = run_cli("run", MISSIONS / "basilisk_rw_reference.yaml", "-o", out, "--no-report")
    assert r.exit_code == 0, r.output
    assert "holds the results of another mission ('caldera_s1_slew'" in r.stderr and "afresh" in r.stderr
    results = json.loads((out / "results.json").read_text())
    assert set(results) == {"compile", "simulate", "run", "requirements"}
    assert results["simulate"]["mission"] == "basilisk_rw_reference"
    # the same mission again: kept, no message
    r = run_cli("simulate", MISSIONS / "basilisk_rw_reference.yaml", "-o", out)
    assert r.exit_code == 0 and "another mission" not in r.stderr
    assert set(json.loads((out / "results.json").read_text())) == {"compile", "simulate", "run", "requirements"}


@pytest.mark.parametrize("command, mission", [("budget", "hipparcos_leo.yaml"), ("analyze", "demeter_3dof.yaml")])
def test_stage_commands_do_not_mix_missions_either(tmp_path, command, mission):
    out = tmp_path / "out"
    assert run_cli("simulate", MISSIONS / "basilisk_rw_reference.yaml", "-o", out).exit_code == 0
    r = run_cli(command, MISSIONS / mission, "-o", out, "--no-plots" if command == "analyze" else "--json")
    assert r.exit_code == 0, r.output
    assert "holds the results of another mission ('basilisk_rw_reference'" in r.stderr
    assert "simulate" not in json.loads((out / "results.json").read_text())


# --------------------------------------------------------------------------- item 13: disk full
class FullDisk(io.FileIO):
    """A file on a disk with ``room`` bytes: a write past it writes what fits, the next one fails."""

    room = 1_000_000

    def write(self, b) -> int:
        free = self.room - self.tell()
        if free <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().write(bytes(b)[:free])


def test_disk_full_during_simulate(tmp_path, monkeypatch):
    import sms_cli.recording.recorder as recorder

    monkeypatch.setattr(recorder, "open", lambda path, mode, buffering=-1: FullDisk(path, mode), raising=False)
    out = tmp_path / "out"
    r = run_cli("simulate", MISSIONS / "basilisk_rw_reference.yaml", "-o", out)
    assert r.exit_code == 3, r.output
    text = r.stderr
    assert "the disk filled while simulating" in text and str(out / "simulation.mcap") in text
    assert "free some space" in text and not EXCEPTION_NAME.search(text), text
    found = re.search(r"keeps (\d+) messages up to t = ([\d.]+) s", text)
    assert found, text
    n, last, _ = read_mcap(out / "simulation.mcap")
    assert n == int(found.group(1)) and last == pytest.approx(float(found.group(2)))
    assert (out / "simulation.mcap").stat().st_size <= FullDisk.room
    sim = json.loads((out / "results.json").read_text())["simulate"]
    assert sim["status"] == "failed" and sim["error"] == "the disk is full"
    assert sim["recorded_until_s"] == pytest.approx(last) and sim["t_end_s"] >= last
    assert run_cli("inspect", out / "simulation.mcap").exit_code == 0
    no_parts(out)


# --------------------------------------------------------------------------- item 8: damaged recordings
def small_recording(path: Path, samples: int = 3000) -> None:
    import numpy as np

    from sms_cli.recording.recorder import McapRecorder

    rec = McapRecorder(path, mission_text="m", mission_name="m", model_summary={}, urdf_text="<robot/>", versions={},
                       chunk_size=16 * 1024)
    rec.add_transform_tree(["base", "arm"], ["world", "base"])
    w = np.zeros((2, 7))
    w[:, 6] = 1
    with rec:
        for i in range(samples):
            w[:, 0] = i * 1e-3
            rec.write_step(i * 0.01, transforms=w, scalars={"/a": {"x": float(i)}, "/b": {"v": w[:, 0]}})


def test_flipped_bytes_name_the_damaged_chunk_then_repair(tmp_path):
    path = tmp_path / "run.mcap"
    small_recording(path)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    total = summary.statistics.message_count
    ci = summary.chunk_indexes[len(summary.chunk_indexes) // 2]
    data = bytearray(path.read_bytes())
    data[ci.chunk_start_offset + ci.chunk_length // 2] ^= 0x20
    path.write_bytes(bytes(data))
    r = run_cli("inspect", path)
    assert r.exit_code == 2, r.output
    text = r.stderr
    assert not EXCEPTION_NAME.search(text) and str(path) in text
    assert f"chunk at byte {ci.chunk_start_offset} (t = {ci.message_start_time / 1e9:.6g} – {ci.message_end_time / 1e9:.6g} s; " \
           "/a, /b, /tf)" in text
    lost = int(re.search(r"Still readable: (\d+) messages in the other", text).group(1))
    assert 0 < lost < total and "sms inspect --repair" in text
    r = run_cli("inspect", "--repair", path)
    assert r.exit_code == 0 and "1 damaged chunk(s) dropped" in r.stderr, r.output
    n, _, meta = read_mcap(path)
    assert n == lost and meta["repair"]["damaged_chunks_dropped"] == "1" and meta["run"]["status"] == "completed"


def test_truncated_recording_says_what_is_readable_then_repair(tmp_path):
    path = tmp_path / "run.mcap"
    small_recording(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    r = run_cli("inspect", path)
    assert r.exit_code == 2 and not EXCEPTION_NAME.search(r.stderr), r.output
    found = re.search(r"killed \(or its disk filled\) at about t = ([\d.]+) s; (\d+) messages", r.stderr)
    assert found and "sms inspect --repair" in r.stderr, r.stderr
    r = run_cli("inspect", "--repair", path)
    assert r.exit_code == 0, r.output
    n, last, meta = read_mcap(path)
    assert n == int(found.group(2)) and last == pytest.approx(float(found.group(1))) and meta["run"]["status"] == "killed"


def test_not_a_recording_is_refused_by_repair(tmp_path):
    path = tmp_path / "x.mcap"
    path.write_bytes(b"not mcap at all")
    r = run_cli("inspect", "--repair", path)
    assert r.exit_code == 2 and path.read_bytes() == b"not mcap at all" and not EXCEPTION_NAME.search(r.stderr)


# --------------------------------------------------------------------------- results.json read side
@pytest.mark.parametrize("content, where", [(b'{"simulate": {"status": "ok",\n  "t": [1, 2', ":2:"), (b"[1, 2]", ":1:1"),
                                            (b'{"a": "\xff"}', ":1:8"), (b"null", ":1:1")])
def test_damaged_results_json_is_an_input_error(tmp_path, content, where):
    from sms_cli.errors import InputError
    from sms_cli.results import ResultsDir

    (tmp_path / "results.json").write_bytes(content)
    with pytest.raises(InputError) as info:
        ResultsDir(tmp_path).read()
    text = info.value.render()
    assert f"{tmp_path / 'results.json'}{where}" in text and "re-run" in text and info.value.exit_code == 2
    assert not EXCEPTION_NAME.search(text)
    # a command that writes the folder starts it afresh and says so
    r = run_cli("simulate", MISSIONS / "caldera_s1_slew.yaml", "-o", tmp_path)
    assert r.exit_code == 0 and "starting it afresh" in r.stderr
    assert set(json.loads((tmp_path / "results.json").read_text())) == {"simulate"}


def test_bad_simulation_name_leaves_no_recording(tmp_path):
    m = mission(tmp_path, "bad", f"""\
extends: {MISSIONS / 'caldera_s2_arm.yaml'}
simulation:
  phases:
    - {{name: move, kind: deploy, duration: 1 s, waypoints: [{{at: 0.5 s, joints: {{joint_9: 1.0}}}}]}}
""")
    r = run_cli("simulate", m, "-o", tmp_path / "out")
    assert r.exit_code == 2 and "joint_9" in r.stderr, r.output
    assert not (tmp_path / "out" / "simulation.mcap").exists()


def test_damaged_first_chunk_keeps_the_rest(tmp_path):
    """The first chunk declares every channel; the summary's copies let repair keep the others."""
    path = tmp_path / "run.mcap"
    small_recording(path)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    ci = summary.chunk_indexes[0]
    data = bytearray(path.read_bytes())
    data[ci.chunk_start_offset + ci.chunk_length - 20] ^= 0x01
    path.write_bytes(bytes(data))
    r = run_cli("inspect", path)
    assert r.exit_code == 2 and f"chunk at byte {ci.chunk_start_offset} (t = 0 – " in r.stderr, r.output
    readable = int(re.search(r"Still readable: (\d+) messages", r.stderr).group(1))
    r = run_cli("inspect", "--repair", path)
    assert r.exit_code == 0, r.output
    n, _, meta = read_mcap(path)
    assert n == readable > 0 and meta["run"]["status"] == "completed"


@pytest.mark.parametrize("state", ["running", "interrupted"])
def test_check_and_report_of_a_killed_or_interrupted_run_fail_and_say_so(tmp_path, state):
    """A run left 'running' by a dead process reads as killed in sms check and sms report, as in sms run."""
    out = tmp_path / "r"
    assert run_cli("run", MISSIONS / "hipparcos_leo.yaml", "-o", out, "--no-report").exit_code == 0
    doc = json.loads((out / "results.json").read_text())
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    doc["run"] = {**doc["run"], "state": state, "pid": dead.pid}
    (out / "results.json").write_text(json.dumps(doc))
    word = "killed" if state == "running" else "interrupted"
    r = run_cli("check", out)
    assert r.exit_code == 1, r.output
    assert f"was {word}: its results are incomplete" in r.stdout
    r = run_cli("report", out, "-o", tmp_path / "report.html")
    assert r.exit_code == 0, r.output
    assert f"the run was {word}: results incomplete" in (tmp_path / "report.html").read_text()


@pytest.mark.parametrize("error, code, words", [
    (OSError(errno.ENOSPC, "No space left on device"), 3, "the disk is full"),
    (PermissionError(errno.EACCES, "Permission denied", "/somewhere/x.csv"), 2, "permission denied"),
])
def test_file_system_failure_inside_sms_run_is_the_contract_code(tmp_path, monkeypatch, error, code, words):
    """sms run maps a stage's file-system failure as every command does (one mapping: sms_cli.failures)."""
    import sms_cli.orbit.stage as budget_stage

    def broken(*args, **kwargs):
        raise error

    monkeypatch.setattr(budget_stage, "run_budget", broken)
    r = run_cli("run", MISSIONS / "hipparcos_leo.yaml", "-o", tmp_path / "r", "--no-report")
    assert r.exit_code == code, r.output
    assert words in r.output
    assert not re.search(r"\b\w+Error\b", r.output), r.output
