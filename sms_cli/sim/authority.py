"""Joint moves sized from the actuator authority (phases of ``duration: auto``), and the demand of
given moves on the actuators (``sms compile``'s move table).

Each waypoint segment is a rest-to-rest quintic q(t) = q_a + p(t/T)(q_b − q_a). Along it the base is
held at rest by the wheels (ω = 0, ω̇ = 0) at zero total momentum (Kraiem 2022 (4.51)); base
translation and wheel rates follow from the momentum (``zero_momentum_rates``), the base linear
acceleration and wheel accelerations from the six base rows of the rigid equations of motion, and the
wheel and joint torques from the other rows (rigid inverse dynamics, modes at rest, payloads as
attached in that phase). With no external force every term scales with the time scaling: torque as
1/T², rates as 1/T. So one evaluation at T = 1 s gives, in closed form, the shortest duration at
which each actuator stays within a fraction of its limit, and which actuator sets it.

Velocity order is Pinocchio's (DESIGN.md §3): base linear (base frame), base angular (base frame),
joints. Torques in N m (revolute) or N (prismatic); rates in rad/s or m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from sms_cli.dynamics.locked import reduced_coupling
from sms_cli.model.system import SystemModel
from sms_cli.sim.references import JointProfile, quintic

SAMPLES_PER_SEGMENT = 201  # quintic blend sampled at s = k/200: peaks within 1e-4 relative of the true ones


def zero_momentum_rates(sm: SystemModel, q: np.ndarray, qd_arm: np.ndarray, H: np.ndarray | None = None) -> np.ndarray:
    """Generalized velocity (nv) with the base not rotating (ω = 0), the arm at ``qd_arm`` and zero total
    momentum: base linear velocity from the linear rows, wheel rates the least-norm solution of the
    angular rows (Kraiem 2022 (3.66)/(4.51): q̇_r = −H0r⁺ H0m q̇_m with the base translation reduced out).
    ``H`` is the rigid mass matrix at q when the caller has it."""
    H = sm.rigid_mass_matrix(q) if H is None else H
    v = np.zeros(sm.nv)
    v[sm.idx.arm] = qd_arm
    _base_rows_solve(sm, H, -H[:6] @ v, v)
    return v


def _base_rows_solve(sm: SystemModel, H: np.ndarray, rhs6: np.ndarray, x: np.ndarray) -> None:
    """Fill x's base-linear and wheel entries so that H[:6] x = rhs6 + H[:6] x_given (x_given: the other
    entries of x, already set; ω entries stay 0): linear part by elimination, wheels least-norm."""
    lin, ang, w = sm.idx.base_linear, sm.idx.base_angular, sm.idx.wheels
    # linear rows: m I a_lin + H_l,ang·0 + H_l,w x_w = rhs_l ; wheels are balanced (H_l,w = 0 within round-off)
    A_ll = H[np.ix_(lin, lin)]
    A_lw = H[np.ix_(lin, w)]
    A_al = H[np.ix_(ang, lin)]
    # reduce the linear unknowns out: x_l = A_ll⁻¹ (rhs_l − A_lw x_w)
    Ai_rl = np.linalg.solve(A_ll, rhs6[:3])
    Ai_lw = np.linalg.solve(A_ll, A_lw) if w.size else np.zeros((3, 0))
    if w.size:
        red = reduced_coupling(H, w)  # G J = A_aw − A_al Ai_lw (sms_cli.dynamics.locked)
        x[w] = np.linalg.pinv(red) @ (rhs6[3:] - A_al @ Ai_rl)
        x[lin] = Ai_rl - Ai_lw @ x[w]
    else:
        x[lin] = Ai_rl


@dataclass
class SegmentDemand:
    """Peaks along one segment at T = 1 s (torque ∝ 1/T², rates ∝ 1/T, base acceleration ∝ 1/T²)."""

    torque: dict[str, float]          # actuator -> peak |τ| (N m or N) at T = 1 s
    rate: dict[str, float]            # actuator -> peak |q̇| (rad/s or m/s) at T = 1 s
    base_acceleration: float          # peak |ω̇| the wheels must cancel (rad/s²) at T = 1 s: H̃_ωω⁻¹ H̃_ωr q̈_r


@dataclass
class MovePlan:
    """One rest-to-rest segment of a joint-waypoint phase."""

    phase: str
    segment: int                      # 1-based waypoint index within the phase
    given_s: float | None             # the mission's segment duration (None for duration: auto)
    shortest_s: float                 # at 100 % of every limit
    limited_by: str                   # "<actuator> torque" or "<actuator> speed"
    chosen_s: float                   # duration the simulation uses
    demand: SegmentDemand = field(repr=False)
    torque_fraction: float = 0.0      # peak |τ|/τ_max over actuators at chosen_s
    speed_fraction: float = 0.0       # peak |q̇|/q̇_max over actuators at chosen_s
    base_acceleration: float = 0.0    # rad/s² at chosen_s

    def as_dict(self) -> dict:
        return {"phase": self.phase, "segment": self.segment, "given_s": self.given_s, "shortest_s": self.shortest_s,
                "limited_by": self.limited_by, "duration_s": self.chosen_s, "torque_fraction": self.torque_fraction,
                "speed_fraction": self.speed_fraction, "base_acceleration_rad_s2": self.base_acceleration}


def _limits(sm: SystemModel) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Actuator names (wheels, then arm), velocity indices, torque limits, speed limits (inf: none)."""
    names = [w.name for w in sm.wheels] + [a.name for a in sm.arm]
    idx = np.concatenate([sm.idx.wheels, sm.idx.arm]).astype(int)
    tau_max = np.array([w.max_torque for w in sm.wheels] + [a.max_effort for a in sm.arm], float)
    rate_max = np.array([w.max_speed for w in sm.wheels] + [a.max_velocity for a in sm.arm], float)
    return names, idx, tau_max, rate_max


