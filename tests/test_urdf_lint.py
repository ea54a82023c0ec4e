"""Every bad URDF input gives its message, the URDF line, and exit code 2 through the CLI."""

from pathlib import Path

import pytest

from conftest import DATA, run_cli

URDF = (DATA / "arm3.urdf").read_text()
MISSION = (DATA / "arm3.yaml").read_text()


def compile_with(tmp_path: Path, urdf_text: str):
    (tmp_path / "arm3.urdf").write_text(urdf_text)
    (tmp_path / "m.yaml").write_text(MISSION)
    return run_cli("compile", tmp_path / "m.yaml")


def line_of(text: str, needle: str) -> int:
    return next(i for i, l in enumerate(text.splitlines(), 1) if needle in l)


CASES = [
    ("undefined child link", lambda u: u.replace('<child link="l2"/>', '<child link="l2x"/>'), "child link 'l2x' is not defined", '<child link="l2x"/>'),
    ("undefined parent link", lambda u: u.replace('<parent link="l1"/>', '<parent link="lone"/>'), "parent link 'lone' is not defined", '<parent link="lone"/>'),
    ("several roots", lambda u: u.replace("</robot>", '<link name="orphan"/>\n</robot>'), "root links", '<link name="orphan"/>'),
    ("duplicate link", lambda u: u.replace("</robot>", '<link name="l1"/>\n</robot>'), "duplicate link name 'l1'", '<link name="l1"/>\n</robot>'),
    ("duplicate joint", lambda u: u.replace('<joint name="j3"', '<joint name="j2"'), "duplicate joint name 'j2'", None),
    ("negative mass", lambda u: u.replace('<mass value="4"/>', '<mass value="-4"/>'), "negative mass", '<mass value="-4"/>'),
    ("zero axis", lambda u: u.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>', 1), "zero axis", '<axis xyz="0 0 0"/>'),
    ("malformed axis", lambda u: u.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 1"/>', 1), "holds 2 value(s), expected 3", '<axis xyz="0 1"/>'),
    ("unsupported joint type", lambda u: u.replace('name="j3" type="revolute"', 'name="j3" type="planar"'), "unsupported type 'planar'", 'type="planar"'),
    ("malformed XML", lambda u: u.replace("</robot>", ""), "not well-formed XML", None),
]


@pytest.mark.parametrize("label, mutate, message, needle", CASES, ids=[c[0] for c in CASES])
def test_bad_urdf_exit_2_with_line(tmp_path, label, mutate, message, needle):
    bad = mutate(URDF)
    assert bad != URDF
    r = compile_with(tmp_path, bad)
    assert r.exit_code == 2, r.output
    assert message in r.stderr
    assert "Traceback" not in r.stderr
    if needle:
        assert f"arm3.urdf:{line_of(bad, needle.splitlines()[0])}" in r.stderr


def test_malformed_number_is_found_before_pinocchio(tmp_path):
    """urdfdom would say "at line 243 in model.cpp"; the lint names the URDF's own line."""
    bad = URDF.replace('<origin xyz="0 0 0.2" rpy="0 0 0"/>', '<origin xyz="0 zero 0.2" rpy="0 0 0"/>')
    r = compile_with(tmp_path, bad)
    assert r.exit_code == 2
    needle = 'xyz="0 zero 0.2"'
    assert f"arm3.urdf:{line_of(bad, needle)}: joint 'j2': <origin {needle}> 'zero' is not a decimal number" in r.stderr
    assert "model.cpp" not in r.stderr and "Pinocchio" not in r.stderr


def test_non_unit_axis_is_normalised_with_warning(tmp_path):
    r = compile_with(tmp_path, URDF.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 2"/>', 1))
    assert r.exit_code == 0, r.output
    assert "has norm 2; normalised" in r.stdout


def test_missing_limit_accepted_and_reported(tmp_path):
    bad = URDF.replace('<limit lower="-2.5" upper="2.5" effort="30" velocity="0.5"/>', "")
    r = compile_with(tmp_path, bad)
    assert r.exit_code == 0, r.output
    assert "revolute joint 'j3' has no <limit>" in r.stdout


@pytest.mark.parametrize("edit, message", [
    (lambda m: m.replace("end_effector: ee", "end_effector: eee"), "did you mean 'ee'"),
    (lambda m: m.replace("j3: -0.7", "j4: -0.7"), "no movable joint named 'j4'"),
    (lambda m: m.replace("frame: ee,", "frame: tool,"), "no link or frame named 'tool'"),
    (lambda m: m.replace("urdf: arm3.urdf", "urdf: nothere.urdf"), "nothere.urdf: no such file"),
    (lambda m: m.replace("participation: [0.8, 0, 0, 0, 1.1, 0]", "participation: [80, 0, 0, 0, 110, 0]"), "not positive definite"),
])
def test_bad_mission_against_robot_exit_2(tmp_path, edit, message):
    (tmp_path / "arm3.urdf").write_text(URDF)
    (tmp_path / "m.yaml").write_text(edit(MISSION))
    r = run_cli("compile", tmp_path / "m.yaml")
    assert r.exit_code == 2, r.output
    assert message in r.stderr
