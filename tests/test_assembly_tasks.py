"""Tile assembly tasks (simulation.assembly, Kraiem 2022 §4.3.1): expansion into phases and payloads.

Test robot: pulsar_simple with three tile slots and an assembly site placed at the end-effector poses
of known arm configurations (forward kinematics), so that every target is reachable by construction;
the oracle of the inverse kinematics is the forward kinematics of the full free-flyer model.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import MISSIONS, ROOT, assert_clean, run_cli

SLOT_CONFIGS = [[1.0, 0.5, -0.3, 0.4, 0.2], [1.5, 0.8, -0.6, 0.5, -0.1], [0.5, 0.3, -0.2, 0.3, 0.1]]
SITE_CONFIG = [2.5, 1.2, -0.8, 0.9, 0.0]
TILE = {"mass": 55.0, "inertia": [5.0, 6.0, 9.0], "com": [0.05, -0.02, 0.1]}

MISSION = """\
name: assembly_test
robot: {{urdf: robot.urdf, base_link: Spacecraft, end_effector: dlsaffe_link_ee,
        arm_joints: [rail_joint_1, arm_joint_1, arm_joint_2, arm_joint_3, arm_joint_4]}}
wheels:
  joints:
    - {{joint: Spacecraft_to_RW1, max_torque: "0.2 N m", max_speed: "6000 rpm"}}
    - {{joint: Spacecraft_to_RW2, max_torque: "0.2 N m", max_speed: "6000 rpm"}}
    - {{joint: Spacecraft_to_RW3, max_torque: "0.2 N m", max_speed: "6000 rpm"}}
    - {{joint: Spacecraft_to_RW4, max_torque: "0.2 N m", max_speed: "6000 rpm"}}
