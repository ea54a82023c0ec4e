"""Mission loading: line-numbered errors, suggestions, duplicate keys, units, schema."""

import json
from pathlib import Path

import pytest

from conftest import DATA, run_cli
from sms_cli.errors import InputError
from sms_cli.mission.load import load_mission

GOOD = (DATA / "arm3.yaml").read_text()


def write(tmp_path: Path, text: str) -> Path:
    (tmp_path / "arm3.urdf").write_text((DATA / "arm3.urdf").read_text())
    p = tmp_path / "m.yaml"
    p.write_text(text)
    return p


def test_good_mission_loads_with_units():
    m = load_mission(DATA / "arm3.yaml").mission
    arr = m.wheels.arrays[0]
    assert arr.max_speed == pytest.approx(6000 * 2 * 3.141592653589793 / 60)
    assert arr.beta == pytest.approx(1.0053096491487339)
    assert m.appendages[0].modes[0].frequency == pytest.approx(0.5 * 2 * 3.141592653589793)


def test_unknown_key_names_line_column_and_suggests(tmp_path):
    p = write(tmp_path, GOOD.replace("max_torque: 0.2 N m", "max_torqe: 0.2 N m"))
    with pytest.raises(InputError) as e:
        load_mission(p)
    text = e.value.render()
    line = next(i for i, l in enumerate(p.read_text().splitlines(), 1) if "max_torqe" in l)
    assert f"m.yaml:{line}:7" in text
    assert "did you mean 'max_torque'" in text
    assert "wheels.arrays.0.max_torqe" in text


def test_duplicate_key_rejected(tmp_path):
    p = write(tmp_path, GOOD + "name: again\n")
    with pytest.raises(InputError) as e:
        load_mission(p)
    assert "duplicate key 'name'" in e.value.render()
    assert "first defined at line 1" in e.value.render()


def test_a_path_with_a_nul_escape_is_refused_at_its_line_with_exit_2(tmp_path):
    """A "\\0" escape in a file path (a fuzzer's find: it crashed path resolution with exit 4);
    names may hold one (test_cli_conventions: the JUnit report escapes it)."""
    p = write(tmp_path, GOOD.replace("urdf: arm3.urdf", 'urdf: "arm\\0.urdf"'))
    assert 'urdf: "arm\\0.urdf"' in p.read_text()
    r = run_cli("compile", p)
    n = next(i for i, l in enumerate(p.read_text().splitlines(), 1) if "arm\\0" in l)
    assert r.exit_code == 2, r.output
    assert f"m.yaml:{n}:" in r.output and "NUL character" in r.output and "Error" not in r.output
    p.write_text('extends: "arm\\0.yaml"\nname: x\n')
    r = run_cli("compile", p)
    assert r.exit_code == 2 and "m.yaml:1:" in r.output and "NUL character" in r.output, r.output


def test_yaml_syntax_error_has_position(tmp_path):
    p = write(tmp_path, "name: x\nrobot: [unclosed\n")
    with pytest.raises(InputError) as e:
        load_mission(p)
    assert "YAML syntax error" in e.value.render() and "m.yaml:" in e.value.render()


def test_wrong_unit_dimension(tmp_path):
    p = write(tmp_path, GOOD.replace("max_speed: 6000 rpm", "max_speed: 6000 kg"))
    with pytest.raises(InputError) as e:
        load_mission(p)
    assert "is not a angular rate" in e.value.render() or "angular rate" in e.value.render()


def test_missing_required_key(tmp_path):
    p = write(tmp_path, GOOD.replace("name: arm3 test\n", ""))
    with pytest.raises(InputError) as e:
        load_mission(p)
    assert "required key is missing" in e.value.render() and "name" in e.value.render()


def test_relative_paths_from_mission_file():
    loaded = load_mission(DATA / "arm3.yaml")
    assert loaded.resolve(loaded.mission.robot.urdf) == (DATA / "arm3.urdf").resolve()


def test_schema_command_prints_json_schema():
    r = run_cli("schema")
    assert r.exit_code == 0
    schema = json.loads(r.stdout)
    assert schema["title"] == "sms mission file"
    assert "robot" in schema["properties"] and schema["additionalProperties"] is False


def test_bad_key_through_cli_exit_2(tmp_path):
    p = write(tmp_path, GOOD.replace("end_effector: ee", "end_efector: ee"))
    r = run_cli("compile", p)
    assert r.exit_code == 2
    assert "did you mean 'end_effector'" in r.stderr
    assert "Traceback" not in r.stderr + r.stdout


def test_extends_merges_and_locates_errors_in_the_right_file(tmp_path):
    sub = tmp_path / "variants"
    sub.mkdir()
    (tmp_path / "arm3.urdf").write_text((DATA / "arm3.urdf").read_text())
    (tmp_path / "base.yaml").write_text(GOOD)
    (sub / "child.yaml").write_text("extends: ../base.yaml\nname: child\ninitial:\n  joints: {j1: 0.9}\n")
    m = load_mission(sub / "child.yaml")
    assert m.mission.name == "child"
    assert m.mission.initial.joints["j1"] == 0.9  # mappings merge key by key
    assert "j2" in m.mission.initial.joints
    assert m.resolve(m.mission.robot.urdf, ("robot", "urdf")) == (tmp_path / "arm3.urdf").resolve()  # parent's folder
    (tmp_path / "base.yaml").write_text(GOOD.replace("max_torque: 0.2 N m", "max_torqe: 0.2 N m"))
    with pytest.raises(InputError) as e:
        load_mission(sub / "child.yaml")
    assert "base.yaml:" in e.value.render() and "did you mean 'max_torque'" in e.value.render()


def test_extends_cycle_is_an_error(tmp_path):
    (tmp_path / "a.yaml").write_text("extends: b.yaml\nname: a\n")
    (tmp_path / "b.yaml").write_text("extends: a.yaml\nname: b\n")
    with pytest.raises(InputError) as e:
        load_mission(tmp_path / "a.yaml")
    assert "cycle" in e.value.render()
