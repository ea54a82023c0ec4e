"""The URDF reproducers of the bad-input review, through the CLI: each is refused with exit 2 at
its URDF line (or accepted, where the model is usable), never exit 4, never an exception name.

Reproducers mutate ``robots/caldera_smallsat.urdf`` under a minimal mission ``name: t /
robot: {urdf: robot.urdf}``, or under a mission that ``extends:`` the shipped caldera mission.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

from conftest import EXCEPTION_TEXT, MISSIONS, ROOT, run_cli

URDF = (ROOT / "robots" / "caldera_smallsat.urdf").read_text()
EXCEPTION_NAMES = EXCEPTION_TEXT
FIRST_MASS = re.search(r'<mass value="([^"]+)"/>', URDF).group(0)


def line_of(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


def compile_minimal(tmp_path: Path, urdf: str):
    (tmp_path / "robot.urdf").write_text(urdf)
    (tmp_path / "m.yaml").write_text("name: t\nrobot: {urdf: robot.urdf}\n")
    return run_cli("compile", tmp_path / "m.yaml")


def compile_shipped(tmp_path: Path, urdf: str):
    """The shipped caldera mission (wheels, arm joints, end effector) on the mutated robot."""
    shutil.copytree(MISSIONS, tmp_path / "missions")
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "caldera_smallsat.urdf").write_text(urdf)
    return run_cli("compile", tmp_path / "missions" / "caldera_smallsat.yaml")


def refused_at(result, line: int, message: str) -> None:
    assert result.exit_code == 2, result.output
    assert f".urdf:{line}:" in result.stderr, result.stderr
    assert message in result.stderr, result.stderr
    assert not EXCEPTION_NAMES.search(result.output), result.output


# item 1: non-numeric numbers, NaN, huge and infinite values
@pytest.mark.parametrize("value, message", [
    ("nine", "'nine' is not a decimal number"), ("", "holds 0 value(s), expected 1"),
    ("0x10", "'0x10' is not a decimal number"), ("0 0 1 1", "holds 4 value(s), expected 1"),
    ("null", "'null' is not a decimal number"), ("nan", "is NaN"),
])
@pytest.mark.parametrize("compile_", [compile_minimal, compile_shipped], ids=["minimal", "shipped"])
def test_malformed_mass(tmp_path, value, message, compile_):
    bad = URDF.replace(FIRST_MASS, f'<mass value="{value}"/>', 1)
    refused_at(compile_(tmp_path, bad), line_of(bad, f'<mass value="{value}"/>'), message)


@pytest.mark.parametrize("value, message", [("1e308", "is out of range"), ("inf", "is infinite"), ("nan", "is NaN")])
@pytest.mark.parametrize("moment", ["ixx", "ixz"])  # an infinite product of inertia made eigvalsh fail (exit 3)
def test_huge_or_infinite_inertia(tmp_path, value, message, moment):
    first = re.search(rf'{moment}="([^"]+)"', URDF).group(0)
    bad = URDF.replace(first, f'{moment}="{value}"', 1)
    refused_at(compile_minimal(tmp_path, bad), line_of(bad, f'{moment}="{value}"'), message)


def test_nan_in_an_inertial_rpy_is_not_blamed_on_modes(tmp_path):
    """item 3: a NaN rpy used to be reported as a mass-matrix problem of 'modes' at the mission's line 1."""
    inertial = re.search(r"<inertial>\s*<origin [^>]*/>", URDF).group(0)
    bad = URDF.replace(inertial, re.sub(r'rpy="[^"]*"', 'rpy="nan 0 0"', inertial), 1)
    assert bad != URDF
    r = compile_minimal(tmp_path, bad)
    refused_at(r, line_of(bad, 'rpy="nan 0 0"'), "is NaN")
    assert "modes" not in r.stderr and "m.yaml:1" not in r.stderr


# item 2: topology
def _loop_urdf() -> str:
    return URDF.replace("</robot>", '<link name="a"/><link name="b"/>\n'
                        '<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>\n'
                        '<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint>\n</robot>')


@pytest.mark.parametrize("compile_", [compile_minimal, compile_shipped], ids=["minimal", "shipped"])
def test_loop_cut_off_from_the_base(tmp_path, compile_):
    bad = _loop_urdf()
    r = compile_(tmp_path, bad)
    refused_at(r, line_of(bad, '<link name="a"/>'), "links a, b are not connected to the base")


def test_joint_named_like_a_link_compiles(tmp_path):
    """Pinocchio alone raises "Several frames match" on such names; sms looks links up first."""
    joint = re.search(r'<joint name="([^"]+)" type="revolute">\s*<parent link="[^"]+"/>\s*<child link="([^"]+)"/>', URDF)
    bad = URDF.replace(f'<joint name="{joint.group(1)}"', f'<joint name="{joint.group(2)}"', 1)
    assert bad != URDF
    r = compile_minimal(tmp_path, bad)
    assert r.exit_code == 0, r.output


# item 3: a massless last moving link
def test_massless_last_moving_link_names_the_joint_not_modes(tmp_path):
    last = list(re.finditer(r'<link name="([^"]+)">\s*<inertial>.*?</inertial>', URDF, re.S))[-1]
    bad = URDF[: last.start()] + f'<link name="{last.group(1)}">' + URDF[last.end():]
    r = compile_minimal(tmp_path, bad)
    assert r.exit_code == 2, r.output
    assert f"link '{last.group(1)}'" in r.stderr and "the mass matrix is singular" in r.stderr
    assert "modes" not in r.stderr and "participation" not in r.stderr
    assert not EXCEPTION_NAMES.search(r.output)


# item 5 (URDF side): files that are not regular files
@pytest.mark.parametrize("kind", ["dev_zero", "fifo", "symlink_loop", "directory"])
def test_urdf_that_is_not_a_regular_file(tmp_path, kind):
    target = {"dev_zero": "/dev/zero", "fifo": "pipe.urdf", "symlink_loop": "loop1.urdf", "directory": "folder.urdf"}[kind]
    if kind == "fifo":
        os.mkfifo(tmp_path / target)
    elif kind == "symlink_loop":
        os.symlink(tmp_path / "loop2.urdf", tmp_path / "loop1.urdf")
        os.symlink(tmp_path / "loop1.urdf", tmp_path / "loop2.urdf")
    elif kind == "directory":
        (tmp_path / target).mkdir()
    (tmp_path / "m.yaml").write_text(f"name: t\nrobot: {{urdf: {target}}}\n")
    r = run_cli("compile", tmp_path / "m.yaml")
    assert r.exit_code == 2, r.output
    assert "m.yaml:2" in r.stderr and "URDF" in r.stderr
    assert not EXCEPTION_NAMES.search(r.output), r.output


# item 9 (URDF side): XML errors say the URDF's line in plain words, UTF-16 is accepted
def test_xml_error_without_libxml2_function_names(tmp_path):
    bad = URDF.replace("<robot ", "<robot foo='&bogus;' ", 1)
    r = compile_minimal(tmp_path, bad)
    assert r.exit_code == 2
    assert "Entity 'bogus' not defined" in r.stderr
    assert not re.search(r"\bxml[A-Z]\w+:", r.stderr) and ", line " not in r.stderr


def test_utf16_urdf_is_accepted(tmp_path):
    (tmp_path / "robot.urdf").write_bytes(URDF.replace('encoding="utf-8"', "").encode("utf-16"))
    (tmp_path / "m.yaml").write_text("name: t\nrobot: {urdf: robot.urdf}\n")
    r = run_cli("compile", tmp_path / "m.yaml")
    assert r.exit_code == 0, r.output
