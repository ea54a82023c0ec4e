"""The JSON Schema of mission files (``sms schema``) says what the loader enforces, both ways.

Every shipped mission validates (complete files and files with ``extends:``); a catalogue of
invalid missions is refused by the schema (Draft 2020-12, and draft-07 as yaml-language-server
reads it) and by ``sms compile`` (exit 2, naming the field), and the same field with a valid value
is accepted by both. The unit patterns are generated from the loader's unit table: every unit the
schema lists, the loader reads as that kind. The shipped ``missions/mission.schema.json`` is
``sms schema``'s output, and every shipped mission names it on its first line.
"""

from __future__ import annotations

import copy
import json
import re
import shutil
import subprocess

import pytest
import yaml
from jsonschema import Draft7Validator, Draft202012Validator
from pydantic import ValidationError

from conftest import EXCEPTION_TEXT, MISSIONS, ROOT, run_cli
from sms_cli.errors import InputError
from sms_cli.mission import units
from sms_cli.mission.load import load_mission, mission_json_schema
from sms_cli.mission.schema import Mission

SCHEMA_FILE = MISSIONS / "mission.schema.json"
MODELINE = "# yaml-language-server: $schema=./mission.schema.json"
SHIPPED = sorted(MISSIONS.glob("*.yaml"))
BASE = MISSIONS / "pulsar_simple.yaml"  # robot, wheels, appendages, payload, budget, analysis, simulation, synthesis


@pytest.fixture(scope="module")
def schema():
    return mission_json_schema()


@pytest.fixture(scope="module")
def validators(schema):
    return [Draft202012Validator(schema), Draft7Validator(schema)]


def problems(validators, data) -> list[list[str]]:
    """The schema's complaints about ``data``, per validator (2020-12, draft-07)."""
    return [[f"{e.json_path}: {e.message[:200]}" for e in v.iter_errors(data)] for v in validators]


# ---------------------------------------------------------------------------- the shipped schema
def test_schema_is_a_valid_schema_for_both_drafts(schema):
    Draft202012Validator.check_schema(schema)
    Draft7Validator.check_schema(schema)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"


def test_shipped_schema_file_is_sms_schema_output():
    r = run_cli("schema")
    assert r.exit_code == 0, r.stderr
    assert SCHEMA_FILE.read_text() == r.stdout, (
        "missions/mission.schema.json is stale: run  sms schema --output missions/mission.schema.json")


def test_schema_output_file_equals_stdout(tmp_path):
    r = run_cli("schema", "--output", tmp_path / "s.json")
    assert r.exit_code == 0, r.stderr
    assert (tmp_path / "s.json").read_text() == SCHEMA_FILE.read_text()


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_mission_names_the_schema_on_its_first_line(path):
    first = path.read_text().splitlines()[0]
    assert first == MODELINE
    assert (path.parent / first.split("$schema=", 1)[1]).resolve() == SCHEMA_FILE.resolve()


def test_help_says_which_schema_an_editor_uses():
    r = run_cli("schema", "--help")
    text = " ".join(r.stdout.split())
    assert r.exit_code == 0
    assert "One schema for every mission file, the one an editor should use" in text
    assert "extends:" in text and MODELINE in text


# ---------------------------------------------------------------------------- valid files validate
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_mission_validates(validators, path):
    assert problems(validators, yaml.safe_load(path.read_text())) == [[], []]


@pytest.mark.parametrize("path", [p for p in SHIPPED if "\nextends:" in p.read_text()], ids=lambda p: p.name)
def test_a_file_with_extends_is_partial_and_the_same_without_it_is_complete(validators, path):
    """The keys a file inherits may be missing; without 'extends' the schema asks for them when the loader does."""
    data = yaml.safe_load(path.read_text())
    assert problems(validators, data) == [[], []]
    del data["extends"]
    try:
        Mission.model_validate(data)
        missing = False
    except ValidationError as exc:
        missing = any(e["type"] == "missing" for e in exc.errors())
    for found in problems(validators, data):
        assert any("is a required property" in p for p in found) == missing, found


