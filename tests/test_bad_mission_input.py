"""Issue #17, mission-file inputs: every bad input is exit 2 with file:line, field and a fix.

Items 4 (NaN/inf), 5 (NUL, nesting, alias bombs, devices, FIFOs, symlink loops, size), 6 (mission
semantics), 9 (encodings, echoed unit strings). Each case goes through the CLI and checks the exit
code, the location, that no Python exception name is shown and that nothing is left on disk.
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import EXCEPTION_TEXT, MISSIONS, run_cli

SMS = Path(sys.executable).with_name("sms")
CALDERA = MISSIONS / "caldera_smallsat.yaml"
_EXC_NAME = EXCEPTION_TEXT


def _files(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*")}


def _clean(text: str) -> None:
    assert not _EXC_NAME.search(text), text


def compile_cli(tmp_path: Path, monkeypatch, mission: Path, *extra: str):
    """``sms compile`` in-process from ``tmp_path``; asserts that it writes nothing."""
    monkeypatch.chdir(tmp_path)
    before = _files(tmp_path)
    r = run_cli("compile", mission, *extra)
    assert _files(tmp_path) == before
    _clean(r.stderr + r.stdout)
    return r


def sms_subprocess(tmp_path: Path, *args: str, timeout: float = 60):
    """``sms`` in a child process (for hangs and memory): 1 GiB address space, ``timeout`` seconds."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))

    before = _files(tmp_path)
    r = subprocess.run([str(SMS), *map(str, args)], cwd=tmp_path, capture_output=True, text=True,
                       timeout=timeout, preexec_fn=limit)
    assert _files(tmp_path) == before
    _clean(r.stderr + r.stdout)
    return r


def extending(tmp_path: Path, body: str, parent: Path = CALDERA, name: str = "m.yaml") -> Path:
    p = tmp_path / name
    p.write_text(f"extends: {parent}\nname: t\n{body}")
    return p


def line_of(path: Path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def assert_input_error(r, mission: Path, line: int | None, *words: str) -> str:
    assert r.exit_code == 2, r.stderr
    err = r.stderr
    if line is not None:
        assert f"{mission.name}:{line}:" in err, err
    assert "fix:" in err, err
    for w in words:
        assert w in err, (w, err)
    return err


# ----------------------------------------------------------------------------- item 4: NaN / inf
NON_FINITE = [
    ("initial:\n  base_attitude: [.nan, 0, 0]\n", ".nan", "initial.base_attitude.0"),
    ("initial:\n  joints: {joint_1: .nan}\n", ".nan", "initial.joints.joint_1"),
    ("initial:\n  base_angular_velocity: [.nan, 0, 0]\n", ".nan", "initial.base_angular_velocity.0"),
    ("wheels:\n  declared:\n    - {name: x, axis: [.nan, 0, 1], spin_inertia: 0.02, max_torque: 0.2, max_speed: 6000 rpm}\n",
     ".nan", "wheels.declared.0.axis.0"),
    ("wheels:\n  declared:\n    - {name: x, axis: [0, 0, 1], position: [0, .nan, 0], spin_inertia: 0.02, max_torque: 0.2, "
     "max_speed: 6000 rpm}\n", ".nan", "wheels.declared.0.position.1"),
    ("payloads:\n  - {name: p, frame: ee_link, mass: .inf, inertia: [1, 1, 1]}\n", ".inf", "payloads.0.mass"),
    ("payloads:\n  - {name: p, frame: ee_link, mass: 1e999 kg, inertia: [1, 1, 1]}\n", "1e999", "payloads.0.mass"),
    ("initial:\n  joints: {joint_1: -.inf}\n", "-.inf", "initial.joints.joint_1"),
    # a plain float field (no unit): the schema's allow_inf_nan=False
    ("simulation:\n  wheel_friction: {viscous: .inf}\n", ".inf", "simulation.wheel_friction.viscous"),
]


@pytest.mark.parametrize("body,needle,field", NON_FINITE, ids=[f for _, _, f in NON_FINITE])
def test_non_finite_numbers_are_input_errors_at_load(tmp_path, monkeypatch, body, needle, field):
    m = extending(tmp_path, body)
    r = compile_cli(tmp_path, monkeypatch, m)
    err = assert_input_error(r, m, line_of(m, needle), field)
    assert "finite" in err


def test_non_finite_bound_of_a_union_field_is_one_problem(tmp_path, monkeypatch):
    # `max` is a number or a string with a unit: the string branch's "not a string" is noise
    m = extending(tmp_path, "requirements:\n  - {name: r, metric: compile.total_mass_kg, max: .nan}\n")
    err = assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 4, "requirements.0.max: not a finite number")
    assert "problem(s)" not in err and "string" not in err and ".float" not in err


# ------------------------------------------------------------------ item 5: hostile files
def test_nul_byte_is_reported_at_its_line(tmp_path, monkeypatch):
    m = tmp_path / "m.yaml"
    m.write_bytes(f"extends: {CALDERA}\nname: t\x00\n".encode())
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 2, "NUL")


