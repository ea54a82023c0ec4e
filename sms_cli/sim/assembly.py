"""Tile assembly tasks (``simulation.assembly``, Kraiem 2022 §4.3.1) expanded into payloads and phases.

Payloads (``assembly_payloads``, read by the compiler): for every tile k of the store, three bodies of the
same mass, CoM and inertia (``TileSpec``, given in the slot frame's axes):

* ``tile_KK@store`` on slot frame k, attached at t = 0 (the stored tile rides on the store's body);
* ``tile_KK`` on the end-effector frame, attached at its grasp (CoM and inertia moved to that frame by the
  grasp pose, ``simulation.assembly.grasp``: the end-effector frame's pose in the slot frame);
* ``tile_KK@PLACE`` on the place frame of its task, attached at its release.

The grasp detaches the first and attaches the second while the end-effector frame sits on the slot's
pose (the move's target), so the tile's mass moves between two bodies at the same place with the same
axes: only the small end-effector velocity left by tracking errors differs. Tiles carried together are
lumped at the end-effector frame.

Phases (``assembly_phases``, after the compiler): per task, ``tN_reach_KK`` (duration 'auto') and
``tN_grasp_KK`` per picked tile, ``tN_carry`` (duration 'auto', to the place frame) and ``tN_release``;
then ``return_home`` (duration 'auto', to the initial arm configuration) when asked. Move targets are
joint configurations found by inverse kinematics of the end-effector frame on the grasp pose in the slot's
(place's) frame, with the base, the wheels and any spring joint fixed at their initial values: slots
and sites are frames of the base, so the target is right whatever the base's motion.
"""

from __future__ import annotations

import numpy as np

from sms_cli.errors import InputError, Problem

# deterministic restarts of the IK when the warm start does not reach a pose
_RESTARTS = 12


def tile_name(spec, k: int) -> str:
    """Payload name of the tile of slot k when carried (``tile_07``; width from the store's size)."""
    return f"tile_{k:0{len(str(spec.tiles))}d}"


def assembly_payloads(mission) -> list[tuple[object, tuple]]:
    """(PayloadSpec, mission path of the frame it names) for every tile body of ``mission.simulation.assembly``
    (none without one). The end-effector frame is ``robot.end_effector``."""
    from sms_cli.mission.system import PayloadSpec

    sim = mission.simulation
    spec = None if sim is None else sim.assembly
    if spec is None:
        return []
    where = ("simulation", "assembly")
    ee = mission.robot.end_effector if mission.robot is not None else None
    if ee is None:
        raise ValueError("assembly tasks carry tiles on the end effector: name it (robot.end_effector)")
    t = spec.tile
    body = {"mass": t.mass, "inertia": t.inertia, "com": t.com}
    carried = {"mass": t.mass, **_in_end_effector(t, spec.grasp)}
    out = []
    for k in range(1, spec.tiles + 1):
        out.append((PayloadSpec(name=f"{tile_name(spec, k)}@store", frame=spec.store.format(index=k), attached=True,
                                **body), where + ("store",)))
        out.append((PayloadSpec(name=tile_name(spec, k), frame=ee, **carried), ("robot", "end_effector")))
    for i, task in enumerate(spec.tasks):
        for k in task.pick:
            out.append((PayloadSpec(name=f"{tile_name(spec, k)}@{task.place}", frame=task.place, **body),
                        where + ("tasks", i, "place")))
    return out


def grasp_pose(grasp):
    """``pinocchio.SE3`` of the end-effector frame in the slot (place) frame (``GraspSpec``)."""
    import pinocchio as pin

    return pin.SE3(pin.rpy.rpyToMatrix(*map(float, grasp.rpy)), np.asarray(grasp.position, dtype=float))


def _in_end_effector(tile, grasp) -> dict:
    """The tile's CoM (m) and inertia about it (six numbers, ``sms_cli.inertia`` order) in the end-effector
    frame: c_e = Rᵀ(c_s − p), I_e = Rᵀ I_s R with (R, p) the grasp pose in the slot frame."""
    from sms_cli.inertia import inertia_tensor

    g = grasp_pose(grasp)
    R, p = g.rotation, g.translation
    I = R.T @ inertia_tensor(*(list(tile.inertia) + [0.0, 0.0, 0.0])[:6]) @ R
    return {"com": (R.T @ (np.asarray(tile.com, dtype=float) - p)).tolist(),
            "inertia": [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]}


