"""``robot.links`` (mission) against an oracle that does not use it: a URDF edited with lxml.

A mission on the shipped URDF with ``robot.links`` and a mission on a copy of the URDF whose
``<inertial>`` carries the same values give one system: total mass, CoM and mass matrix. Links
merged by fixed joints into their parent body are among the overridden ones (astrobee's fixed jaw,
pulsar's panel behind a rotated fixed joint, a small robot's rotated inertial frame)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from lxml import etree

from conftest import EXCEPTION_TEXT, ROOT, assert_clean, compile_path, run_cli
from sms_cli.inertia import inertia_tensor

SMALL_URDF = """<?xml version="1.0"?>
<robot name="small">
  <link name="base"><inertial><mass value="50"/><inertia ixx="4" iyy="5" izz="6" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0.3 0.1 0.5" rpy="0.2 0.4 -0.3"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <link name="arm"><inertial><origin xyz="0.2 0.01 -0.03" rpy="0.3 -0.2 0.5"/><mass value="2"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.025" ixy="0.001" ixz="-0.002" iyz="0.0015"/></inertial></link>
  <joint name="tool_joint" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0.4 -0.05 0.02" rpy="1.1 -0.4 0.7"/></joint>
  <link name="tool"><inertial><origin xyz="0.05 0 0" rpy="0.4 0.1 0"/><mass value="0.5"/>
    <inertia ixx="0.001" iyy="0.002" izz="0.0022" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j2" type="revolute"><parent link="tool"/><child link="hand"/><origin xyz="0.1 0 0" rpy="0 0.5 0"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <link name="hand"><inertial><origin xyz="0.03 0 0.01"/><mass value="0.3"/>
    <inertia ixx="0.0005" iyy="0.0006" izz="0.0007" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>
