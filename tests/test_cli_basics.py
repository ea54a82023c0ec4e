"""The CLI answers --version/--help without importing heavy modules, and maps errors to exit codes."""

import subprocess
import sys

from conftest import run_cli
from sms_cli import __version__


def test_version_and_help():
    r = run_cli("--version")
    assert r.exit_code == 0 and __version__ in r.stdout
    r = run_cli("--help")
    assert r.exit_code == 0 and "Exit codes" in r.stdout and "compile" in r.stdout


def test_cli_import_is_light():
    code = "import sys, sms_cli.cli; print(sorted(m for m in ('pinocchio','numpy','scipy','cvxpy','matplotlib') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"


def test_missing_mission_file_exit_2(tmp_path):
    r = run_cli("compile", tmp_path / "nope.yaml")
    assert r.exit_code == 2 and "no such file" in r.stderr


def test_mission_without_robot_exit_2(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_text("name: budget only\n")
    r = run_cli("compile", p)
    assert r.exit_code == 2 and "has no robot" in r.stderr
