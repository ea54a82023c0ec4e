"""The mission's ``thrusters:`` section resolved against the compiled model (``sms compile``):
mount links to the base joint frame, the cube preset generated about the base CoM, the tank placed.
Every problem is an ``InputError`` (exit 2) with its mission location and a fix."""

from __future__ import annotations

import difflib

import numpy as np

from sms_cli.errors import InputError, Problem
from sms_cli.thrusters.layout import ThrusterSet, cube_thrusters


def _where(loaded, *key):
    return loaded.source.locate(("thrusters",) + key, prefer_key=True)


def _mount(sm, loaded, link: str | None, at: tuple) -> tuple[np.ndarray, np.ndarray] | Problem:
    """(R, p) of the link frame in the base joint frame, or the Problem of a link that is not on the base body."""
    model = sm.model
    if link is None:
        fid = sm.base_frame_id
    elif link not in sm.link_frames:
        close = difflib.get_close_matches(link, list(sm.link_frames), n=1)
        return Problem(f"no link named '{link}'", _where(loaded, *at), "thrusters." + ".".join(map(str, at)),
                       f"did you mean '{close[0]}'?" if close else f"links: {', '.join(sm.link_frames)}")
    else:
        fid = sm.link_frames[link]
    frame = model.frames[fid]
    if frame.parentJoint != sm.base_joint_id:
        return Problem(f"link '{link}' moves relative to the base (joint '{model.names[frame.parentJoint]}'): thrusters "
                       "must be on the base body", _where(loaded, *at), "thrusters." + ".".join(map(str, at)),
                       "mount the thruster on the base link or a link fixed to it (omit 'link' for the base link)")
    return frame.placement.rotation.copy(), frame.placement.translation.copy()


def build_thrusters(sm, loaded) -> ThrusterSet | None:
    """The ``ThrusterSet`` of ``loaded.mission.thrusters`` on ``sm`` (None without the section)."""
    spec = loaded.mission.thrusters
    if spec is None:
        return None
    problems: list[Problem] = []
    Y = sm.model.inertias[sm.base_joint_id]
    com = np.asarray(Y.lever, float).copy()  # base body CoM, base joint frame
    rows = []
    if spec.layout == "cube":
        rows = cube_thrusters(spec.size, spec.force, spec.isp, com)
    else:
        for i, t in enumerate(spec.entries):
            m = _mount(sm, loaded, t.link, ("entries", i, "link"))
            if isinstance(m, Problem):
                problems.append(m)
                continue
            R, p = m
            d = np.asarray(t.direction, float)
            rows.append((t.name, R @ np.asarray(t.position, float) + p, R @ (d / np.linalg.norm(d)), t.max_force, t.isp))
    tank = com if spec.tank.position is None else np.asarray(spec.tank.position, float)
    if spec.tank.propellant >= Y.mass:
        problems.append(Problem(f"the propellant load {spec.tank.propellant:g} kg is not less than the base body's mass "
                                f"{Y.mass:.6g} kg (which includes it)", _where(loaded, "tank", "propellant"),
                                "thrusters.tank.propellant", "give the propellant loaded in the base link's mass"))
    if problems:
        raise InputError(f"{loaded.path}: {len(problems)} problem(s) in the thrusters section", problems)
    names, pos, dirs, fmax, isp = zip(*rows)
    return ThrusterSet(list(names), np.array(pos), np.array(dirs), np.array(fmax, float), np.array(isp, float),
                       spec.firing_cycle, spec.mib, spec.quantization, tank, spec.tank.propellant)
