"""Fuzzing the inputs: mutated shipped missions, URDFs, results and recordings through the CLI.

The property, for every input: the exit code is 0, 1, 2 or 3 (never 4: that is a bug), no Python
exception name or traceback reaches the user, the command ends within a time bound, and nothing
half-written is left (no ``.part`` file). The default run tries a fixed, bounded set of examples
(derandomised: the same ones on every machine, well under a minute); the ``slow`` run draws
fresh random ones, in subprocesses with a memory limit.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import EXCEPTION_TEXT, MISSIONS, ROOT, run_cli
from fuzz_mutators import corrupt_bytes, mutate_mission, mutate_urdf

EXCEPTION_NAMES = EXCEPTION_TEXT
ALLOWED = {0, 1, 2, 3}
SECONDS = 20  # bound on one in-process command (the slowest compile of a shipped mission takes < 2 s)

FUZZ_MISSIONS = ["caldera_s1_slew.yaml", "pulsar_simple.yaml", "astrobee_slew_backstepping.yaml",
                 "hipparcos_leo.yaml", "demeter_3dof.yaml", "chevallard_deploy_track.yaml"]
FUZZ_URDFS = ["caldera_smallsat.urdf", "pulsar_simple.urdf", "astrobee_arm.urdf"]

def check(result, out_dir: Path | None = None) -> None:
    """The fuzz property on one CLI result."""
    assert result.exit_code in ALLOWED, f"exit {result.exit_code}:\n{result.output}"
    assert not EXCEPTION_NAMES.search(result.output), result.output
    assert len(result.output) < 200_000, "unbounded output"
    if out_dir is not None and out_dir.exists():
        stray = [p.name for p in out_dir.rglob("*.part")]
        assert not stray, f"half-written files left: {stray}"


class Timeout(Exception):
    pass


def bounded(fn, seconds: int = SECONDS):
    """Run fn() with a wall-clock bound (SIGALRM, main thread); a hang fails the example."""
    def alarm(*_):
        raise Timeout(f"no answer within {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        return fn()
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    """A copy of missions/ and robots/ (missions refer to ../robots/)."""
    root = tmp_path_factory.mktemp("fuzz")
    shutil.copytree(MISSIONS, root / "missions")
    shutil.copytree(ROOT / "robots", root / "robots")
    return root


FUZZ = settings(max_examples=60, deadline=None, database=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


# ---------------------------------------------------------------- default run (bounded, deterministic)
@FUZZ
@given(data=st.data())
def test_fuzzed_missions_never_crash(tree, data):
    name = data.draw(st.sampled_from(FUZZ_MISSIONS))
    text = mutate_mission((MISSIONS / name).read_text(), data.draw(st.randoms(use_true_random=False)))
    path = tree / "missions" / "fuzz.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogateescape")
    check(bounded(lambda: run_cli("compile", path)))


@FUZZ
@given(data=st.data())
def test_fuzzed_urdfs_never_crash(tree, data):
    name = data.draw(st.sampled_from(FUZZ_URDFS))
    text = mutate_urdf((ROOT / "robots" / name).read_text(), data.draw(st.randoms(use_true_random=False)))
    (tree / "robots" / "fuzz.urdf").write_text(text)
    mission = tree / "missions" / "fuzz_urdf.yaml"
    mission.write_text("name: fuzz\nrobot: {urdf: ../robots/fuzz.urdf}\n")
    check(bounded(lambda: run_cli("compile", mission)))


@pytest.fixture(scope="module")
def results_dir(tree) -> Path:
    """A real results folder (compile + budget) to corrupt."""
    out = tree / "results"
    assert run_cli("budget", tree / "missions" / "hipparcos_leo.yaml", "-o", out).exit_code == 0
    return out


@settings(max_examples=40, deadline=None, database=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzzed_results_and_baselines_never_crash(results_dir, tmp_path, data):
    original = (results_dir / "results.json").read_bytes()
    work = tmp_path / "r"
    work.mkdir(exist_ok=True)
    rng = data.draw(st.randoms(use_true_random=False))
    kind = rng.choice(["bytes", "cut", "json", "json", "baseline"])
    base = None
    if kind in ("bytes", "cut"):
        blob = corrupt_bytes(original, rng, cut=kind == "cut")
    else:
        doc = json.loads(original)
        replacement = rng.choice([None, [], {}, "x", 1.5, [None], {"a": None}, float("nan")])
        if kind == "json":
            key = rng.choice(sorted(doc) + ["__root__"])
            doc = replacement if key == "__root__" else {**doc, key: replacement}
        else:
            base = tmp_path / "baseline.json"
            base.write_text(json.dumps({"budget.total_dv_m_s": replacement, "metrics": replacement}))
        blob = json.dumps(doc).encode()
    (work / "results.json").write_bytes(blob)
    args = ["check", work] + (["--baseline", base] if base else [])
    check(bounded(lambda: run_cli(*args)), work)
    check(bounded(lambda: run_cli("report", work, "-o", tmp_path / "report.html")), work)


# ---------------------------------------------------------------- slow run: fresh random inputs, subprocesses
def run_limited(args: list[str], cwd: Path, seconds: int = 60, memory: int = 3 << 30) -> subprocess.CompletedProcess:
    """``sms`` in a subprocess with an address-space limit and a timeout."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    sms = Path(sys.executable).with_name("sms")
    return subprocess.run([str(sms), *args], cwd=cwd, capture_output=True, text=True, timeout=seconds,
                          preexec_fn=limit, env={**os.environ, "SMS_NO_PROGRESS": "1"})


@pytest.mark.slow
@settings(max_examples=30, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_fuzzed_inputs_in_subprocesses(tree, data):
    if data.draw(st.booleans()):
        name = data.draw(st.sampled_from(FUZZ_MISSIONS))
        text = mutate_mission((MISSIONS / name).read_text(), data.draw(st.randoms(use_true_random=False)))
        path = tree / "missions" / "fuzz_slow.yaml"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
    else:
        name = data.draw(st.sampled_from(FUZZ_URDFS))
        text = mutate_urdf((ROOT / "robots" / name).read_text(), data.draw(st.randoms(use_true_random=False)))
        (tree / "robots" / "fuzz_slow.urdf").write_text(text)
        path = tree / "missions" / "fuzz_slow.yaml"
        path.write_text("name: fuzz\nrobot: {urdf: ../robots/fuzz_slow.urdf}\n")
    r = run_limited(["compile", str(path)], tree)
    out = r.stdout + r.stderr
    assert r.returncode in ALLOWED, f"exit {r.returncode}:\n{out}"
    assert not EXCEPTION_NAMES.search(out), out
