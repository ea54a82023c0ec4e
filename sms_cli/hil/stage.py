"""``sms export hil``: a two-spacecraft run + a facility file → robot commands, reachability and workspace.

Reads ``<results>/results.json`` (``simulate.formation``) and its relative-motion table, maps the
relative motion onto the facility (Vicariotto 2023 (6.2), :mod:`sms_cli.hil.poses`), checks each robot's
inverse kinematics (:mod:`sms_cli.hil.reach`), compares the absolute and relative replays' workspace
(:mod:`sms_cli.hil.workspace`) and writes ``<out>/hil/``: ``commands.csv``, ``commands.mcap``,
``workspace.json`` and ``workspace.png``.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from sms_cli.errors import InputError, Problem
from sms_cli.hil.motion import Formation, load_run
from sms_cli.hil.schema import LoadedFacility, MountSpec, load_facility

#: A start offset above these (the mounts do not hold the initial relative pose) is warned about.
OFFSET_WARN_M, OFFSET_WARN_RAD = 1e-3, np.radians(0.1)


def resolve_roles(loaded: LoadedFacility, formation: Formation) -> tuple[dict[str, tuple[str, MountSpec]], str]:
    """{"master": (key, spec), "other": (key, spec)} from the facility's spacecraft keys (master/other or
    the formation's names), and the moving role."""
    fac = loaded.facility
    names = {"master": "master", "other": "other", formation.master: "master", formation.other: "other"}
    roles: dict[str, tuple[str, MountSpec]] = {}
    for key, spec in fac.spacecraft.items():
        role = names.get(key)
        where = loaded.where("spacecraft", key, prefer_key=True)
        if role is None:
            raise InputError(problems=[Problem(
                f"'{key}' is neither master/other nor a spacecraft of this run ({formation.master}, {formation.other})",
                where, f"spacecraft.{key}", f"name it master or {formation.master} (body 1), other or {formation.other} (body 2)")])
        if role in roles:
            raise InputError(problems=[Problem(f"'{key}' and '{roles[role][0]}' both name the {role} spacecraft", where,
                                               f"spacecraft.{key}", "keep one of the two entries")])
        roles[role] = (key, spec)
    for role, name in (("master", formation.master), ("other", formation.other)):
        if role not in roles:
            raise InputError(problems=[Problem(f"no mount for the {role} spacecraft ('{name}')", loaded.where("spacecraft"),
                                               "spacecraft", f"add '{name}:' (or '{role}:') with its mount")])
    moving = names.get(fac.moving)
    if moving is None:
        raise InputError(problems=[Problem(f"moving is '{fac.moving}': expected master, other, {formation.master} or "
                                           f"{formation.other}", loaded.where("moving"), "moving",
                                           "master replays the relative motion on body 1's robot (the thesis), other the mirror")])
    return roles, moving


def _robot(loaded: LoadedFacility, key: str, role: str, spec: MountSpec):
    from sms_cli.hil.poses import pose_row
    from sms_cli.hil.reach import load_robot

    r = spec.robot
    at = ("spacecraft", key, "robot")
    urdf = loaded.resolve(r.urdf, at + ("urdf",))
    return load_robot(role, urdf, r.tool_frame, pose_row(r.base.se3()), pose_row(r.flange_to_mockup.se3()), r.home,
                      loaded.where(*at, "urdf"), loaded.where(*at, "tool_frame"), loaded.where(*at, "home"))