simulation:
  attitude: {{law: mrp_feedback, K: 2, P: 40}}
  arm: {{law: computed_torque, kp: 0.04, kd: 0.4, model: attitude_held}}
  phases: [{{name: hold, duration: 5 s}}]
  assembly:
    tile: {{mass: {mass} kg, inertia: {inertia}, com: {com}}}
    grasp: {grasp}
    store: {store}
    tiles: 3
    tasks:
{tasks}
"""
TASKS = "      - {pick: [1], place: assembly_site}\n      - {pick: [2, 3], place: assembly_site}"


GRASPS = {"on the frame": ("{position: [0, 0, 0], rpy: [0, 0, 0]}", pin.SE3.Identity()),
          "flipped, 10 cm off": ("{position: [0.02, -0.03, 0.1], rpy: [170 deg, 20 deg, 30 deg]}",
                                 pin.SE3(pin.rpy.rpyToMatrix(*np.radians([170, 20, 30])), np.array([0.02, -0.03, 0.1])))}


def _frames(sm, grasp) -> str:
    """URDF text of massless fixed links on the base whose grasp pose is the end-effector pose of each of the
    chosen configurations (frame = end-effector pose · grasp⁻¹)."""
    out = []
    names = [f"tile_slot_{k}" for k in (1, 2, 3)] + ["assembly_site"]
    for name, c in zip(names, SLOT_CONFIGS + [SITE_CONFIG]):
        q = sm.q0.copy()
        for a, v in zip(sm.arm, c):
            q[a.q_index] = v
        pin.framesForwardKinematics(sm.model, sm.data, q)
        T = sm.data.oMf[sm.base_frame_id].actInv(sm.data.oMf[sm.ee_frame_id]) * grasp.inverse()
        xyz = " ".join(f"{x:.17g}" for x in T.translation)
        rpy = " ".join(f"{x:.17g}" for x in pin.rpy.matrixToRpy(T.rotation))
        out.append(f'  <joint name="{name}_mount" type="fixed"><parent link="Spacecraft"/><child link="{name}"/>'
                   f'<origin xyz="{xyz}" rpy="{rpy}"/></joint>\n  <link name="{name}"/>\n')
    return "".join(out)


@pytest.fixture(scope="module", params=list(GRASPS), ids=list(GRASPS))
def folder(request, tmp_path_factory):
    """A folder with the test robot whose slots are reachable with this grasp; ``folder.grasp``: its YAML."""
    from conftest import compile_path

    sm = compile_path(MISSIONS / "pulsar_simple.yaml")
    d = tmp_path_factory.mktemp("assembly")
    text = (ROOT / "robots" / "pulsar_simple.urdf").read_text()
    (d / "robot.urdf").write_text(text.replace("</robot>", _frames(sm, GRASPS[request.param][1]) + "</robot>"))
    (d / "grasp.txt").write_text(GRASPS[request.param][0])
    return d


def _mission(folder, name="m.yaml", store="tile_slot_{index}", tasks=TASKS, **tile):
    t = {**TILE, **tile}
    path = folder / name
    path.write_text(MISSION.format(store=store, tasks=tasks, grasp=(folder / "grasp.txt").read_text(), **t))
    return path


def _expanded(path):
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.sim.stage import planned_simulation

    loaded = load_mission(path)
    sm = compile_system(loaded)
    spec, plans = planned_simulation(sm, loaded)
    return sm, spec, plans


def test_each_move_puts_the_end_effector_on_its_frame(folder):
    sm, spec, _ = _expanded(_mission(folder))
    targets = {"t1_reach_tile_1": "tile_slot_1", "t1_carry": "assembly_site", "t2_reach_tile_2": "tile_slot_2",
               "t2_reach_tile_3": "tile_slot_3", "t2_carry": "assembly_site"}
    moves = {p.name: p for p in spec.phases if p.waypoints}
    assert set(moves) == set(targets) | {"return_home"}
    for phase, frame in targets.items():
        q = sm.q0.copy()
        for a in sm.arm:
            q[a.q_index] = moves[phase].waypoints[-1].joints[a.name]
        pin.framesForwardKinematics(sm.model, sm.data, q)
        # pose of the end-effector frame in the target frame, both on the free-flyer model, against the grasp
        grasp = GRASPS["on the frame" if "rpy: [0, 0, 0]" in (folder / "grasp.txt").read_text() else "flipped, 10 cm off"][1]
        rel = sm.data.oMf[sm.model.getFrameId(frame)].actInv(sm.data.oMf[sm.ee_frame_id])
        err = pin.log6(grasp.actInv(rel)).vector
        assert np.linalg.norm(err) < 1e-9, (phase, err)
    home = moves["return_home"].waypoints[-1].joints
    assert np.allclose([home[a.name] for a in sm.arm], sm.q0[[a.q_index for a in sm.arm]], atol=0)


def test_phases_move_each_tile_from_the_store_to_the_end_effector_to_the_site(folder):
    sm, spec, _ = _expanded(_mission(folder))
    assert [p.name for p in spec.phases] == [
        "hold", "t1_reach_tile_1", "t1_grasp_tile_1", "t1_carry", "t1_release",
        "t2_reach_tile_2", "t2_grasp_tile_2", "t2_reach_tile_3", "t2_grasp_tile_3", "t2_carry", "t2_release",
        "return_home"]
    kinds = {p.name: p.kind for p in spec.phases}
    assert kinds["t2_reach_tile_2"] == "deploy" and kinds["t2_reach_tile_3"] == "move_payload"
    assert all(p.duration > 0 for p in spec.phases)  # every 'auto' move sized
    # walk the phases: where is each tile's mass (store / end effector / site)?
    where = {k: "store" for k in (1, 2, 3)}
    on_ee_at_carry = {}
    for p in spec.phases:
        for name in p.detach:
            k = int(name.split("@")[0].split("_")[1])
            assert where[k] == ("store" if name.endswith("@store") else "ee"), (p.name, name)
            where[k] = None
        for name in p.attach:
            k = int(name.split("@")[0].split("_")[1])
            assert where[k] is None, (p.name, name)
            where[k] = "site" if "@" in name else "ee"
        if p.name.endswith("carry"):
            on_ee_at_carry[p.name] = sorted(k for k, w in where.items() if w == "ee")
    assert on_ee_at_carry == {"t1_carry": [1], "t2_carry": [2, 3]}  # loads 55 kg and 110 kg
    assert where == {1: "site", 2: "site", 3: "site"}
    # the compiled model starts with the three stored tiles on the base
    assert [n for n, p in sm.payloads.items() if p.attached] == ["tile_1@store", "tile_2@store", "tile_3@store"]


def test_a_grasp_moves_the_tile_mass_without_moving_it(folder):
    """At the reach target, the tile on the end effector and the tile in its slot are the same body:
    the system's mass, CoM and inertia about the CoM (world frame) are unchanged by the transfer."""
    sm, spec, _ = _expanded(_mission(folder))
    reach = next(p for p in spec.phases if p.name == "t2_reach_tile_3")
    q = sm.q0.copy()
    for a in sm.arm:
        q[a.q_index] = reach.waypoints[-1].joints[a.name]

    def composite():
        data = sm.model.createData()
        pin.ccrba(sm.model, data, q, np.zeros(sm.model.nv))
        return data.Ig.mass, data.com[0].copy(), data.Ig.inertia.copy()

    before = composite()
    sm.detach_payload("tile_3@store")
    sm.attach_payload("tile_3")
    after = composite()
    assert after[0] == pytest.approx(before[0], rel=1e-14)
    assert np.allclose(after[1], before[1], atol=1e-9)
    assert np.allclose(after[2], before[2], atol=1e-7)


