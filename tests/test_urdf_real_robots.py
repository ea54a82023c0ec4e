"""Robot descriptions as engineers have them: each pattern found in public URDF corpora (frame links
without mass, point masses, CAD rounding, name clashes, visual-only moving links), written here,
compiles with a warning at its URDF line or is refused with a message that names the link.

The oracle for "usable" is Pinocchio alone: it loads the same text and its mass matrix is positive
definite. A property test holds sms to it over generated trees.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import EXCEPTION_TEXT, run_cli

EXCEPTION_NAMES = EXCEPTION_TEXT


# ---------------------------------------------------------------- URDF text builders
def inertial(mass: float, moments=(0.1, 0.1, 0.1, 0.0, 0.0, 0.0), com=(0.0, 0.0, 0.0)) -> str:
    ixx, iyy, izz, ixy, ixz, iyz = moments
    return (f'<inertial><origin xyz="{com[0]} {com[1]} {com[2]}"/><mass value="{mass}"/>'
            f'<inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="{ixy}" ixz="{ixz}" iyz="{iyz}"/></inertial>')


def link(name: str, body: str = "") -> str:
    return f'<link name="{name}">{body}</link>' if body else f'<link name="{name}"/>'


def joint(name: str, kind: str, parent: str, child: str, xyz=(0.0, 0.0, 0.25), axis="0 0 1") -> str:
    lim = '<limit lower="-3" upper="3" effort="10" velocity="1"/>' if kind in ("revolute", "prismatic") else ""
    ax = f'<axis xyz="{axis}"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="0 0 0"/>{ax}{lim}</joint>')


def robot(*parts: str) -> str:
    return '<?xml version="1.0"?>\n<robot name="peer">\n' + "\n".join(parts) + "\n</robot>\n"


def sc3(*extra: str, l3: str | None = None) -> str:
    """A SPART-like free-floating spacecraft: 100 kg base, three 5 kg links, then ``extra``."""
    l3 = inertial(5, (0.05, 0.05, 0.05, 0, 0, 0), (0, 0, 0.1)) if l3 is None else l3
    return robot(
        link("base", inertial(100, (9.3, 9.3, 9.3, 0, 0, 0))),
        joint("j1", "revolute", "base", "l1", (0, 0, 0.4)),
        link("l1", inertial(5, (0.05, 0.05, 0.05, 0, 0, 0), (0, 0, 0.1))),
        joint("j2", "revolute", "l1", "l2", (0, 0, 0.2), "0 1 0"),
        link("l2", inertial(5, (0.05, 0.05, 0.05, 0, 0, 0), (0, 0, 0.1))),
        joint("j3", "revolute", "l2", "l3", (0, 0, 0.2), "0 1 0"),
        link("l3", l3),
        *extra)


def compile_text(tmp_path: Path, urdf: str, *args: str, mission_extra: str = ""):
    (tmp_path / "robot.urdf").write_text(urdf)
    (tmp_path / "m.yaml").write_text(f"name: peer\nrobot: {{urdf: robot.urdf}}\n{mission_extra}")
    return run_cli("compile", tmp_path / "m.yaml", *args)


def line_of(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


def named(name: str) -> str:
    """The text that starts the element with this name attribute."""
    return f'name="{name}"'


def clean(result) -> None:
    """No traceback and no Python exception name reaches the user."""
    assert not EXCEPTION_NAMES.search(result.output), result.output


# ---------------------------------------------------------------- accepted with a warning
TOOL0 = (joint("tool_joint", "fixed", "l3", "tool0", (0, 0, 0.2)), link("tool0", inertial(0.0, (0, 0, 0, 0, 0, 0))))


def test_zero_mass_fixed_frame_link_is_merged_with_a_warning(tmp_path):
    urdf = sc3(*TOOL0, joint("ee_joint", "fixed", "tool0", "ee_link", (0, 0, 0.05)), link("ee_link"))
    r = compile_text(tmp_path, urdf, "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["total_mass_kg"] == pytest.approx(115.0, rel=1e-12)
    assert s["end_effector"] == "ee_link"
    w = next(w for w in s["warnings"] if "massless" in w)
    assert f"robot.urdf:{line_of(urdf, named('tool0'))}" in w and "link 'tool0'" in w


def test_point_mass_on_a_fixed_link_counts_its_mass(tmp_path):
    urdf = sc3(joint("imu_joint", "fixed", "base", "imu", (0.1, 0, 0)), link("imu", inertial(0.5, (0, 0, 0, 0, 0, 0))))
    r = compile_text(tmp_path, urdf, "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["total_mass_kg"] == pytest.approx(115.5, rel=1e-12)
    assert any("point masses" in w and "link 'imu' (0.5 kg)" in w for w in s["warnings"])


@pytest.mark.parametrize("moments, expect", [
    ((7.86e-5, 1.47e-4, 2.32e-4, 0, 0, 0), "by rounding"),  # CAD rounding: a + b < c by 2.5 % of c
    ((-2e-22, 3e-6, 3e-6, 0, 0, 0), "by rounding"),  # a round-off negative moment
    ((0.001, 0.001, 0.01, 0, 0, 0), "violate the triangle inequality by 80 %"),
    ((1.0, 1.0, 1.0, 0.4, 0.4, 0.4), "sign-flipped"),  # flipping ixy ixz iyz gives moments 0.2, 1.4, 1.4
    ((-3.5e-8, 3.5e-8, 9.1e-8, 0, 0, 0), "a negative principal moment"),
])
def test_off_triangle_and_negative_inertias_are_accepted_with_the_cause(tmp_path, moments, expect):
    urdf = sc3(joint("grip_joint", "fixed", "l3", "grip", (0, 0, 0.2)), link("grip", inertial(0.2, moments)))
    r = compile_text(tmp_path, urdf)
    assert r.exit_code == 0, r.output
    assert expect in r.stdout
    assert f"robot.urdf:{line_of(urdf, named('grip'))}" in r.stdout
    clean(r)


def test_sign_flip_hint_is_true(tmp_path):
    """The hint's claim, checked independently: the flipped tensor has physical principal moments."""
    T = np.array([[1.0, 0.4, 0.4], [0.4, 1.0, 0.4], [0.4, 0.4, 1.0]])
    a, b, c = np.linalg.eigvalsh(T)
    assert a + b < c  # as written: not physical
    a, b, c = np.linalg.eigvalsh(T * (2 * np.eye(3) - 1))
    assert a >= 0 and a + b >= c - 1e-12