def reference_dynamics(sm: SystemModel, q: np.ndarray, qd_arm: np.ndarray, qdd_arm: np.ndarray,
                       data: pin.Data | None = None, H: np.ndarray | None = None):
    """(v, a, τ) of the reference at configuration q: the base held at rest by the wheels (ω = ω̇ = 0) at
    zero momentum while the arm moves at (qd_arm, qdd_arm). τ (nv) has zero base wrench; its wheel and
    arm entries are the torques the actuators must give (rigid model, modes at rest)."""
    d = pin.Data(sm.model) if data is None else data
    H = sm.rigid_mass_matrix(q) if H is None else H
    v = zero_momentum_rates(sm, q, qd_arm, H)
    a = np.zeros(sm.nv)
    a[sm.idx.arm] = qdd_arm
    h = pin.nonLinearEffects(sm.model, d, q, v)
    _base_rows_solve(sm, H, -(H[:6] @ a) - h[:6], a)
    return v, a, H @ a + h


def segment_demand(sm: SystemModel, q_start: np.ndarray, arm_from: np.ndarray, arm_to: np.ndarray,
                   samples: int = SAMPLES_PER_SEGMENT, duration: float = 1.0) -> SegmentDemand:
    """Inverse dynamics along the quintic from ``arm_from`` to ``arm_to`` over ``duration`` (1 s: the
    reference the planner scales), the rest of the configuration (base pose, wheel angles) from ``q_start``."""
    names, idx, _, _ = _limits(sm)
    d = pin.Data(sm.model)
    w_idx, ang, lin = sm.idx.wheels, sm.idx.base_angular, sm.idx.base_linear
    delta = np.asarray(arm_to, float) - np.asarray(arm_from, float)
    tau_peak = np.zeros(len(names))
    rate_peak = np.zeros(len(names))
    acc_peak = 0.0
    q = np.array(q_start, float)
    for s in np.linspace(0.0, 1.0, samples):
        p, dp, ddp = quintic(float(s))
        q[sm.idx.q_arm] = arm_from + p * delta
        H = sm.rigid_mass_matrix(q)
        v, a, tau = reference_dynamics(sm, q, dp / duration * delta, ddp / duration**2 * delta, d, H)
        tau_peak = np.maximum(tau_peak, np.abs(tau[idx]))
        rate_peak = np.maximum(rate_peak, np.abs(v[idx]))
        if w_idx.size:  # base angular acceleration the wheels' reaction cancels (translation reduced out)
            Hr = H[np.ix_(ang, ang)] - H[np.ix_(ang, lin)] @ np.linalg.solve(H[np.ix_(lin, lin)], H[np.ix_(lin, ang)])
            acc_peak = max(acc_peak, float(np.linalg.norm(np.linalg.solve(Hr, H[np.ix_(ang, w_idx)] @ a[w_idx]))))
    return SegmentDemand(dict(zip(names, tau_peak.tolist())), dict(zip(names, rate_peak.tolist())), acc_peak)


def shortest_duration(sm: SystemModel, demand: SegmentDemand, torque_fraction: float = 1.0,
                      speed_fraction: float = 1.0) -> tuple[float, str]:
    """(T, what sets it): the least T with every peak torque ≤ torque_fraction·τ_max (τ(T) = τ(1)/T²) and
    every peak rate ≤ speed_fraction·q̇_max (q̇(T) = q̇(1)/T)."""
    names, _, tau_max, rate_max = _limits(sm)
    best, why = 0.0, "no actuator limit"
    for i, n in enumerate(names):
        if math.isfinite(tau_max[i]) and tau_max[i] > 0:
            T = math.sqrt(demand.torque[n] / (torque_fraction * tau_max[i]))
            if T > best:
                best, why = T, f"{n} torque"
        if math.isfinite(rate_max[i]) and rate_max[i] > 0:
            T = demand.rate[n] / (speed_fraction * rate_max[i])
            if T > best:
                best, why = T, f"{n} speed"
    return best, why


