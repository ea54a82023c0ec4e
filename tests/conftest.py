"""Shared test helpers: paths, CLI runner, mission compilation."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
MISSIONS = ROOT / "missions"


@pytest.fixture(scope="session")
def runner() -> CliRunner:
    return CliRunner()


#: What the error contract forbids in text shown to a user: a Python exception class name, a
#: traceback, a source location of sms's own code.
EXCEPTION_TEXT = re.compile(r"\b[A-Za-z_]\w*(?:Error|Exception|Warning|Interrupt)\b|Traceback|\.py:\d+")


def assert_clean(result, code: int, *texts) -> None:
    """The exit code, each text (a path, a phrase) in the output, nothing the error contract forbids."""
    assert result.exit_code == code, result.output
    for t in texts:
        assert str(t) in result.output, result.output
    assert not EXCEPTION_TEXT.search(result.output), result.output


def run_cli(*args: str):
    """Invoke ``sms`` in-process; returns click's Result (exit_code, stdout, stderr)."""
    from sms_cli.cli import app

    return CliRunner().invoke(app, [str(a) for a in args])


def compile_path(path: Path | str):
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    return compile_system(load_mission(path))


def sm_sensed(sm, t, st):
    """Noise-free measurements of a plant state (what the controllers see), for law tests."""
    from sms_cli.sim.sensors import Sensors
    from sms_cli.sim.schema import SensorsSpec

    return Sensors(sm, SensorsSpec()).measure(t, st.q, st.v, st.eta, st.etadot)


@pytest.fixture(scope="module")
def arm3():
    return compile_path(DATA / "arm3.yaml")


def assert_tree_close(a, b, path: str = "", rel: float = 1e-9, abs_: float = 2e-9) -> None:
    """Equal JSON trees (dicts, lists, numbers, strings): numbers to ``rel`` relative or ``abs_`` absolute
    (two engines differ by round-off; /tf poses are integer counts of 1e-9, so the last count may flip);
    ``path`` names the first difference."""
    import pytest

    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            assert_tree_close(a[k], b[k], f"{path}.{k}", rel, abs_)
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_tree_close(x, y, f"{path}[{i}]", rel, abs_)
    elif isinstance(a, float) or isinstance(b, float):
        assert b == pytest.approx(a, rel=rel, abs=abs_), path
    else:
        assert a == b, path
