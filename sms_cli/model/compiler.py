"""Mission + URDF → ``SystemModel``: lint, build, add wheels, springs, payloads and modes,
assign every joint to one partition, set the initial state."""

from __future__ import annotations

import difflib
import math

import numpy as np
import pinocchio as pin

from sms_cli.errors import InputError, Location, Problem, Warnings
from sms_cli.mission.load import LoadedMission
from sms_cli.model.build import (AddedRotor, add_rotor, build_rigid_model, frame_id, link_inertia, payload_inertia,
                                 replace_link_inertia, rotor_link_name, spatial_inertia)
from sms_cli.inertia import inertia_tensor
from sms_cli.model.conventions import euler_zyx_to_matrix, quaternion_xyzw_from_matrix
from sms_cli.model.mass_check import add_placeholders, diagnose
from sms_cli.model.system import Appendage, ArmJoint, Partitions, Payload, Spring, SystemModel, Wheel
from sms_cli.model.urdf_lint import MOVABLE, UrdfInfo, lint_urdf
from sms_cli.model.urdf_inertia import with_inertials

_TR_FROM_RT = np.array([3, 4, 5, 0, 1, 2])


def _where(loaded: LoadedMission, *path) -> Location:
    return loaded.source.locate(tuple(path))


def _assembly_payloads(loaded: LoadedMission) -> list:
    """The tile bodies of ``simulation.assembly`` (``sms_cli.sim.assembly``), as (PayloadSpec, mission path)."""
    from sms_cli.sim.assembly import assembly_payloads

    try:
        return assembly_payloads(loaded.mission)
    except ValueError as exc:
        raise InputError(problems=[Problem(str(exc), _where(loaded, "simulation", "assembly"),
                                           hint="add robot.end_effector: <link name>")]) from None


def _unknown_joint(name: str, candidates: list[str], where: Location, what: str) -> Problem:
    close = difflib.get_close_matches(name, candidates, n=1)
    return Problem(f"{what}: no movable joint named '{name}' in the URDF", where,
                   hint=f"did you mean '{close[0]}'?" if close else f"movable joints: {', '.join(candidates) or 'none'}")


def _rotors_from_mission(loaded: LoadedMission, base_link: str, warnings: Warnings) -> list[tuple[AddedRotor, object, Location]]:
    """Declared wheels and wheel arrays as rotors to add (with their spec and location)."""
    spec = loaded.mission.wheels
    out = []
    for i, w in enumerate(spec.declared):
        axis = np.asarray(w.axis, float)
        norm = np.linalg.norm(axis)
        where = _where(loaded, "wheels", "declared", i, "axis")
        if norm < 1e-12:
            raise InputError(problems=[Problem(f"wheel '{w.name}' has a zero axis", where, hint="give a unit axis")])
        if abs(norm - 1) > 1e-9:
            warnings.add(f"wheel '{w.name}' axis has norm {norm:.6g}; normalised", where, "axis", "write a unit axis")
        out.append((AddedRotor(w.name, w.mount or base_link, np.asarray(w.position, float), axis / norm, w.spin_inertia,
                               w.transverse_inertia if w.transverse_inertia is not None else 0.5 * w.spin_inertia, w.mass), w,
                    _where(loaded, "wheels", "declared", i)))
    for i, arr in enumerate(spec.arrays):
        R = euler_zyx_to_matrix(*arr.rpy)
        if arr.layout == "orthogonal":
            axes = [np.eye(3)[:, k] for k in range(3)]
        else:
            axes = []
            for k in range(arr.count):
                phi = arr.azimuth0 + 2.0 * math.pi * k / arr.count
                axes.append(np.array([math.sin(arr.beta) * math.cos(phi), math.sin(arr.beta) * math.sin(phi), math.cos(arr.beta)]))
        for k, a in enumerate(axes):
            axis = R @ a
            pos = np.asarray(arr.position, float) + arr.radius * axis
            out.append((AddedRotor(f"{arr.name}{k + 1}", arr.mount or base_link, pos, axis, arr.spin_inertia,
                                   arr.transverse_inertia if arr.transverse_inertia is not None else 0.5 * arr.spin_inertia,
                                   arr.mass), arr, _where(loaded, "wheels", "arrays", i)))
    return out


