"""Can a facility robot follow its commanded mock-up poses? Inverse kinematics per sample with Pinocchio.

The robot is a fixed-base URDF (``pinocchio.buildModelFromUrdf``, no free flyer) placed at ``base``
(world<-robot base) in the facility world; the mock-up is bolted to ``tool_frame`` with
``flange_to_mockup`` (tool<-mock-up). The tool pose that puts the mock-up at g_HW(t) is therefore, in
the robot's base frame, ``base⁻¹ g_HW(t) flange_to_mockup⁻¹``.

Solver: ``sms_cli.model.ik.solve_frame_ik`` (damped least squares closed-loop IK, joint limits
enforced by projection), warm-started from the previous sample's solution (the first sample from ``home``, then
a few deterministic restarts). A sample is reachable when the converged tool pose is within
:data:`POSITION_TOL` (1 mm) and :data:`ROTATION_TOL` (0.1 deg) of the target; otherwise the finding says
whether the solver stopped against a joint limit or simply short of the pose (out of reach).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sms_cli.errors import InputError, Location, Problem
from sms_cli.hil.poses import compose, inverse
from sms_cli.model.ik import POSITION_TOL, ROTATION_TOL, IkSolution, solve_frame_ik


@dataclass
class FacilityRobot:
    """A fixed-base robot of the facility. ``base``, ``flange_to_mockup``: (7,) pose rows."""

    role: str
    model: object
    tool: int
    tool_name: str
    base: np.ndarray
    flange_to_mockup: np.ndarray
    home: np.ndarray
    joint_names: list[str]
    urdf: Path
    data: object = field(init=False)

    def __post_init__(self) -> None:
        self.data = self.model.createData()
        self.lower = np.array(self.model.lowerPositionLimit, dtype=float)
        self.upper = np.array(self.model.upperPositionLimit, dtype=float)

    def tool_targets(self, mockup_poses: np.ndarray) -> np.ndarray:
        """Tool poses (n, 7) in the robot's base frame that put the mock-up at ``mockup_poses`` (facility world)."""
        return compose(inverse(self.base), compose(mockup_poses, inverse(self.flange_to_mockup)))

    def tool_pose(self, q: np.ndarray):
        """``pinocchio.SE3`` of the tool frame in the robot's base frame at joint angles ``q`` (rad)."""
        import pinocchio as pin

        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.tool].copy()

    def mockup_pose(self, q: np.ndarray) -> np.ndarray:
        """The mock-up's pose row in the facility world at ``q`` (forward kinematics)."""
        from sms_cli.hil.poses import pose_row

        return compose(self.base, compose(pose_row(self.tool_pose(q)), self.flange_to_mockup))


def load_robot(role: str, urdf: Path, tool_frame: str, base: np.ndarray, flange_to_mockup: np.ndarray,
               home: list[float] | None, where_urdf: Location, where_tool: Location, where_home: Location) -> FacilityRobot:
    """A facility robot from its URDF (linted first, so a bad file reads as file:line)."""
    import pinocchio as pin

    from sms_cli.errors import Warnings
    from sms_cli.model.build import captured_c_stderr, find_frame
    from sms_cli.model.urdf_lint import lint_urdf

    lint_urdf(urdf, Warnings(), where_urdf)
    with captured_c_stderr():
        try:
            model = pin.buildModelFromUrdf(str(urdf))
        except Exception:  # noqa: BLE001 - pinocchio raises ValueError/RuntimeError
            raise InputError(problems=[Problem("Pinocchio could not build a fixed-base model of this URDF", where_urdf,
                                               hint="check the file with sms compile on a mission that uses it")]) from None
    joint_names = [model.names[j] for j in range(1, model.njoints)]
    if model.nq != model.nv or model.nq == 0:
        raise InputError(problems=[Problem(f"the robot must have revolute or prismatic joints only ({model.nq} "
                                           f"coordinates for {model.nv} velocities)", where_urdf,
                                           hint="give continuous joints position limits (type revolute)")])
    fid = find_frame(model, tool_frame)
    if fid is None:
        names = [f.name for f in model.frames if f.name != "universe"]
        close = difflib.get_close_matches(tool_frame, names, n=1)
        raise InputError(problems=[Problem(f"no link or frame named '{tool_frame}' in {urdf.name}", where_tool, "robot.tool_frame",
                                           f"did you mean '{close[0]}'?" if close else "links: " + ", ".join(names))])
    q0 = np.zeros(model.nq) if home is None else np.array(home, dtype=float)
    if q0.size != model.nq:
        raise InputError(problems=[Problem(f"home has {q0.size} joint angles, the robot has {model.nq} joints "
                                           f"({', '.join(joint_names)})", where_home, "robot.home")])
    lo, hi = np.array(model.lowerPositionLimit), np.array(model.upperPositionLimit)
    outside = np.nonzero((q0 < lo) | (q0 > hi))[0]
    if outside.size:
        j = int(outside[0])
        raise InputError(problems=[Problem(f"home puts {joint_names[j]} at {np.degrees(q0[j]):.6g} deg, outside its limits "
                                           f"[{np.degrees(lo[j]):.6g}, {np.degrees(hi[j]):.6g}] deg", where_home, "robot.home")])
    return FacilityRobot(role, model, fid, tool_frame, np.asarray(base, float), np.asarray(flange_to_mockup, float), q0,
                         joint_names, urdf)