def test_joint_named_like_a_link_resolves_to_the_link(tmp_path):
    """Baxter-like files name a joint and a link alike; frames are looked up links first."""
    urdf = sc3(joint("l3_tip", "fixed", "l3", "l3_tip_link", (0, 0, 0.3)), link("l3_tip_link")).replace(
        'joint name="j3"', 'joint name="l3"')
    (tmp_path / "robot.urdf").write_text(urdf)
    (tmp_path / "m.yaml").write_text("name: peer\nrobot: {urdf: robot.urdf, end_effector: l3}\n"
                                     "payloads: [{name: box, frame: l3, mass: 1 kg, inertia: [0.01, 0.01, 0.01], attached: true}]\n")
    r = run_cli("compile", tmp_path / "m.yaml", "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["end_effector"] == "l3"
    # the link l3 sits 0.4 + 0.2 + 0.2 m above the base origin (the joint frame 'l3' is at the same place;
    # a wrong frame type would be the fixed joint 'l3_tip' 0.3 m further)
    assert np.allclose(s["end_effector_position_world_m"], [0, 0, 0.8], atol=1e-12)
    assert s["total_mass_kg"] == pytest.approx(116.0)


def test_frame_lookup_prefers_links_over_joints():
    """The end effector named like both a joint and a link is the link's BODY frame."""
    from sms_cli.model.build import find_frame

    urdf = robot(link("base", inertial(10)), joint("arm", "revolute", "base", "arm"), link("arm", inertial(1, com=(0, 0, 0.1))))
    model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
    with pytest.raises(Exception):
        model.getFrameId("arm")  # Pinocchio alone: "Several frames match"
    assert model.frames[find_frame(model, "arm")].type == pin.FrameType.BODY


# ---------------------------------------------------------------- refused: the model is unusable
def test_massless_moving_link_is_refused_naming_joint_and_link(tmp_path):
    urdf = sc3(*TOOL0, l3="")
    r = compile_text(tmp_path, urdf)
    assert r.exit_code == 2, r.output
    err = r.stderr
    assert f"robot.urdf:{line_of(urdf, '<joint ' + named('j3'))}: joint 'j3' moves links 'l3' (line {line_of(urdf, '<link ' + named('l3'))})" in err
    assert "tool0" in err and "nothing it moves carries mass or inertia about its axis" in err
    assert "add an <inertial> to link 'l3'" in err and "robot.kinematics_only: true" in err
    assert "modes" not in err and "participation" not in err
    clean(r)


def test_point_mass_on_its_own_joint_axis_is_refused(tmp_path):
    r = compile_text(tmp_path, sc3(l3=inertial(5, (0, 0, 0, 0, 0, 0))))
    assert r.exit_code == 2
    assert "joint 'j3' moves link 'l3'" in r.stderr


def test_two_joints_moving_the_same_inertia_are_named(tmp_path):
    """j3 and j4 turn about the same axis with a massless link between them: one motion, two joints."""
    urdf = sc3(joint("j4", "revolute", "l3", "l4", (0, 0, 0), "0 1 0"),
               link("l4", inertial(2, (0.02, 0.02, 0.02, 0, 0, 0), (0, 0, 0.1))), l3="")
    r = compile_text(tmp_path, urdf)
    assert r.exit_code == 2, r.output
    assert "joints 'j3', 'j4' move the same inertia" in r.stderr
    assert "link 'l3'" in r.stderr


def test_negative_mass_is_refused_at_its_line(tmp_path):
    urdf = sc3(l3=inertial(-5))
    r = compile_text(tmp_path, urdf)
    assert r.exit_code == 2
    assert f"robot.urdf:{line_of(urdf, 'value=' + chr(34) + '-5')}: link 'l3' has a negative mass (-5 kg)" in r.stderr


def test_loop_cut_off_from_the_base_is_refused(tmp_path):
    urdf = sc3(link("a", inertial(1)), link("b", inertial(1)),
               joint("ab", "revolute", "a", "b"), joint("ba", "revolute", "b", "a"))
    r = compile_text(tmp_path, urdf)
    assert r.exit_code == 2, r.output
    assert "links a, b are not connected to the base 'base': joints ab, ba form a loop" in r.stderr
    clean(r)


@pytest.mark.parametrize("value", ["nine", "", "0x10", "0 0 1 1", "null", "nan", "1e308", "inf", "1_000"])
@pytest.mark.parametrize("where", ["mass", "inertia", "origin"])
def test_malformed_numbers_are_refused_at_their_line(tmp_path, value, where):
    good = inertial(5, (0.05, 0.05, 0.05, 0, 0, 0), (0, 0, 0.1))
    bad = {"mass": good.replace('<mass value="5"/>', f'<mass value="{value}"/>'),
           "inertia": good.replace('ixx="0.05"', f'ixx="{value}"'),
           "origin": good.replace('<origin xyz="0 0 0.1"/>', f'<origin xyz="0 0 0.1" rpy="{value}"/>')}[where]
    urdf = sc3(l3=bad)
    r = compile_text(tmp_path, urdf)
    assert r.exit_code == 2, r.output
    assert f"robot.urdf:{line_of(urdf, '<link ' + named('l3'))}: link 'l3': <" in r.stderr
    assert "fix:" in r.stderr
    clean(r)


# ---------------------------------------------------------------- strict mode and kinematics-only
LINTY = sc3(*TOOL0, joint("grip_joint", "fixed", "l3", "grip", (0, 0, 0.2)),
            link("grip", inertial(0.2, (7.86e-5, 1.47e-4, 2.32e-4, 0, 0, 0))))


@pytest.mark.parametrize("how", ["flag", "mission"])
def test_strict_refuses_what_is_otherwise_accepted(tmp_path, how):
    assert compile_text(tmp_path, LINTY).exit_code == 0
    if how == "flag":
        r = compile_text(tmp_path, LINTY, "--strict")
    else:
        (tmp_path / "m.yaml").write_text("name: peer\nrobot: {urdf: robot.urdf, strict: true}\n")
        r = run_cli("compile", tmp_path / "m.yaml")
    assert r.exit_code == 2, r.output
    assert "refused by strict mode" in r.stderr and "tool0" in r.stderr and "grip" in r.stderr


KIN_MISSION = """name: peer
robot: {urdf: robot.urdf, kinematics_only: true}
analysis: {sampling: {method: grid, n: 5}, plots: false, table: false}
synthesis: {law: pd, pd: {bandwidth: 0.1 rad/s, damping: 0.9}}
"""


def test_kinematics_only_runs_kinematic_studies_and_refuses_dynamics(tmp_path):
    urdf = sc3(*TOOL0, l3="")
    (tmp_path / "robot.urdf").write_text(urdf)
    (tmp_path / "m.yaml").write_text(KIN_MISSION)
    r = run_cli("compile", tmp_path / "m.yaml")
    assert r.exit_code == 0, r.output
    assert "KINEMATICS ONLY: placeholder inertias on l3" in r.stdout

    r = run_cli("analyze", tmp_path / "m.yaml", "-o", tmp_path / "out", "--json")
    assert r.exit_code == 0, r.output
    nominal = json.loads((tmp_path / "out" / "results.json").read_text())["analysis"]["variants"]["nominal"]
    assert "mu_fixed" in nominal["indices"] and "mu_gjm" not in nominal["indices"]
    assert "K_m" not in nominal["indices"]
    assert any("kinematics-only" in why for why in nominal["skipped"].values())
    # the fixed-base manipulability is the robot's kinematics, placeholders or not: an independent check
    assert nominal["indices"]["mu_fixed"]["max"] > 0

    r = run_cli("synthesize", tmp_path / "m.yaml", "-o", tmp_path / "out")
    assert r.exit_code == 2, r.output
    assert "gain synthesis needs the robot's inertias, but links l3 have placeholder inertias" in r.stderr
    clean(r)


def test_kinematics_only_fixed_manipulability_equals_the_real_robots(tmp_path):
    """Placeholders do not change kinematics: mu_fixed of the massless robot equals that of the same
    robot with a real l3 inertia, sample by sample (same grid)."""
    out = {}
    for label, l3 in (("placeholder", ""), ("real", inertial(5, (0.05, 0.05, 0.05, 0, 0, 0), (0, 0, 0.1)))):
        d = tmp_path / label
        d.mkdir()
        (d / "robot.urdf").write_text(sc3(*TOOL0, l3=l3))
        (d / "m.yaml").write_text(KIN_MISSION.replace("plots: false, table: false", "plots: false, table: true"))
        assert run_cli("analyze", d / "m.yaml", "-o", d / "out").exit_code == 0
        out[label] = pq.read_table(d / "out" / "analysis_nominal.parquet", columns=["mu_fixed"])["mu_fixed"].to_numpy()
    a, b = out["placeholder"], out["real"]
    assert a.size == 125 and np.allclose(a, b, rtol=1e-12, atol=0)


# ---------------------------------------------------------------- property: sms agrees with Pinocchio
INERTIAL_KINDS = ("none", "zero", "point", "physical", "rounding", "roundoff_negative")


@st.composite
def trees(draw):
    """A random tree: a base and 1–6 links, with fixed frame links, point masses and rounding."""
    n = draw(st.integers(1, 6))
    base_mass = draw(st.sampled_from([10.0, 100.0]))
    parts = [link("base", inertial(base_mass, (2.0, 3.0, 4.0, 0.1, 0.0, 0.0)))]
    masses, names = [base_mass], ["base"]
    for i in range(1, n + 1):
        parent = names[draw(st.integers(0, len(names) - 1))]
        kind = draw(st.sampled_from(["revolute", "prismatic", "continuous", "fixed", "fixed"]))
        axis = draw(st.sampled_from(["1 0 0", "0 1 0", "0 0 1", "0.6 0.8 0"]))
        xyz = tuple(draw(st.sampled_from([0.0, 0.1, -0.2, 0.3])) for _ in range(3))
        ikind = draw(st.sampled_from(INERTIAL_KINDS))
        com = tuple(draw(st.sampled_from([0.0, 0.05, 0.1])) for _ in range(3))
        m = draw(st.sampled_from([0.5, 2.0]))
        body = {"none": "", "zero": inertial(0.0, (0, 0, 0, 0, 0, 0)), "point": inertial(m, (0, 0, 0, 0, 0, 0), com),
                "physical": inertial(m, (0.02, 0.03, 0.04, 0.001, 0.0, -0.002), com),
                "rounding": inertial(m, (7.86e-5, 1.47e-4, 2.32e-4, 0, 0, 0), com),
                "roundoff_negative": inertial(m, (-2e-22, 3e-6, 3e-6, 0, 0, 0), com)}[ikind]
        masses.append(m if ikind not in ("none", "zero") else 0.0)
        parts += [joint(f"j{i}", kind, parent, f"l{i}", xyz, axis), link(f"l{i}", body)]
        names.append(f"l{i}")
    return robot(*parts), sum(masses)


def pinocchio_usable(urdf: str) -> tuple[bool, np.ndarray]:
    model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
    M = pin.crba(model, model.createData(), pin.neutral(model))
    M = np.triu(M) + np.triu(M, 1).T
    eig = np.linalg.eigvalsh(M)
    return bool(eig.min() > 1e-12 * np.abs(M).max()), M


@settings(max_examples=40, deadline=None, database=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(trees())
def test_generated_trees_compile_exactly_when_pinocchio_finds_them_usable(tmp_path, tree):
    urdf, total_mass = tree
    usable, M_pin = pinocchio_usable(urdf)
    r = compile_text(tmp_path, urdf, "--json")
    clean(r)
    assert r.exit_code in (0, 2), r.output
    assert (r.exit_code == 0) == usable, r.output
    if usable:
        s = json.loads(r.stdout)
        assert s["total_mass_kg"] == pytest.approx(total_mass, rel=1e-12)
        from sms_cli.mission.load import load_mission
        from sms_cli.model import compile_system

        sm = compile_system(load_mission(tmp_path / "m.yaml"))
        assert np.allclose(sm.mass_matrix(pin.neutral(sm.model)), M_pin, rtol=0, atol=1e-12 * np.abs(M_pin).max())
    else:
        assert "joint '" in r.stderr or "joints '" in r.stderr