def run_export(results: Path, facility: Path, out: Path | None = None, *, plots: bool = True) -> dict:
    """Run the export; returns the summary printed by the command (and ``--json``)."""
    from sms_cli.hil.export import MockupTrack, facility_metadata, write_commands_csv, write_commands_mcap
    from sms_cli.hil.poses import hil_commands, pose_row
    from sms_cli.hil.reach import reach_trajectory
    from sms_cli.hil.workspace import Envelope, absolute_replay, compare
    from sms_cli.results import write_json_atomic

    loaded = load_facility(facility)
    formation, motion = load_run(results)
    roles, moving = resolve_roles(loaded, formation)
    held = "other" if moving == "master" else "master"
    mount = {role: pose_row(spec.mount.se3()) for role, (_, spec) in roles.items()}
    robots = {role: _robot(loaded, key, role, spec) for role, (key, spec) in roles.items() if spec.robot is not None}
    name = {"master": formation.master, "other": formation.other}

    t = motion.t
    cmd = hil_commands(t, motion.g1, motion.g2, motion.V1, motion.V2, mount["master"], mount["other"], moving)
    if cmd.start_offset[0] > OFFSET_WARN_M or cmd.start_offset[1] > OFFSET_WARN_RAD:
        warnings.warn(f"the mounts do not hold the run's initial relative pose: the {name[moving]} mock-up starts "
                      f"{round(cmd.start_offset[0], 9):.4g} m and {round(float(np.degrees(cmd.start_offset[1])), 9):.4g} deg from its mount "
                      f"({loaded.where('spacecraft', roles[moving][0], 'mount')})", UserWarning, stacklevel=2)

    reach = {}
    tracks = []
    for role, poses, twist in ((moving, cmd.poses, cmd.twist), (held, cmd.held[None, :], None)):
        tr = MockupTrack(name[role], "moving" if role == moving else "held", poses, twist)
        robot = robots.get(role)
        if robot is not None:
            rc = reach_trajectory(robot, poses)
            reach[role] = rc
            tr.robot_base = robot.base
            tr.tool = np.array([pose_row(robot.tool_pose(q)) for q in rc.q])
            tr.joints, tr.reachable = rc.q, rc.reachable
            tr.position_error, tr.rotation_error = rc.position_error, rc.rotation_error
        tracks.append(tr)

    fac = loaded.facility
    e = fac.envelope
    env = Envelope(tuple(e.translation) if e.translation is not None else None, e.radius, e.rotation)
    g_moving = motion.g1 if moving == "master" else motion.g2
    workspace, ex_abs, ex_rel = compare(t, absolute_replay(g_moving, mount[moving]), cmd.poses, env)
    workspace = {"moving": name[moving], "role": moving,
                 "absolute_replay": "mount · g(0)⁻¹ g(t) of the moving spacecraft",
                 "relative_replay": "g1_HW = g2_HW g12⁻¹ (Vicariotto 2023 (6.2))" if moving == "master"
                 else "g2_HW = g1_HW g12 (the mirror of Vicariotto 2023 (6.2))", **workspace}

    folder = Path(out if out is not None else results) / "hil"
    files = {"commands_csv": folder / "commands.csv", "commands_mcap": folder / "commands.mcap",
             "workspace_json": folder / "workspace.json"}
    write_commands_csv(files["commands_csv"], t, tracks)
    write_commands_mcap(files["commands_mcap"], t, tracks, world=fac.world_frame, metadata={
        "facility": facility_metadata(fac.name, loaded.path, loaded.text),
        "formation": {"master": formation.master, "other": formation.other, "moving": name[moving],
                      "relative_motion": str(motion.path)}})
    write_json_atomic(files["workspace_json"], workspace)
    if plots:
        from sms_cli.hil.plots import write_workspace_png

        files["workspace_png"] = write_workspace_png(folder / "workspace.png", ex_abs, ex_rel, env, workspace, name[moving])

    return {
        "facility": fac.name,
        "facility_file": str(loaded.path),
        "results": str(results),
        "formation": {"master": formation.master, "other": formation.other},
        "moving": name[moving],
        "held": name[held],
        "samples": int(t.size),
        "duration_s": float(t[-1] - t[0]),
        "start_offset": {"distance_m": cmd.start_offset[0], "angle_deg": float(np.degrees(cmd.start_offset[1]))},
        "reachability": {name[role]: rc.summary(t) for role, rc in reach.items()} or None,
        "workspace": workspace,
        "files": {k: str(v) for k, v in files.items()},
    }


def all_reachable(summary: dict) -> bool | None:
    """Whether every robot reaches every commanded pose (None: the facility gives no robot)."""
    reach = summary["reachability"]
    return None if reach is None else all(r["all_reachable"] for r in reach.values())


def _s(x: float | None) -> str:
    return "never" if x is None else f"{x:.4g} s"


def format_export(s: dict) -> str:
    """The command's human output."""
    w = s["workspace"]
    env = w["envelope"]
    box = env["translation_half_ranges_m"]
    lines = [f"HIL export: {s['facility']} · {s['samples']} samples over {s['duration_s']:.4g} s · "
             f"{s['moving']} moves (relative motion), {s['held']} held",
             f"  start offset from the mount: {s['start_offset']['distance_m']:.3g} m, {s['start_offset']['angle_deg']:.3g} deg",
             "  envelope: " + ("±" + " × ".join(f"{h:.3g}" for h in box) + " m" if box else f"radius {env['radius_m']:.3g} m")
             + f", {env['rotation_deg']:.3g} deg",
             f"  {'replay':<10}{'range x/y/z (m)':>26}{'max rot (deg)':>15}{'leaves envelope':>18}"]
    for kind in ("absolute", "relative"):
        m = w[kind]
        rng = "/".join(f"{v:.3g}" for v in m["translation_range_m"].values())
        leave = _s(m["leaves_envelope_s"]) + (f" ({m['leaves_by']})" if m["leaves_by"] else "")
        lines.append(f"  {kind:<10}{rng:>26}{m['max_rotation_deg']:>15.4g}  {leave}")
    if s["reachability"] is None:
        lines.append("  reachability: not checked (the facility file gives no robot URDF)")
    else:
        for mock, r in s["reachability"].items():
            verdict = "all reachable" if r["all_reachable"] else f"first unreachable at {r['first_unreachable_s']:.6g} s: {r['reason']}"
            lines.append(f"  reachability of the {mock} robot ({r['samples']} poses): {verdict}")
    lines.append("  wrote " + ", ".join(s["files"].values()))
    return "\n".join(lines)


__all__ = ["run_export", "format_export", "resolve_roles", "all_reachable"]