def _default_end_effector(info: UrdfInfo, arm_joint_names: list[str]) -> str:
    """Child link of the last arm joint, followed down a chain of single fixed children."""
    if not arm_joint_names:
        return info.root
    link = info.joints[arm_joint_names[-1]].child
    while True:
        kids = [info.joints[j] for j in info.children.get(link, []) if info.joints[j].kind == "fixed"]
        if len(kids) != 1 or info.children.get(link) and len(info.children[link]) != 1:
            return link
        link = kids[0].child


def _refuse_lint(warnings: Warnings, urdf_path) -> None:
    """Strict mode: the accepted-with-a-warning findings become errors."""
    lint = warnings.lint()
    if lint:
        raise InputError(f"{urdf_path}: {len(lint)} finding(s) refused by strict mode (robot.strict or --strict)",
                         [Problem(p.message, p.location, p.field, p.hint) for p in lint])


def compile_system(loaded: LoadedMission, strict: bool = False) -> SystemModel:
    """Build the SystemModel of a mission. Raises InputError (exit 2) on any inconsistency.

    ``strict`` (or ``robot.strict`` in the mission) refuses what is otherwise accepted with a warning."""
    mission = loaded.mission
    if mission.robot is None:
        raise InputError(problems=[Problem("this mission has no robot", _where(loaded),
                                           hint="add a 'robot:' section with 'urdf: path/to/robot.urdf'")])
    warnings = Warnings()
    urdf_path = loaded.resolve(mission.robot.urdf, ("robot", "urdf"))
    info = lint_urdf(urdf_path, warnings, _where(loaded, "robot", "urdf"))
    if strict or mission.robot.strict:
        _refuse_lint(warnings, urdf_path)
    model = build_rigid_model(info.xml, urdf_path)

    base_link = mission.robot.base_link or info.root
    if base_link != info.root:
        raise InputError(problems=[Problem(f"base_link '{base_link}' is not the URDF root link ('{info.root}')",
                                           _where(loaded, "robot", "base_link"), "robot.base_link",
                                           f"remove base_link or set it to '{info.root}'; re-root the URDF to use another base")])
    movable = [j for j in info.movable_joints_in_tree_order()]
    problems: list[Problem] = []

    # ---- wheels named in the URDF
    urdf_wheels = {}
    for i, w in enumerate(mission.wheels.joints):
        where = _where(loaded, "wheels", "joints", i, "joint")
        if w.joint not in info.joints or info.joints[w.joint].kind not in ("continuous", "revolute"):
            problems.append(_unknown_joint(w.joint, [j for j in movable if info.joints[j].kind != "prismatic"], where, "wheels.joints"))
        else:
            urdf_wheels[w.joint] = (w, where)
    springs_spec = {}
    for i, s in enumerate(mission.springs):
        where = _where(loaded, "springs", i, "joint")
        if s.joint not in info.joints or info.joints[s.joint].kind not in MOVABLE:
            problems.append(_unknown_joint(s.joint, movable, where, "springs"))
        elif s.joint in urdf_wheels:
            problems.append(Problem(f"joint '{s.joint}' is both a wheel and a spring", where))
        else:
            springs_spec[s.joint] = s
    if mission.robot.arm_joints is not None:
        arm_names = list(mission.robot.arm_joints)
        for i, name in enumerate(arm_names):
            where = _where(loaded, "robot", "arm_joints", i)
            if name not in info.joints or info.joints[name].kind not in MOVABLE:
                problems.append(_unknown_joint(name, movable, where, "robot.arm_joints"))
            elif name in urdf_wheels or name in springs_spec:
                problems.append(Problem(f"joint '{name}' is listed as an arm joint and as a wheel/spring", where))
        unassigned = [j for j in movable if j not in arm_names and j not in urdf_wheels and j not in springs_spec]
        if unassigned:
            problems.append(Problem(f"movable joints in no partition: {', '.join(unassigned)}", _where(loaded, "robot", "arm_joints"),
                                    "robot.arm_joints", "add them to arm_joints, wheels.joints or springs"))
    else:
        arm_names = [j for j in movable if j not in urdf_wheels and j not in springs_spec]
    link_inertias = _link_inertias(loaded, model, info, problems)
    if problems:
        raise InputError(f"{loaded.path}: {len(problems)} problem(s) relating the mission to its robot", problems)

    # ---- added wheels
    rotors = _rotors_from_mission(loaded, base_link, warnings)
    names_taken = set(info.joints) | set(info.links)
    for rotor, _, where in rotors:
        if rotor.name in names_taken:
            raise InputError(problems=[Problem(f"wheel name '{rotor.name}' is already used by the URDF", where,
                                               hint="choose another name (or name prefix for arrays)")])
        names_taken.add(rotor.name)
        link_inertias[rotor_link_name(rotor.name)] = model.inertias[add_rotor(model, rotor, where)].copy()

    # ---- payloads
    payloads: dict[str, Payload] = {}
    payload_specs = [(p, ("payloads", i, "frame")) for i, p in enumerate(mission.payloads)] + _assembly_payloads(loaded)
    for p, path in payload_specs:
        if p.name in payloads:
            raise InputError(problems=[Problem(f"payload name '{p.name}' is used twice (the assembly tasks name their "
                                               "tiles tile_KK, tile_KK@store and tile_KK@PLACE)", _where(loaded, *path),
                                               hint="rename the mission's payload")])
        fid = frame_id(model, p.frame, f"payload '{p.name}' frame", _where(loaded, *path))
        fr = model.frames[fid]
        Y = fr.placement.act(payload_inertia(p.mass, np.asarray(p.com), p.inertia))
        payloads[p.name] = Payload(p.name, fid, fr.parentJoint, Y, attached=False)

    # ---- index sets
    def jid(name: str) -> int:
        return model.getJointId(name)

    wheel_joint_names = list(urdf_wheels) + [r.name for r, _, _ in rotors]
    wheel_limits = {n: spec for n, (spec, _) in urdf_wheels.items()}
    wheel_limits.update({r.name: spec for r, spec, _ in rotors})

    pin_data = model.createData()
    q_ref = pin.neutral(model)
    pin.framesForwardKinematics(model, pin_data, q_ref)
    pin.computeJointJacobians(model, pin_data, q_ref)
    base_R = pin_data.oMi[1].rotation

    wheels = []
    for n in wheel_joint_names:
        j = jid(n)
        R_joint_in_base = base_R.T @ pin_data.oMi[j].rotation
        jm = model.joints[j]
        local_axis = _joint_axis(model, pin_data, j)
        Y = model.inertias[j]
        spin = float(local_axis @ Y.inertia @ local_axis)
        spec = wheel_limits[n]
        wheels.append(Wheel(n, j, jm.idx_v, jm.idx_q, R_joint_in_base @ local_axis, spin,
                            spec.max_torque, spec.max_speed, spec.initial_speed))
    arm = []
    for n in arm_names:
        j, uj = jid(n), info.joints[n]
        jm = model.joints[j]
        arm.append(ArmJoint(n, j, jm.idx_v, jm.idx_q, uj.kind,
                            uj.lower if uj.has_limit else -math.inf, uj.upper if uj.has_limit else math.inf,
                            uj.velocity, uj.effort))
    springs = []
    for n, s in springs_spec.items():
        jm = model.joints[jid(n)]
        if jm.nq != 1:
            raise InputError(problems=[Problem(f"spring joint '{n}' is continuous; use a revolute joint with limits", _where(loaded, "springs"))])
        springs.append(Spring(n, jm.idx_v, jm.idx_q, s.stiffness, s.damping, s.rest))

    def vidx(names):
        return np.array([model.joints[jid(n)].idx_v for n in names], dtype=int)

    def qidx(names):
        out = []
        for n in names:
            jm = model.joints[jid(n)]
            out.extend(range(jm.idx_q, jm.idx_q + jm.nq))
        return np.array(out, dtype=int)

    # ---- appendages
    appendages = []
    start = 0
    for i, a in enumerate(mission.appendages):
        frame_name = a.frame or a.link
        frame_id(model, a.link, f"appendage '{a.name}' link", _where(loaded, "appendages", i, "link"))
        fid = frame_id(model, frame_name, f"appendage '{a.name}' frame", _where(loaded, "appendages", i, "frame"))
        L = np.array([m.participation for m in a.modes], dtype=float)
        if a.ordering == "RT":
            L = L[:, _TR_FROM_RT]
        n = len(a.modes)
        appendages.append(Appendage(a.name, fid, L, np.array([m.frequency for m in a.modes]),
                                    np.array([m.damping for m in a.modes]), slice(start, start + n)))
        start += n

    idx = Partitions(
        base=np.arange(6), base_linear=np.arange(3), base_angular=np.arange(3, 6),
        wheels=vidx(wheel_joint_names), arm=vidx(arm_names), passive=vidx(list(springs_spec)),
        modes=model.nv + np.arange(start),
        q_wheels=qidx(wheel_joint_names), q_arm=qidx(arm_names), q_passive=qidx(list(springs_spec)),
    )

    # ---- end effector
    ee_name = mission.robot.end_effector or _default_end_effector(info, arm_names)
    ee_fid = frame_id(model, ee_name, "robot.end_effector", _where(loaded, "robot", "end_effector"))
    base_fid = frame_id(model, base_link, "base link")

    # ---- initial state
    init = mission.initial
    q0 = pin.neutral(model)
    q0[0:3] = init.base_position
    q0[3:7] = quaternion_xyzw_from_matrix(euler_zyx_to_matrix(*init.base_attitude))
    v0 = np.zeros(model.nv)
    R0 = euler_zyx_to_matrix(*init.base_attitude)
    v0[0:3] = R0.T @ np.asarray(init.base_linear_velocity, float)
    v0[3:6] = init.base_angular_velocity
    all_named = set(arm_names) | set(springs_spec) | set(urdf_wheels)
    for key, table in (("joints", init.joints), ("joint_rates", init.joint_rates)):
        for name, value in table.items():
            if name not in all_named:
                raise InputError(problems=[_unknown_joint(name, sorted(all_named), _where(loaded, "initial", key, name), f"initial.{key}")])
            jm = model.joints[jid(name)]
            if key == "joint_rates":
                v0[jm.idx_v] = value
            elif jm.nq == 2:
                q0[jm.idx_q: jm.idx_q + 2] = [math.cos(value), math.sin(value)]
            else:
                q0[jm.idx_q] = value
    for w in wheels:
        v0[w.v_index] = w.initial_speed
    for a in arm:
        if a.q_index is not None and model.joints[a.joint_id].nq == 1:
            val = q0[a.q_index]
            if val < a.lower - 1e-12 or val > a.upper + 1e-12:
                warnings.add(f"initial position of '{a.name}' ({val:g}) is outside its limits [{a.lower:g}, {a.upper:g}]",
                             _where(loaded, "initial", "joints", a.name), "initial.joints")
    eta0 = np.zeros(start)
    for a_spec, a in zip(mission.appendages, appendages):
        if a_spec.initial_amplitudes is not None:
            if len(a_spec.initial_amplitudes) != a.omega.size:
                raise InputError(problems=[Problem(f"appendage '{a.name}': {len(a_spec.initial_amplitudes)} initial amplitudes for {a.omega.size} modes",
                                                   _where(loaded, "appendages"), hint="give one amplitude per mode")])
            eta0[a.modes] = a_spec.initial_amplitudes

    placeholders = _check_rigid(model, q0, info, loaded, warnings)
    urdf_text = with_inertials(info.xml, {n: (link_inertias[n].mass, np.asarray(link_inertias[n].lever),
                                              np.asarray(link_inertias[n].inertia))
                                          for n, s in mission.robot.links.items()
                                          if n in link_inertias and (s.mass, s.com, s.inertia) != (None, None, None)})
    sm = SystemModel(model=model, name=mission.name, urdf_text=urdf_text, idx=idx, wheels=wheels, arm=arm, springs=springs,
                     appendages=appendages, payloads=payloads, ee_frame_id=ee_fid, base_frame_id=base_fid,
                     q0=q0, v0=v0, eta0=eta0, etadot0=np.zeros(start), warnings=list(warnings))
    sm.link_parents = {info.root: "world"}
    sm.link_parents.update({j.child: j.parent for j in info.joints.values()})
    sm.link_parents.update({rotor_link_name(r.name): r.mount_frame for r, _, _ in rotors})
    sm.link_frames = {name: frame_id(model, name, "link") for name in sm.link_parents}
    sm.link_inertias = link_inertias
    sm.kinematics_only = placeholders
    for p, _ in payload_specs:
        if p.attached:
            sm.attach_payload(p.name)
    _check_physical(sm, loaded, info, warnings)
    sm.warnings = list(warnings)
    from sms_cli.thrusters.build import build_thrusters

    sm.thrusters = build_thrusters(sm, loaded)
    return sm