def _fractions(sm: SystemModel, demand: SegmentDemand, T: float) -> tuple[float, float]:
    names, _, tau_max, rate_max = _limits(sm)
    tf = max((demand.torque[n] / T**2 / tau_max[i] for i, n in enumerate(names)
              if math.isfinite(tau_max[i]) and tau_max[i] > 0), default=0.0)
    sf = max((demand.rate[n] / T / rate_max[i] for i, n in enumerate(names)
              if math.isfinite(rate_max[i]) and rate_max[i] > 0), default=0.0)
    return tf, sf


def plan_moves(sm: SystemModel, spec) -> list[MovePlan]:
    """Every joint-waypoint segment of ``spec`` (a SimulationSpec) in phase order: demand, shortest
    duration, the duration used (given, or sized for ``duration: auto``). Payloads are attached and
    released as the phases do, and restored afterwards. Phases after an end-effector phase are not
    planned (their start configuration is known only by simulating)."""
    auto = spec.auto_duration
    names = [a.name for a in sm.arm]
    state = {n: p.attached for n, p in sm.payloads.items()}
    q = sm.q0.copy()
    arm_ref = q[sm.idx.q_arm].copy()
    plans: list[MovePlan] = []
    try:
        for phase in spec.phases:
            for n in phase.detach:
                sm.detach_payload(n)
            for n in phase.attach:
                sm.attach_payload(n)
            if phase.end_effector is not None:
                if any(p.duration == "auto" for p in spec.phases[spec.phases.index(phase):]):
                    raise ValueError(f"phase '{phase.name}' tracks the end effector: later phases of duration 'auto' "
                                     "have no known start configuration")
                break
            if not phase.waypoints or phase.joint_profile == "step":
                continue
            profile = JointProfile(arm_ref, names, [type(w)(at=k + 1.0, joints=w.joints) for k, w in enumerate(phase.waypoints)])
            t_prev = 0.0
            for k in range(1, len(profile.points)):
                dem = segment_demand(sm, q, profile.points[k - 1], profile.points[k])
                t_min, why = shortest_duration(sm, dem)
                if phase.duration == "auto":
                    t_need, _ = shortest_duration(sm, dem, auto.torque_fraction, auto.speed_fraction)
                    chosen = max(auto.round_to, math.ceil(t_need / auto.round_to - 1e-9) * auto.round_to)
                    given = None
                else:
                    at = phase.waypoints[k - 1].at
                    chosen = given = at - t_prev
                    t_prev = at
                tf, sf = _fractions(sm, dem, chosen)
                plans.append(MovePlan(phase.name, k, given, t_min, why, chosen, dem, tf, sf,
                                      dem.base_acceleration / chosen**2))
            arm_ref = profile.final
    finally:
        for n, attached in state.items():
            (sm.attach_payload if attached else sm.detach_payload)(n)
    return plans


def resolve_durations(spec, plans: list[MovePlan]):
    """``spec`` with every ``duration: auto`` phase given its sized segments (waypoint times) and length."""
    if not any(p.duration == "auto" for p in spec.phases):
        return spec
    by_phase: dict[str, list[MovePlan]] = {}
    for mp in plans:
        by_phase.setdefault(mp.phase, []).append(mp)
    phases = []
    for phase in spec.phases:
        if phase.duration != "auto":
            phases.append(phase)
            continue
        t, wps = 0.0, []
        for w, mp in zip(phase.waypoints, by_phase[phase.name]):
            t += mp.chosen_s
            wps.append(w.model_copy(update={"at": t}))
        phases.append(phase.model_copy(update={"waypoints": wps, "duration": t + spec.auto_duration.hold_after}))
    return spec.model_copy(update={"phases": phases})


def format_moves(plans: list[dict], auto) -> list[str]:
    """Lines of ``sms compile``'s move table (``plans``: MovePlan.as_dict() rows)."""
    if not plans:
        return []
    lines = ["moves     phase            seg  shortest (s)  set by                        duration (s)  torque  speed",
             f"          (shortest: the reference needs 100 % of a limit; 'auto' segments need <= {auto.torque_fraction:.0%}"
             f" of every torque and <= {auto.speed_fraction:.0%} of every speed limit; torque/speed: the largest share"
             " of a limit at the duration used)"]
    for p in plans:
        tag = "" if p["given_s"] is not None else " auto"
        over = "  OVER A LIMIT" if p["torque_fraction"] > 1 or p["speed_fraction"] > 1 else ""
        lines.append(f"          {p['phase'][:16]:<16} {p['segment']:>3}  {p['shortest_s']:>12.1f}  {p['limited_by'][:28]:<28}"
                     f" {p['duration_s']:>9.1f}{tag:<5} {p['torque_fraction']:>6.0%} {p['speed_fraction']:>6.0%}{over}")
    return lines
