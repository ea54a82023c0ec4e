"""The six-number inertia convention (sms_cli/inertia.py), held against Pinocchio's own URDF parser:
a body written as a mission payload and the same body written as a URDF link give one system inertia."""

from __future__ import annotations

import json

import numpy as np

from conftest import run_cli

MOMENTS = (0.5, 0.6, 0.7, 0.05, -0.03, 0.02)  # ixx iyy izz ixy ixz iyz (kg m²): every product distinct


def robot(extra: str = "") -> str:
    return ('<?xml version="1.0"?>\n<robot name="r">\n'
            '<link name="base"><inertial><mass value="100"/><inertia ixx="9" iyy="8" izz="7" ixy="0" ixz="0" iyz="0"/>'
            '</inertial></link>\n'
            '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.5"/>'
            '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>\n'
            '<link name="arm"><inertial><origin xyz="0.2 0 0"/><mass value="2"/>'
            '<inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>\n'
            '<joint name="tool_joint" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0.4 0 0"/></joint>\n'
            f'<link name="tool">{extra}</link>\n</robot>\n')


def inertia_of(tmp_path, name: str, urdf: str, mission_extra: str = "") -> np.ndarray:
    d = tmp_path / name
    d.mkdir()
    (d / "r.urdf").write_text(urdf)
    (d / "m.yaml").write_text("name: t\nrobot: {urdf: r.urdf}\n" + mission_extra)
    r = run_cli("compile", d / "m.yaml", "--json")
    assert r.exit_code == 0, r.output
    return np.array(json.loads(r.stdout)["inertia_about_com_world_kgm2"])


def test_payload_inertia_equals_the_same_body_in_urdf(tmp_path):
    ixx, iyy, izz, ixy, ixz, iyz = MOMENTS
    in_urdf = inertia_of(tmp_path, "urdf", robot(
        f'<inertial><origin xyz="0.1 0.05 0"/><mass value="3"/><inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" '
        f'ixy="{ixy}" ixz="{ixz}" iyz="{iyz}"/></inertial>'))
    as_payload = inertia_of(tmp_path, "payload", robot(), "payloads: [{name: box, frame: tool, mass: 3 kg, com: [0.1, 0.05, 0], "
                            f"inertia: {list(MOMENTS)}, attached: true}}]\n")
    assert np.allclose(as_payload, in_urdf, rtol=0, atol=1e-12)