def _link_inertias(loaded: LoadedMission, model: pin.Model, info: UrdfInfo, problems: list[Problem]) -> dict[str, pin.Inertia]:
    """Each URDF link's inertia in its link frame: its <inertial> (zero without one) with ``robot.links``
    applied. Each override is swapped into the model body that carries the link; errors go to ``problems``."""
    out = {}
    for name in info.links:
        if name in info.inertials:
            m, xyz, rpy, moments = info.inertials[name]
            out[name] = link_inertia(m, xyz, moments, rpy)
        else:
            out[name] = pin.Inertia.Zero()
    for name, spec in loaded.mission.robot.links.items():
        where = loaded.source.locate(("robot", "links", name), prefer_key=True)
        if name not in info.links:
            close = difflib.get_close_matches(name, list(info.links), n=1)
            problems.append(Problem(f"no link named '{name}' in the URDF", where, "robot.links",
                                    f"did you mean '{close[0]}'?" if close else f"URDF links: {', '.join(info.links)}"))
            continue
        old = out[name]
        if spec.mass is None and spec.com is None and spec.inertia is None:
            continue
        mass = old.mass if spec.mass is None else spec.mass
        if mass <= 0.0:
            problems.append(Problem(f"link '{name}' has no mass in the URDF, so its 'com' and "
                                    "'inertia' describe no body", where, f"robot.links.{name}", "give its 'mass' too"))
            continue
        com = old.lever if spec.com is None else np.asarray(spec.com, float)
        inertia = old.inertia if spec.inertia is None else inertia_tensor(*spec.inertia)
        out[name] = spatial_inertia(mass, com, inertia)
        replace_link_inertia(model, frame_id(model, name, "link"), old, out[name])
    return out