class ArmIk:
    """Inverse kinematics of the end-effector frame with the arm joints free and every other joint (base,
    wheels, springs) fixed at the model's initial configuration. Poses are in the world frame of that
    configuration; slots, sites and the arm's root are all on the base, so the solution does not depend on
    the base's pose."""

    def __init__(self, sm):
        import pinocchio as pin

        model = sm.model
        arm_ids = {a.joint_id for a in sm.arm}
        lock = [j for j in range(1, model.njoints) if j not in arm_ids]
        self.model = pin.buildReducedModel(model, lock, sm.q0)
        self.data = self.model.createData()
        if self.model.nq != self.model.nv:
            raise ValueError("assembly tasks need revolute or prismatic arm joints (a continuous joint has no "
                             "position to solve for): give it limits (type revolute)")
        self.names = [self.model.names[j] for j in range(1, self.model.njoints)]
        self.index = [self.names.index(a.name) for a in sm.arm]  # reduced q index of each arm joint
        self.ee = self.model.getFrameId(sm.model.frames[sm.ee_frame_id].name)
        self.lower = np.array(self.model.lowerPositionLimit, dtype=float)
        self.upper = np.array(self.model.upperPositionLimit, dtype=float)
        self.start = self._from_arm(np.asarray(sm.q0)[[a.q_index for a in sm.arm]])

    def _from_arm(self, q_arm: np.ndarray) -> np.ndarray:
        q = np.zeros(self.model.nq)
        q[self.index] = q_arm
        return q

    def frame_pose(self, name: str):
        """``pinocchio.SE3`` of a frame of the reduced model at the initial configuration (base frame)."""
        import pinocchio as pin

        fid = self.model.getFrameId(name)
        pin.framesForwardKinematics(self.model, self.data, self.start)
        return self.data.oMf[fid].copy()

    def solve(self, target, q_arm0: np.ndarray):
        """``IkSolution`` (the warm start, else the best of deterministic restarts: reached, then with no joint
        on a limit) and its arm joints in ``sm.arm`` order."""
        from sms_cli.model.ik import solve_frame_ik

        rng = np.random.default_rng(2022)
        lo = np.where(np.isfinite(self.lower), self.lower, -np.pi)
        hi = np.where(np.isfinite(self.upper), self.upper, np.pi)
        def rank(sol):  # reached, then off the joint limits (a target on a stop drives the joint into it)
            return sol.reachable, not sol.at_limit, -(sol.position_error + sol.rotation_error)

        best = None
        for attempt in range(_RESTARTS + 1):
            q0 = self._from_arm(q_arm0) if attempt == 0 else lo + (hi - lo) * rng.random(lo.size)
            sol = solve_frame_ik(self.model, self.data, self.ee, target, q0, self.lower, self.upper, max_iter=300)
            if best is None or rank(sol) > rank(best):
                best = sol
            if sol.reachable and not sol.at_limit:
                break
        return best, best.q[self.index]


def assembly_phases(sm, spec, loaded=None):
    """``spec`` (a SimulationSpec) with its assembly tasks appended to ``phases`` (unchanged without
    ``assembly``). InputError (exit 2, at the task) when a slot or place pose is out of the arm's reach."""
    from sms_cli.sim.schema import PhaseSpec, Waypoint

    asm = spec.assembly
    if asm is None:
        return spec
    try:
        ik = ArmIk(sm)
    except ValueError as exc:
        raise InputError(problems=[Problem(str(exc), _locate(loaded, ("simulation", "assembly")), "simulation.assembly",
                                           "assembly tasks need an arm of revolute and prismatic joints")]) from None
    names = [a.name for a in sm.arm]
    grasp = grasp_pose(asm.grasp)
    q_arm = np.asarray(sm.q0)[[a.q_index for a in sm.arm]].copy()
    home = q_arm.copy()

    def move(name: str, kind: str, frame: str, path: tuple) -> PhaseSpec:
        nonlocal q_arm
        sol, q_new = ik.solve(ik.frame_pose(frame) * grasp, q_arm)
        if not sol.reachable:
            raise InputError(problems=[Problem(
                f"the end effector cannot reach frame '{frame}': the closest arm configuration leaves it "
                f"{sol.position_error * 1e3:.4g} mm and {np.degrees(sol.rotation_error):.4g} deg away"
                + (f", with {', '.join(names[i] for i in _arm_at_limit(ik, sol))} on a limit" if sol.at_limit else ""),
                _locate(loaded, path), ".".join(map(str, path)),
                "move the frame within the arm's reach (sms analyze maps the workspace) or pick another slot")])
        q_arm = q_new
        return PhaseSpec(name=name, kind=kind, duration="auto",
                         waypoints=[Waypoint(joints={n: float(v) for n, v in zip(names, q_new)})])

    phases = list(spec.phases)
    for i, task in enumerate(asm.tasks):
        carried: list[str] = []
        for j, k in enumerate(task.pick):
            tile = tile_name(asm, k)
            phases.append(move(f"t{i + 1}_reach_{tile}", "move_payload" if carried else "deploy",
                               asm.store.format(index=k), ("simulation", "assembly", "tasks", i, "pick", j)))
            phases.append(PhaseSpec(name=f"t{i + 1}_grasp_{tile}", kind="grasp", duration=asm.dwell,
                                    detach=[f"{tile}@store"], attach=[tile]))
            carried.append(tile)
        phases.append(move(f"t{i + 1}_carry", "move_payload", task.place, ("simulation", "assembly", "tasks", i, "place")))
        phases.append(PhaseSpec(name=f"t{i + 1}_release", kind="release", duration=asm.dwell, detach=carried,
                                attach=[f"{t}@{task.place}" for t in carried]))
    if asm.return_home:
        phases.append(PhaseSpec(name="return_home", kind="deploy", duration="auto",
                                waypoints=[Waypoint(joints={n: float(v) for n, v in zip(names, home)})]))
    return spec.model_copy(update={"phases": phases, "assembly": None})


def _arm_at_limit(ik: ArmIk, sol) -> list[int]:
    return [ik.index.index(j) for j in sol.at_limit if j in ik.index]


def _locate(loaded, path: tuple):
    return None if loaded is None else loaded.source.locate(path)