def test_control_character_is_reported_at_its_line(tmp_path, monkeypatch):
    m = tmp_path / "m.yaml"
    m.write_bytes(f"extends: {CALDERA}\nname: t\x01\n".encode())
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 2, "U+0001")


def test_deep_nesting_is_refused_without_recursion(tmp_path, monkeypatch):
    m = tmp_path / "m.yaml"
    m.write_text("name: t\nx: " + "[" * 5000 + "]" * 5000 + "\n")
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 2, "nested more than")


def test_alias_bomb_is_refused_fast_with_bounded_memory(tmp_path):
    lines = ["name: t", "a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 10)]
    m = tmp_path / "m.yaml"
    m.write_text("\n".join(lines) + "\n")
    r = sms_subprocess(tmp_path, "compile", m, timeout=30)
    assert r.returncode == 2 and "aliases expand" in r.stderr and "m.yaml:" in r.stderr, r.stderr


def test_self_referencing_alias_is_refused(tmp_path, monkeypatch):
    m = tmp_path / "m.yaml"
    m.write_text("name: t\na: &a [*a]\n")
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 2, "aliases")


def test_device_as_mission_and_as_extends(tmp_path):
    r = sms_subprocess(tmp_path, "compile", "/dev/zero", timeout=30)
    assert r.returncode == 2 and "/dev/zero" in r.stderr and "character device" in r.stderr, r.stderr
    m = tmp_path / "m.yaml"
    m.write_text("name: t\nextends: /dev/zero\n")
    r = sms_subprocess(tmp_path, "compile", m, timeout=30)
    assert r.returncode == 2 and "m.yaml:2:" in r.stderr and "/dev/zero" in r.stderr and "not a regular file" in r.stderr


def test_fifo_as_mission_and_as_extends_does_not_hang(tmp_path):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    r = sms_subprocess(tmp_path, "compile", fifo, timeout=30)
    assert r.returncode == 2 and "pipe.yaml" in r.stderr and "FIFO" in r.stderr, r.stderr
    m = tmp_path / "m.yaml"
    m.write_text("name: t\nextends: pipe.yaml\n")
    r = sms_subprocess(tmp_path, "compile", m, timeout=30)
    assert r.returncode == 2 and "m.yaml:2:" in r.stderr and "FIFO" in r.stderr, r.stderr


def test_symlink_loop_as_mission_and_as_extends(tmp_path, monkeypatch):
    (tmp_path / "a.yaml").symlink_to(tmp_path / "b.yaml")
    (tmp_path / "b.yaml").symlink_to(tmp_path / "a.yaml")
    r = compile_cli(tmp_path, monkeypatch, tmp_path / "a.yaml")
    assert r.exit_code == 2 and "a.yaml" in r.stderr and "symbolic link loop" in r.stderr, r.stderr
    m = tmp_path / "m.yaml"
    m.write_text("name: t\nextends: a.yaml\n")
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 2, "symbolic link loop", "a.yaml")


def test_file_over_the_size_limit_is_not_read(tmp_path, monkeypatch):
    big = tmp_path / "big.yaml"
    with open(big, "wb") as f:  # sparse: 17 MiB on paper, nothing on disk
        f.truncate(17 * 2**20)
    r = compile_cli(tmp_path, monkeypatch, big)
    assert r.exit_code == 2 and "16 MiB" in r.stderr and "big.yaml" in r.stderr, r.stderr


# --------------------------------------------------------------------- item 9: encodings
@pytest.mark.parametrize("encoding", ["utf-16", "utf-8-sig", "utf-16-be"])
def test_mission_with_byte_order_mark_is_accepted(tmp_path, monkeypatch, encoding):
    m = tmp_path / "m.yaml"
    text = f"extends: {CALDERA}\nname: bom é\n"
    m.write_bytes((b"\xfe\xff" if encoding == "utf-16-be" else b"") + text.encode(encoding))
    r = compile_cli(tmp_path, monkeypatch, m)
    assert r.exit_code == 0, r.stderr
    assert "bom é" in r.stdout


def test_undecodable_byte_is_reported_at_line_and_column(tmp_path, monkeypatch):
    m = tmp_path / "m.yaml"
    m.write_bytes(f"extends: {CALDERA}\nname: ab\xc3\x28\n".encode("latin-1"))
    err = assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 2, "UTF-8")
    assert "m.yaml:2:9:" in err and "position" not in err


def test_long_unit_string_is_echoed_clipped_once(tmp_path, monkeypatch):
    m = extending(tmp_path, "initial:\n  joints: {joint_1: '1 " + "x" * 80_000 + "'}\n")
    err = assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 4, "initial.joints.joint_1", "angle")
    assert len(err) < 1000 and len(re.findall(r"x{10,}", err)) == 1 and "…" in err


def test_unit_error_says_the_expected_kind(tmp_path, monkeypatch):
    m = extending(tmp_path, "initial:\n  joints: {joint_1: 3 furlongs}\n")
    err = assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 4, "unknown unit 'furlongs'", "expected an angle")
    assert "deg" in err