def test_the_tasks_simulate_end_to_end(folder, tmp_path):
    path = _mission(folder, "one.yaml", tasks="      - {pick: [3], place: assembly_site}")
    result = run_cli("simulate", path, "-o", tmp_path / "out")
    assert_clean(result, 0)
    import json

    sim = json.loads((tmp_path / "out" / "results.json").read_text())["simulate"]
    assert [p["name"] for p in sim["phases"]] == ["hold", "t1_reach_tile_3", "t1_grasp_tile_3", "t1_carry",
                                                 "t1_release", "return_home"]
    assert sim["status"] == "completed"
    # momentum between the mass transfers (metrics.conservation measures within each segment)
    assert sim["conservation"]["angular_momentum_drift_rel"] < 1e-9


@pytest.mark.parametrize("case, expect", [
    ("unreachable", "the end effector cannot reach frame 'far_slot_1'"),
    ("index", "slot 4 is not in the store (slots 1..3)"),
    ("twice", "the tile of slot 1 is picked twice"),
    ("pattern", "must name the slot number as {index}"),
    ("constant", "gives every slot the same frame name"),
])
def test_bad_assembly_input_is_exit_2_at_its_line(folder, case, expect):
    if case == "unreachable":
        text = (folder / "robot.urdf").read_text()
        far = "".join(f'  <joint name="far_{k}" type="fixed"><parent link="Spacecraft"/><child link="far_slot_{k}"/>'
                      f'<origin xyz="40 0 0" rpy="0 0 0"/></joint>\n  <link name="far_slot_{k}"/>\n' for k in (1, 2, 3))
        (folder / "far.urdf").write_text(text.replace("</robot>", far + "</robot>"))
        path = _mission(folder, "far.yaml", store="far_slot_{index}")
        path.write_text(path.read_text().replace("urdf: robot.urdf", "urdf: far.urdf"))
    elif case == "index":
        path = _mission(folder, "index.yaml", tasks="      - {pick: [4], place: assembly_site}")
    elif case == "twice":
        path = _mission(folder, "twice.yaml", tasks="      - {pick: [1, 1], place: assembly_site}")
    elif case == "pattern":
        path = _mission(folder, "pattern.yaml", store="tile_slot_{k}")
    else:
        path = _mission(folder, "constant.yaml", store="tile_slot")
    result = run_cli("compile", path)
    assert_clean(result, 2, expect, path.name)