"""

# Every product of inertia distinct and non-zero: a swapped pair changes the result.
CASES = {
    "astrobee": ("robots/astrobee_arm.urdf", {
        "fixed_jaw": {"mass": 0.2, "com": [0.01, 0.02, -0.03], "inertia": [1e-4, 2e-4, 2.5e-4, 1e-5, -2e-5, 3e-5]},
        "distal_link": {"mass": 0.3, "inertia": [2e-4, 3e-4, 2.2e-4, -1.5e-5, 2.5e-5, 1e-5]},
        "proximal_link": {"mass": 0.25},
        "base_link": {"com": [0.004, -0.002, 0.003]},
        "gripper_center": {"mass": 0.05, "com": [0.01, 0, 0], "inertia": [1e-5, 1.2e-5, 1.4e-5, 1e-6, 2e-6, -3e-6]},
    }),
    "pulsar": ("robots/pulsar_simple.urdf", {
        "Left_Panel": {"mass": 70.0, "com": [0.02, -0.01, 3.5], "inertia": [250, 240, 12, 3, -4, 5]},
        "RW1": {"inertia": [0.08, 0.09, 0.15, 0.002, -0.003, 0.004]},
        "Payload": {"com": [1.3, 0.05, -0.02]},
    }),
    "small": (None, {
        "arm": {"mass": 2.5},
        "tool": {"com": [0.06, 0.01, -0.02], "inertia": [0.0012, 0.0021, 0.0025, 1e-4, -2e-4, 3e-4]},
        "hand": {"mass": 0.35, "com": [0.02, 0.01, 0.0]},
    }),
}


def urdf_text(case: str) -> str:
    path = CASES[case][0]
    return SMALL_URDF if path is None else (ROOT / path).read_text()


def edited_urdf(text: str, links: dict) -> str:
    """The oracle: ``text`` with each link's <inertial> edited by lxml (created if absent). A given
    inertia is in the link axes: the inertial origin's rpy becomes 0."""
    root = etree.fromstring(text.encode())
    for name, values in links.items():
        link = root.find(f"link[@name='{name}']")
        inertial = link.find("inertial")
        if inertial is None:
            inertial = etree.SubElement(link, "inertial")
            etree.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
            etree.SubElement(inertial, "mass", value="0")
            etree.SubElement(inertial, "inertia", **{k: "0" for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")})
        origin = inertial.find("origin")
        if origin is None:
            origin = etree.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
        if "mass" in values:
            inertial.find("mass").set("value", repr(values["mass"]))
        if "com" in values:
            origin.set("xyz", " ".join(repr(float(x)) for x in values["com"]))
        if "inertia" in values:
            origin.set("rpy", "0 0 0")
            for key, x in zip(("ixx", "iyy", "izz", "ixy", "ixz", "iyz"), values["inertia"]):
                inertial.find("inertia").set(key, repr(float(x)))
    return etree.tostring(root, encoding="unicode")


def mission(tmp_path: Path, name: str, urdf: str, links: dict | None = None) -> Path:
    d = tmp_path / name
    d.mkdir()
    (d / "r.urdf").write_text(urdf)
    robot = {"urdf": "r.urdf", **({"links": links} if links else {})}
    (d / "m.yaml").write_text(f"name: {name}\nrobot: {json.dumps(robot)}\n")
    return d / "m.yaml"


def mass_matrix(sm, q) -> np.ndarray:
    M = pin.crba(sm.model, sm.model.createData(), q)
    return np.triu(M) + np.triu(M, 1).T


def close(a, b, rtol=1e-12) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max()) <= rtol * max(1.0, float(np.abs(b).max()))


@pytest.mark.parametrize("case", sorted(CASES))
def test_overrides_give_the_system_of_the_edited_urdf(tmp_path, case):
    links = CASES[case][1]
    text = urdf_text(case)
    oracle = compile_path(mission(tmp_path, "edited", edited_urdf(text, links)))
    sm = compile_path(mission(tmp_path, "override", text, links))
    original = compile_path(mission(tmp_path, "original", text))
    q0 = sm.q0
    q1 = pin.integrate(sm.model, q0, np.random.default_rng(3).uniform(-0.7, 0.7, sm.nv))
    assert not close(mass_matrix(original, q0), mass_matrix(oracle, q0), 1e-6)  # the edit is visible
    assert close(sm.total_mass, oracle.total_mass)
    for q in (q0, q1):
        assert close(sm.com(q), oracle.com(q))
        assert close(mass_matrix(sm, q), mass_matrix(oracle, q))


@pytest.mark.parametrize("case", sorted(CASES))
def test_link_inertial_reads_back_the_overrides(tmp_path, case):
    links = CASES[case][1]
    text = urdf_text(case)
    sm = compile_path(mission(tmp_path, "override", text, links))
    original = compile_path(mission(tmp_path, "original", text))
    for name, values in links.items():
        mass, com, inertia6 = sm.link_inertial(name)
        m0, c0, i0 = original.link_inertial(name)
        assert com.shape == (3,) and inertia6.shape == (6,)
        assert close(mass, values.get("mass", m0))
        assert close(com, values.get("com", c0))
        assert close(inertia6, values.get("inertia", i0))


def test_link_inertial_without_overrides_is_the_urdf(tmp_path):
    sm = compile_path(mission(tmp_path, "plain", urdf_text("astrobee")))
    mass, com, inertia6 = sm.link_inertial("fixed_jaw")
    assert (mass, com.tolist(), inertia6.tolist()) == (0.06285, [0.025, 0, 0], [5.857e-06, 1.6472e-05, 1.5571e-05, 0, 0, 0])
    assert sm.link_inertial("gripper_center")[0] == 0.0


@pytest.mark.parametrize("case", sorted(CASES))
def test_link_inertials_add_up_to_the_model_bodies(tmp_path, case):
    """What link_inertial reports is what the bodies hold: each joint's inertia is the sum of its links'."""
    sm = compile_path(mission(tmp_path, "override", urdf_text(case), CASES[case][1]))
    total = [np.zeros(10) for _ in range(sm.model.njoints)]
    for name, fid in sm.link_frames.items():
        frame = sm.model.frames[fid]
        mass, com, inertia6 = sm.link_inertial(name)
        Y = frame.placement.act(pin.Inertia(mass, com, inertia_tensor(*inertia6)))
        total[frame.parentJoint] += Y.toDynamicParameters()
    for j in range(1, sm.model.njoints):
        assert close(total[j], sm.model.inertias[j].toDynamicParameters()), sm.model.names[j]


def bad_mission(tmp_path: Path, links_yaml: str) -> Path:
    (tmp_path / "m.yaml").write_text(f"name: t\nrobot:\n  urdf: {ROOT / 'robots/astrobee_arm.urdf'}\n  links:\n{links_yaml}")
    return tmp_path / "m.yaml"


def test_unknown_link_is_refused_at_its_key_with_a_suggestion(tmp_path):
    path = bad_mission(tmp_path, "    distal_link: {mass: 0.2}\n    fixed_jow: {mass: 0.2}\n")
    assert_clean(run_cli("compile", path), 2, f"{path}:6:", "no link named 'fixed_jow'", "did you mean 'fixed_jaw'?")


def test_massless_link_needs_a_mass_for_com_or_inertia(tmp_path):
    path = bad_mission(tmp_path, "    gripper_center: {com: [0, 0, 0.1]}\n")
    assert_clean(run_cli("compile", path), 2, f"{path}:5:", "gripper_center", "mass")


@pytest.mark.parametrize("links_yaml, texts", [
    ("    fixed_jaw: {mass: -0.1}\n", ("robot.links.fixed_jaw.mass", "greater than 0")),
    ("    fixed_jaw: {mass: 0}\n", ("robot.links.fixed_jaw.mass", "greater than 0")),
    ("    fixed_jaw:\n      inertia: [1e-4, 1e-4, 3e-4]\n", ("robot.links.fixed_jaw.inertia", "triangle inequality")),
    ("    fixed_jaw:\n      inertia: [1e-4, 2e-4, 2e-4, 3e-4, 0, 0]\n", ("robot.links.fixed_jaw.inertia", "cannot be negative")),
])
def test_non_physical_values_are_refused(tmp_path, links_yaml, texts):
    path = bad_mission(tmp_path, links_yaml)
    line = 6 if "inertia" in links_yaml else 5
    assert_clean(run_cli("compile", path), 2, f"{path}:{line}:", *texts)


def test_errors_through_the_installed_command(tmp_path):
    path = bad_mission(tmp_path, "    fixed_jow: {mass: 0.2}\n")
    sms = Path(sys.executable).parent / "sms"
    r = subprocess.run([str(sms), "compile", str(path)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"{path}:5:" in r.stderr and "did you mean 'fixed_jaw'?" in r.stderr, r.stderr
    assert not EXCEPTION_TEXT.search(r.stderr), r.stderr


def test_a_link_with_round_off_negative_moments_takes_a_mass_override(tmp_path):
    """The URDF lint accepts a moment negative by round-off; overriding that link's mass keeps it."""
    text = edited_urdf(SMALL_URDF, {"hand": {"inertia": [5e-4, 5e-4, -1e-12, 0, 0, 0]}})
    links = {"hand": {"mass": 0.4}}
    oracle = compile_path(mission(tmp_path, "edited", edited_urdf(text, links)))
    sm = compile_path(mission(tmp_path, "override", text, links))
    assert close(mass_matrix(sm, sm.q0), mass_matrix(oracle, oracle.q0))
    assert close(sm.link_inertial("hand")[2], [5e-4, 5e-4, -1e-12, 0, 0, 0])


def test_the_stored_urdf_is_the_robot_the_overrides_made():
    """Recordings store SystemModel.urdf_text: parsed by Pinocchio alone (no mission, no overrides) it
    gives the mass matrix of the model built with robot.links."""
    import pinocchio as pin

    from sms_cli.mission.load import load_mission_text
    from sms_cli.model import compile_system

    mission = ROOT / "missions" / "astrobee_arm.yaml"
    text = (f"extends: {mission}\nrobot:\n  links:\n    distal_link: {{mass: 0.3, com: [0.01, 0.02, -0.03], "
            "inertia: [0.002, 0.003, 0.004, 0.0001, -0.0002, 0.00005]}\n    base_link: {mass: 12.5}\n")
    sm = compile_system(load_mission_text(text, base_dir=mission.parent))
    plain = pin.buildModelFromXML(sm.urdf_text, pin.JointModelFreeFlyer())
    q = pin.neutral(plain)
    for jid in range(2, plain.njoints):  # the same joint angles in both models
        q[plain.joints[jid].idx_q] = 0.3 * jid
    qs = sm.q0.copy()
    for jid in range(2, sm.model.njoints):
        name = sm.model.names[jid]
        qs[sm.model.joints[jid].idx_q] = q[plain.joints[plain.getJointId(name)].idx_q]
    M_plain = pin.crba(plain, plain.createData(), q)
    M_sm = pin.crba(sm.model, sm.model.createData(), qs)
    assert np.max(np.abs(M_plain - M_sm)) <= 1e-12 * np.max(np.abs(M_sm))