def test_partial_file_needs_the_keys_its_sections_never_inherit(validators):
    """A partial simulation may leave out 'phases'; a complete one must not."""
    partial = {"extends": "caldera_s1_slew.yaml", "name": "x", "simulation": {"attitude": "from_gains"}}
    assert problems(validators, partial) == [[], []]
    complete = {k: v for k, v in partial.items() if k != "extends"}
    for found in problems(validators, complete):
        assert found == ["$.simulation: 'phases' is a required property"]


def test_partial_file_may_change_one_key_shared_by_several_variants(validators, tmp_path):
    """'inertia' belongs to four attitude laws: in a partial file it may match all of them (anyOf, not oneOf)."""
    data = {"extends": str(MISSIONS / "caldera_s1_slew.yaml"), "name": "x", "simulation": {"attitude": {"inertia": "online"}}}
    assert problems(validators, data) == [[], []]
    attitude = load_mission(write(tmp_path, data)).mission.simulation.attitude
    assert (attitude.law, attitude.inertia) == ("smc", "online")


# ---------------------------------------------------------------------------- invalid files are refused
# (id, where, bad value, good value). where: a key path into pulsar_simple.yaml's data (set there),
# or ("extends", {...}) for a file that extends pulsar_simple.yaml. Each bad value is refused by the
# schema and by sms compile (exit 2, naming the field); the good value is accepted by both.
_WHEEL = {"name": "rwx", "axis": [1, 0, 0], "spin_inertia": "0.02 kg m^2", "max_torque": "0.2 N m",
          "max_speed": "6000 rpm"}
_ARRAY = {"layout": "pyramid", "count": 4, "beta": "54.74 deg", "spin_inertia": 0.02, "max_torque": 0.2,
          "max_speed": "6000 rpm"}
_SIM = {k: v for k, v in yaml.safe_load(BASE.read_text())["simulation"].items() if k != "ndi"}
_PD = {"law": "quaternion_pd", "kp": 0.5, "kd": 5}
MASS = ("payloads", 0, "mass")
MODE = ("appendages", 0, "modes", 0)
CATALOGUE = [
    ("unknown unit", MASS, "0.2 furlong", "0.2 t"),
    ("velocity as a mass", MASS, "150 m/s", "150 kg"),
    ("torque as a force", ("wheels", "joints", 0, "max_torque"), "0.2 N", "0.2 N m"),
    ("mass as a wheel speed", ("wheels", "joints", 0, "max_speed"), "6000 kg", "100 Hz"),
    ("length as a time", ("simulation", "phases", 0, "duration"), "10 m", "10 min"),
    ("unknown unit in a product", ("wheels", "joints", 0, "max_torque"), "0.2 N furlong", "200 mN m"),
    ("negative mass with a unit", MASS, "-150 kg", "150000 g"),
    ("zero mass with a unit", MASS, "0 kg", "0.001 kg"),
    ("negative mass", MASS, -150, 150),
    ("zero mass", MASS, 0, 0.5),
    ("negative frequency with a unit", MODE + ("frequency",), "-0.16 Hz", "0.16 Hz"),
    ("negative frequency", ("simulation", "control_rate"), -10, 10),
    ("negative recording rate", ("simulation", "record_rate"), "-10 Hz", "10 Hz"),
    ("negative wheel torque limit", ("wheels", "joints", 0, "max_torque"), "-0.2 N m", "0.2 N m"),
    ("zero wheel speed limit", ("wheels", "joints", 0, "max_speed"), 0, "100 Hz"),
    ("zero time step", ("simulation", "dt"), "0 s", "10 ms"),
    ("negative optional inertia", ("wheels", "declared"), [{**_WHEEL, "transverse_inertia": "-0.01 kg m^2"}],
     [{**_WHEEL, "transverse_inertia": "0.01 kg m^2"}]),
    ("damping ratio of 1.5", MODE + ("damping",), 1.5, 0.5),
    ("13 wheels in an array", ("wheels", "arrays"), [{**_ARRAY, "count": 13}], [_ARRAY]),
    ("2-element inertia", ("payloads", 0, "inertia"), [6, 6], [6, 6, 6, 0, 0, 0]),
    ("4-element inertia", ("payloads", 0, "inertia"), [6, 6, 6, 0], [6, 6, 6]),
    ("4-element axis", ("wheels", "declared"), [{**_WHEEL, "axis": [1, 0, 0, 0]}], [_WHEEL]),
    ("5 participation factors", MODE + ("participation",), [-6.4, 0, 0, 0, -35], [-6.4, 0, 0, 0, -35, 0]),
    ("2-element attitude", ("initial", "base_attitude"), [0, 0], [0, 0, "10 deg"]),
    ("2-element base velocity", ("initial", "base_linear_velocity"), [0, 1], [0, 1, "0.1 m/s"]),
    ("2-element gyro bias", ("simulation", "sensors"), {"gyro": {"bias": [0, 0]}}, {"gyro": {"bias": [0, 0, 1e-6]}}),
    ("3-element joint range", ("analysis", "sampling", "ranges"), {"arm_joint_1": [-1, 0, 1]}, {"arm_joint_1": [-1, 1]}),
    ("a law without one of its gains", ("simulation",), {**_SIM, "attitude": {"law": "quaternion_pd", "kp": 0.5}},
     {**_SIM, "attitude": _PD}),
    ("gains without their law", ("simulation",), {**_SIM, "attitude": {"kp": 0.5, "kd": 5}}, {**_SIM, "attitude": _PD}),
    ("unknown key", ("payloads", 0, "masss"), 150, None),
    ("unknown top-level key", ("simulaton",), {"dt": 0.01}, None),
    ("missing required key", ("name",), None, "pulsar"),
    ("text where a flag goes", ("payloads", 0, "attached"), "sometimes", False),
    ("flag where a mass goes", MASS, True, 150),
    ("list where a name goes", ("name",), ["a", "b"], "pulsar"),
    ("bad enum: ordering", ("appendages", 0, "ordering"), "XY", "RT"),
    ("bad enum: base mode", ("simulation", "phases", 0, "base_mode"), "floating", "free-floating"),
    ("quantity string over 200 characters", MASS, "150" + " " * 250 + "kg", "1.5e2 kg"),
    ("partial file: unknown unit", ("extends", {"simulation": {"dt": "0.01 furlong"}}), None, {"simulation": {"dt": "10 ms"}}),
    ("partial file: list items are complete", ("extends", {"payloads": [{"name": "box", "frame": "Spacecraft", "mass": 10}]}),
     None, {"payloads": [{"name": "box", "frame": "Spacecraft", "mass": 10, "inertia": [1, 1, 1]}]}),
]
DELETE = object()