def _joint_axis(model: pin.Model, data: pin.Data, jid: int) -> np.ndarray:
    """Unit rotation axis of a 1-DoF revolute joint in its own joint frame (from its motion subspace)."""
    col = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.LOCAL)[:, model.joints[jid].idx_v]
    if np.linalg.norm(col[3:6]) < 1e-12 or np.linalg.norm(col[0:3]) > 1e-12:
        raise InputError(f"wheel joint '{model.names[jid]}' is not a revolute joint")
    return col[3:6] / np.linalg.norm(col[3:6])


def _check_rigid(model: pin.Model, q0: np.ndarray, info: UrdfInfo, loaded: LoadedMission, warnings: Warnings) -> list[str]:
    """The rigid mass matrix (wheels added, payloads detached) must be positive definite.

    Refused with the joints and links at fault, unless ``robot.kinematics_only``: then the massless
    moving bodies get placeholder inertias, listed in the returned names and in a warning."""
    kin = loaded.mission.robot.kinematics_only
    problems = diagnose(model, q0, info, kinematics_hint=not kin)
    if not problems:
        if kin:
            warnings.add("robot.kinematics_only is set but every moving body has inertia: nothing was replaced, "
                         "and the dynamics stages run", _where(loaded, "robot", "kinematics_only"))
        return []
    if not kin:
        raise InputError(f"{info.path}: the robot's mass matrix is singular", problems)
    given = add_placeholders(model, q0, info)
    left = diagnose(model, q0, info)
    if left:
        raise InputError(f"{info.path}: the robot's mass matrix stays singular with placeholder inertias", left)
    warnings.add(f"kinematics only: placeholder inertias on {', '.join(given)}; the dynamics stages (simulate, "
                 "synthesize, dynamic indices, modal analysis) refuse this model", _where(loaded, "robot", "kinematics_only"),
                 "robot.kinematics_only", "give these links an <inertial> for dynamics")
    return given