# -------------------------------------------------------------------- item 6: semantics
@pytest.mark.parametrize("inertia,words", [("[-6, 6, 6]", ("-6, 6, 6", "negative")),
                                           ("[1, 1, 6]", ("1, 1, 6", "triangle inequality"))])
def test_impossible_payload_inertia_names_the_principal_moments(tmp_path, monkeypatch, inertia, words):
    m = extending(tmp_path, f"payloads:\n  - {{name: p, frame: ee_link, mass: 5, inertia: {inertia}}}\n")
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 4, "payloads.0.inertia", "principal moments", *words)


def test_thin_rod_inertia_is_accepted(tmp_path, monkeypatch):
    m = extending(tmp_path, "payloads:\n  - {name: rod, frame: ee_link, mass: 5, inertia: [1, 1, 0]}\n")
    assert compile_cli(tmp_path, monkeypatch, m).exit_code == 0


DUPLICATES = [
    ("robot: {arm_joints: [joint_1, joint_2, joint_3, joint_1]}\n", 3, "robot.arm_joints.3", "'joint_1' is listed twice"),
    ("wheels:\n  joints:\n    - {joint: joint_1, max_torque: 1, max_speed: 1}\n"
     "    - {joint: joint_1, max_torque: 1, max_speed: 1}\n", 6, "wheels.joints.1.joint", "'joint_1' is listed twice"),
    ("wheels:\n  declared:\n    - {name: x, axis: [0, 0, 1], spin_inertia: 0.02, max_torque: 0.2, max_speed: 6000 rpm}\n"
     "    - {name: x, axis: [0, 1, 0], spin_inertia: 0.02, max_torque: 0.2, max_speed: 6000 rpm}\n",
     6, "wheels.declared.1.name", "wheel 'x' is listed twice"),
    ("payloads:\n  - {name: p, frame: ee_link, mass: 5, inertia: [1, 1, 1]}\n"
     "  - {name: p, frame: ee_link, mass: 5, inertia: [1, 1, 1]}\n", 5, "payloads.1.name", "payload 'p' is listed twice"),
]


@pytest.mark.parametrize("body,line,field,what", DUPLICATES, ids=[d[2] for d in DUPLICATES])
def test_names_listed_twice_are_input_errors(tmp_path, monkeypatch, body, line, field, what):
    m = extending(tmp_path, body)
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, line, field, what)


def test_requirement_min_above_max_is_an_input_error_at_load(tmp_path, monkeypatch):
    m = extending(tmp_path, "requirements:\n  - {name: r, metric: compile.total_mass_kg, min: 5 t, max: 1000}\n")
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 4, "requirements.0.min", "above max")


def test_exponent_without_dot_is_a_number(tmp_path, monkeypatch):
    from sms_cli.mission.yaml_source import load_yaml_text

    data, _ = load_yaml_text("a: 1e2\nb: 1.0e+2\nc: -1e-3\nd: 1E5\ne: 1.0e2\nf: '1e2'\ng: 1e2x\n")
    assert data == {"a": 100.0, "b": 100.0, "c": -1e-3, "d": 1e5, "e": 100.0, "f": "1e2", "g": "1e2x"}
    # through the CLI: YAML 1.1 read `k: 1e2` as a string and the union refused it
    m = extending(tmp_path, "simulation:\n  attitude: {law: smc, k: 1e2, c: 1e-2, mu: 2E1}\n",
                  parent=MISSIONS / "caldera_s2_arm.yaml")
    r = compile_cli(tmp_path, monkeypatch, m)
    assert r.exit_code == 0, r.stderr


SIM_NAMES = [
    ("{jiont_1: 1}", "jiont_1", "no arm joint named 'jiont_1'", "did you mean 'joint_1'?"),
    ("{rw1: 1}", "rw1", "'rw1' is a reaction wheel", "arm joints only"),
]


@pytest.mark.parametrize("joints,needle,what,hint", SIM_NAMES, ids=["unknown joint", "wheel joint"])
def test_waypoint_names_are_checked_at_compile(tmp_path, monkeypatch, joints, needle, what, hint):
    m = extending(tmp_path, "simulation:\n  phases:\n    - name: a\n      duration: 10 s\n"
                            f"      waypoints: [{{at: 5 s, joints: {joints}}}]\n")
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, line_of(m, needle),
                       f"simulation.phases.0.waypoints.0.joints.{needle}", what, hint)


def test_attach_of_unknown_payload_is_checked_at_compile(tmp_path, monkeypatch):
    m = extending(tmp_path, "payloads:\n  - {name: tile, frame: ee_link, mass: 5, inertia: [1, 1, 1]}\n"
                            "simulation:\n  phases:\n    - {name: a, duration: 10 s, attach: [tiel]}\n")
    assert_input_error(compile_cli(tmp_path, monkeypatch, m), m, 7, "simulation.phases.0.attach.0",
                       "no payload named 'tiel'", "did you mean 'tile'?")