def _set(data: dict, where: tuple, value) -> None:
    node = data
    for key in where[:-1]:
        node = node[key]
    if value is DELETE:
        node.pop(where[-1], None)
    else:
        node[where[-1]] = value


def variant(where: tuple, value) -> dict:
    """pulsar_simple.yaml's data with ``value`` at ``where`` (None: the key removed), or a file extending it."""
    if where[0] == "extends":
        return {"extends": str(BASE), "name": "variant", **(where[1] if value is None else value)}
    data = yaml.safe_load(BASE.read_text())
    data["robot"]["urdf"] = str((BASE.parent / data["robot"]["urdf"]).resolve())
    _set(data, where, DELETE if value is None else value)
    return data


def write(tmp_path, data: dict, name: str = "variant.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True))
    return p


def _bad_path(where: tuple) -> tuple:
    """The key path of the value a catalogue case breaks."""
    return where if where[0] != "extends" else next(_paths(where[1]))


def _paths(tree, at=()):
    if isinstance(tree, dict) and tree:
        for k, v in tree.items():
            yield from _paths(v, at + (k,))
    else:
        yield at


def _json_path(keys: tuple) -> str:
    return "$" + "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in keys)


def test_catalogue_covers_at_least_15_kinds_of_error():
    assert len(CATALOGUE) >= 15


@pytest.mark.parametrize("case, where, bad, good", CATALOGUE, ids=[c[0] for c in CATALOGUE])
def test_invalid_mission_is_refused_by_the_schema_and_by_sms_compile(validators, tmp_path, case, where, bad, good):
    data = variant(where, bad)
    found = problems(validators, data)
    assert found[0] and found[1], f"the schema accepts {case}"
    assert len(found[0]) == 1, f"reported more than once: {found[0]}"
    at, field = found[0][0].split(": ", 1)[0], _json_path(_bad_path(where))
    assert field.startswith(at) or at.startswith(field), (at, field)  # the field itself or its mapping (a key)
    r = run_cli("compile", write(tmp_path, data))
    assert r.exit_code == 2, r.stdout + r.stderr
    assert not EXCEPTION_TEXT.search(r.stderr)
    assert ".".join(map(str, _bad_path(where)[:2])) in r.stderr, r.stderr


@pytest.mark.parametrize("case, where, bad, good", CATALOGUE, ids=[c[0] for c in CATALOGUE])
def test_the_same_field_with_a_valid_value_is_accepted_by_both(validators, tmp_path, case, where, bad, good):
    data = variant(where, good)
    assert problems(validators, data) == [[], []]
    load_mission(write(tmp_path, data))  # raises InputError if the loader refuses it


# ---------------------------------------------------------------------------- the unit patterns
KINDS = sorted(units.DIMENSIONS)


def _spellings(kind: str) -> list[str]:
    """Every unit product the schema lists for ``kind``, once with each token of its classes."""
    most = max(len(t) for t in units._unit_classes().values())
    return sorted({units.spell(p, pick) for p in units.unit_products(kind) for pick in range(most)})


ALL_SPELLINGS = sorted({s for k in KINDS for s in _spellings(k)} | {
    "furlong", "N furlong", "m m/m", "kg deg", "m N", "rad", "deg", "Hz", "rev/s", "N m/rad", "N m s", "1/s", "s^-1"})


@pytest.mark.parametrize("kind", KINDS)
def test_every_unit_the_schema_lists_the_loader_reads_as_that_kind(kind):
    pattern = re.compile(units.quantity_pattern(kind))
    for spelled in _spellings(kind):
        for text in (f"2.5 {spelled}", f"+1e-3{spelled}", f" 7 {spelled.replace(' ', '*')} "):
            assert pattern.search(text), (kind, text)
            units.to_si(text, kind)  # raises UnitError if the loader does not read it


@pytest.mark.parametrize("kind", KINDS)
def test_what_the_pattern_accepts_the_loader_accepts(kind):
    """Soundness over every unit of every kind (and a few the schema leaves out on purpose)."""
    pattern = re.compile(units.quantity_pattern(kind))
    for spelled in ALL_SPELLINGS:
        text = f"3 {spelled}"
        if pattern.search(text):
            units.to_si(text, kind)
        else:
            try:
                units.to_si(text, kind)
            except units.UnitError:
                pass  # both refuse


def test_usual_spellings_are_in_the_patterns():
    usual = {
        "mass": ["150 kg", "150kg", "1.5 t", "20 g", "1e2"], "length": ["35786 km", "5 mm"],
        "angle": ["57.6 deg", "90 °", "1 rev", "10 arcsec"], "time": ["10 min", "2 days", "1 yr"],
        "angular rate": ["2800 rpm", "0.16 Hz", "3 deg/s", "1 1/s", "0.5 rad s^-1"],
        "frequency": ["0.16 Hz", "10 Hz", "1 1/s"], "velocity": ["7.8 km/s", "50 m/s", "3 km/h"],
        "acceleration": ["9.81 m/s^2", "9.81 m s^-2"], "force": ["0.5 N", "224 mN", "1 kN"],
        "torque": ["0.2 N m", "0.2 N*m", "0.2 N·m", "0.2 N.m", "0.2 Nm", "20 mN m", "1 J"],
        "angular momentum": ["50 N m s", "50 N*m*s", "50 Nms", "1 kg m^2/s"],
        "inertia": ["4e-4 kg m^2", "4e-4 kg*m2", "10 g cm^2"],
        "rotational stiffness": ["20 N m/rad", "120 N m/deg", "20 N m"],
        "rotational damping": ["0.1 N m s/rad", "2 N m s"], "linear stiffness": ["100 N/m"],
        "gravitational parameter": ["398600.4418 km^3/s^2", "3.986e14 m^3 s^-2"],
        "power": ["100 W", "1 J/s"], "angular acceleration": ["0.01 rad/s^2", "1 rpm/s", "1 deg/s^2"],
    }
    for kind, texts in usual.items():
        pattern = re.compile(units.quantity_pattern(kind))
        for text in texts:
            assert pattern.search(text), (kind, text)
            units.to_si(text, kind)


@pytest.mark.parametrize("kind, text", [("mass", "5 kg deg"), ("dimensionless", "0.05 rad"), ("length", "1 m m/m"),
                                        ("torque", "1 m N"), ("angular momentum", "1 kg m^2 rpm")])
def test_the_schema_leaves_out_what_the_loader_reads_only_by_its_algebra(kind, text):
    """An angle where the kind has none (the loader counts cycles: "5 kg deg" is 5/360 kg), factors
    that cancel, factors in another order: the loader reads them, the schema flags them in the editor."""
    units.to_si(text, kind)
    assert not re.search(units.quantity_pattern(kind), text)


def test_sign_patterns_agree_with_the_numbers(schema):
    positive = next(b["allOf"][1]["pattern"] for b in schema["$defs"]["PayloadSpec"]["properties"]["mass"]["anyOf"]
                    if "allOf" in b)
    non_negative = next(b["allOf"][1]["pattern"] for b in schema["$defs"]["Mode"]["properties"]["damping"]["anyOf"]
                        if "allOf" in b)
    for text in ["0", "0.0", "-0", "00.000e5", ".0", "0.", "1", "0.5", ".5", "5.", "1e-3", "+2", "-1", "-0.5", "-.1",
                 "10", "0.01", "01", "-0e3"]:
        value = float(text)
        assert bool(re.search(positive, text + " kg")) == (value > 0), text
        assert bool(re.search(non_negative, text + " kg")) == (value >= 0), text


_NODE = shutil.which("node")


@pytest.mark.skipif(_NODE is None, reason="node is not installed: the patterns are checked with Python's re only")
def test_patterns_mean_the_same_in_javascript(schema):
    """Editors run the patterns as ECMA-262 regular expressions with the u flag (yaml-language-server)."""
    patterns = sorted({n["pattern"] for n in _all_nodes(schema) if "pattern" in n})
    samples = sorted(set(ALL_SPELLINGS) | {"150 kg", "-150 kg", "0 kg", "0.2 furlong", "1e2", " 3 N*m ", "2 m^2",
                                           "0.16 Hz", "5 °", "x"})
    texts = [f"{n} {s}" for s in samples for n in ("1", "-0.0", "2.5e3")] + samples
    script = ("const [ps, ts] = JSON.parse(require('fs').readFileSync(0, 'utf8'));"
              "console.log(JSON.stringify(ps.map(p => { const r = new RegExp(p, 'u'); return ts.map(t => r.test(t)); })));")
    out = subprocess.run([_NODE, "-e", script], input=json.dumps([patterns, texts]), capture_output=True, text=True,
                         timeout=60, check=True)
    js = json.loads(out.stdout)
    py = [[bool(re.search(p, t)) for t in texts] for p in patterns]
    assert js == py


def _all_nodes(node):
    if isinstance(node, dict):
        yield node
        for v in node.values():
            yield from _all_nodes(v)
    elif isinstance(node, list):
        for v in node:
            yield from _all_nodes(v)


def test_every_quantity_field_names_a_unit_pattern_and_no_pydantic_keywords_leak(schema):
    texts = [n for n in _all_nodes(schema) if n.get("type") == "string" and "pattern" in n]
    assert all(n["pattern"] != r"^\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*.*$" for n in texts)
    keywords = {k for n in _all_nodes(schema) for k in n}
    assert not keywords & {"gt", "ge", "lt", "le"}


def test_bounds_a_string_cannot_show_are_said_in_the_description(schema):
    damping = schema["$defs"]["Mode"]["properties"]["damping"]
    assert "must be ≥ 0 and < 1" in damping["description"] and "sms checks the bound" in damping["description"]
    mass = schema["$defs"]["PayloadSpec"]["properties"]["mass"]
    assert mass["description"].endswith("must be > 0")


def test_loader_refuses_what_the_schema_refuses_for_a_bare_string_number(tmp_path):
    """A number written as a string ("1e2") is SI for both."""
    data = variant(MASS, "1e2")
    assert load_mission(write(tmp_path, data)).mission.payloads[0].mass == 100.0
    with pytest.raises(InputError):
        load_mission(write(tmp_path, variant(MASS, "-1e2")))


def test_schema_file_is_in_the_repository():
    assert SCHEMA_FILE.is_file() and SCHEMA_FILE.parent == ROOT / "missions"