def _check_physical(sm: SystemModel, loaded: LoadedMission, info: UrdfInfo, warnings: Warnings) -> None:
    """The augmented mass matrix must be positive definite (the rigid one is, ``_check_rigid``); per
    appendage, M_jj − LᵀL ⪰ 0 is expected (the modes cannot carry more inertia than the appendage's
    rigid body at the junction)."""
    if not sm.appendages:
        return
    M = sm.mass_matrix(sm.q0)
    eig = np.linalg.eigvalsh(M)
    if eig.min() <= 1e-12 * max(eig.max(), 1.0):
        raise InputError(problems=[Problem(
            f"the mass matrix with modes is not positive definite (smallest eigenvalue {eig.min():.3g}): "
            "the participation factors exceed what the rigid inertia allows",
            _where(loaded, "appendages"), hint="check the participation factors (units, ordering) and the appendage link inertia")])
    for i, (spec, a) in enumerate(zip(loaded.mission.appendages, sm.appendages)):
        M_jj = _link_inertia_at_frame(sm, loaded, info, spec.link, a.frame_id)
        if M_jj is None:
            warnings.add(f"appendage '{a.name}': link '{spec.link}' has no <inertial>; its modes cannot be checked",
                         _where(loaded, "appendages", i, "link"))
            continue
        residual = np.linalg.eigvalsh(M_jj - a.L.T @ a.L)
        if residual.min() < -1e-9 * np.abs(M_jj).max():
            warnings.add(f"appendage '{a.name}': modal effective mass exceeds the rigid inertia of its link at the junction "
                         f"(min eigenvalue of M_jj − LᵀL = {residual.min():.4g}); the model stays well-posed but the data disagree",
                         _where(loaded, "appendages", i), "participation",
                         "check the link inertia, the ordering (TR/RT) and the frame of L")


def _link_inertia_at_frame(sm: SystemModel, loaded: LoadedMission, info: UrdfInfo, link: str, frame_id: int) -> np.ndarray | None:
    """6×6 spatial inertia ([v; ω] order) of a URDF link's own <inertial> (with ``robot.links``), expressed at a frame;
    None for a link with neither."""
    if link not in info.inertials and link not in loaded.mission.robot.links:
        return None
    d = sm.model.createData()
    pin.framesForwardKinematics(sm.model, d, sm.q0)
    link_to_frame = d.oMf[frame_id].actInv(d.oMf[sm.link_frames[link]])
    return link_to_frame.act(sm.link_inertias[link]).matrix()