def solve_ik(robot: FacilityRobot, target, q0: np.ndarray) -> IkSolution:
    """Damped least squares CLIK from ``q0`` to the tool pose ``target`` (``pinocchio.SE3``, robot base frame)."""
    return solve_frame_ik(robot.model, robot.data, robot.tool, target, q0, robot.lower, robot.upper)


def _seeds(robot: FacilityRobot, n: int = 8) -> list[np.ndarray]:
    """Start configurations of the first sample: home, then deterministic draws inside the limits."""
    rng = np.random.default_rng(20230)
    lo, hi = robot.lower, robot.upper
    return [robot.home] + [lo + (hi - lo) * rng.random(lo.size) for _ in range(n - 1)]


@dataclass
class Reach:
    """Reachability of a trajectory: joint angles (n, nq) rad, residuals (n,) m and rad, reachable (n,),
    and the first unreachable sample with why (None: all reachable)."""

    robot: FacilityRobot
    q: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray
    reachable: np.ndarray
    first_unreachable: int | None
    reason: str

    def summary(self, t: np.ndarray) -> dict:
        k = self.first_unreachable
        return {
            "role": self.robot.role,
            "urdf": str(self.robot.urdf),
            "tool_frame": self.robot.tool_name,
            "joints": self.robot.joint_names,
            "samples": int(self.q.shape[0]),
            "all_reachable": k is None,
            "first_unreachable_s": None if k is None else float(t[k]),
            "reason": self.reason,
            "unreachable_samples": int(np.count_nonzero(~self.reachable)),
            "max_position_error_m": float(self.position_error.max()),
            "max_rotation_error_deg": float(np.degrees(self.rotation_error.max())),
            "joint_min_deg": np.degrees(self.q.min(axis=0)).tolist(),
            "joint_max_deg": np.degrees(self.q.max(axis=0)).tolist(),
        }


def reach_trajectory(robot: FacilityRobot, mockup_poses: np.ndarray) -> Reach:
    """IK of every commanded mock-up pose (n, 7) in the facility world, warm-started sample to sample."""
    import pinocchio as pin

    targets = robot.tool_targets(np.atleast_2d(mockup_poses))
    n = targets.shape[0]
    Q = np.empty((n, robot.model.nq))
    pe, re = np.empty(n), np.empty(n)
    ok = np.empty(n, dtype=bool)
    first, reason = None, "all reachable"
    q = robot.home
    for k in range(n):
        target = pin.XYZQUATToSE3(targets[k])
        if k == 0:
            sols = []
            for seed in _seeds(robot):
                sols.append(solve_ik(robot, target, seed))
                if sols[-1].reachable:
                    break
            sol = min(sols, key=lambda s: (not s.reachable, s.position_error + s.rotation_error))
        else:
            sol = solve_ik(robot, target, q)
        q = sol.q
        Q[k], pe[k], re[k], ok[k] = sol.q, sol.position_error, sol.rotation_error, sol.reachable
        if first is None and not sol.reachable:
            first = k
            miss = f"{sol.position_error * 1e3:.4g} mm, {np.degrees(sol.rotation_error):.4g} deg short of the pose"
            if sol.at_limit:
                names = ", ".join(robot.joint_names[j] for j in sol.at_limit)
                reason = f"joint limit ({names}); {miss}"
            else:
                reason = f"out of reach; {miss}"
    return Reach(robot, Q, pe, re, ok, first, reason)


__all__ = ["FacilityRobot", "IkSolution", "Reach", "load_robot", "reach_trajectory", "solve_ik",
           "POSITION_TOL", "ROTATION_TOL"]
