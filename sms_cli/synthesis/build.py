"""From a compiled ``SystemModel`` and the mission's ``synthesis:`` section to the inputs of the
solvers: LMI ``SynthesisRequest`` (Kraiem 2022), worst-case inertias and disturbance bounds (PD,
LQR, SMC).

Frames and units: actuator coordinates q = [wheel angles; arm joints] (rad or m, v-index order);
base attitude axes are the base frame's x, y, z; inertias in kg m², torques in N m, SI throughout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sms_cli.errors import InputError, Problem
from sms_cli.synthesis.lmi import ErrorModel, SynthesisRequest, ellipsoid_from_box
from sms_cli.synthesis.reduced import configuration, error_model, model_index, sample_configurations
from sms_cli.synthesis.regions import PoleRegion


@dataclass
class LmiSetup:
    request: SynthesisRequest
    actuators: list[str]
    state_names: list[str]
    torque_limit: np.ndarray  # N m (or N), inf where unknown
    configurations: list[np.ndarray]  # q of every linearisation, nominal first


def region(spec) -> PoleRegion:
    return PoleRegion(float(spec.decay_rate), float(spec.min_damping), float(spec.max_frequency))


def torque_limits(sm, spec) -> np.ndarray:
    """Per actuator (wheels, then arm): the wheel's max_torque, the joint's URDF effort, or the
    synthesis section's ``max_torque`` where the URDF has none; inf when nothing is known."""
    out = [float(w.max_torque) if w.max_torque and np.isfinite(w.max_torque) else np.inf for w in sm.wheels]
    for j in sm.arm:
        e = float(j.max_effort) if j.max_effort is not None else np.inf
        if not np.isfinite(e) or e <= 0:
            e = float(spec.max_torque) if spec.max_torque is not None else np.inf
        out.append(e)
    return np.asarray(out, dtype=float)


def lmi_setup(sm, spec) -> LmiSetup:
    """The Kraiem 2022 request: nominal = the mission's initial configuration (+ the listed extra
    configurations), samples = random arm configurations in a box of half-width ``spread``."""
    lspec = spec.lmi
    ix, names, fnames = model_index(sm)
    if len(names) == 0:
        raise InputError("LMI synthesis needs actuators (reaction wheels or arm joints)",
                         [Problem("the robot has no wheel and no arm joint", field="synthesis.law",
                                  hint="use law: pd, lqr or smc for a base-only robot")])
    if len(fnames) == 0:
        raise InputError("LMI synthesis (Kraiem 2022) estimates flexible states: the robot has none",
                         [Problem("no appendage modes and no spring joints", field="synthesis.law",
                                  hint="use law: pd or lqr, or add appendages")])
    qs = [np.asarray(sm.q0, dtype=float)]
    for k, conf in enumerate(lspec.sampling.configurations):
        try:
            qs.append(configuration(sm, sm.q0, conf))
        except KeyError as exc:
            raise InputError(f"unknown joint {exc} in synthesis.lmi.sampling.configurations",
                             [Problem(f"unknown joint {exc}", field=f"synthesis.lmi.sampling.configurations.{k}",
                                      hint="known: " + ", ".join(j.name for j in sm.arm))]) from None
    nominal = [error_model(sm, q, "nominal" if i == 0 else f"configuration_{i}") for i, q in enumerate(qs)]
    samp_q = sample_configurations(sm, np.asarray(sm.q0, dtype=float), lspec.sampling.samples,
                                   float(lspec.sampling.spread), lspec.sampling.seed)
    samples = [error_model(sm, q, f"sample_{k + 1}") for k, q in enumerate(samp_q)]
    n_f = len(fnames)
    ie = lspec.initial_errors
    bounds = [ie.modal_displacement] * n_f + [ie.base_rate] * 3 + [ie.modal_rate] * n_f
    ndo = lspec.variant == "ndi_observer_ndo"
    n_q = len(names)
    n_total = len(bounds) + (n_q if ndo else 0)
    E_e = ellipsoid_from_box(np.asarray(bounds, dtype=float), n_total)
    E_d = ellipsoid_from_box(np.full(n_q, float(ie.disturbance_torque)), n_total) if ndo else None
    tau = torque_limits(sm, spec)
    all_models = nominal + samples
    m_dia = np.max([np.diag(m.M) for m in all_models], axis=0)
    accel = tau / m_dia  # rad/s² (m/s²): authority of the feedback on the heaviest configuration
    amp = float(ie.tracking) if ie.tracking is not None else float(lspec.tracking_error_amplitude)
    rate = float(ie.tracking_rate) if ie.tracking_rate is not None else 0.0
    tracking = np.tile([amp, rate], (n_q, 1))
    req = SynthesisRequest(
        nominal=nominal, controller_region=region(lspec.controller_region),
        observer_region=region(lspec.observer_region or lspec.controller_region), E_e=E_e, samples=samples,
        relaxation=lspec.relaxation, accel_limit=accel if np.any(np.isfinite(accel)) else None,
        tracking=tracking, E_d=E_d, variant=lspec.variant)
    states = list(fnames) + ["w0_x", "w0_y", "w0_z"] + [f"{n}_rate" for n in fnames]
    return LmiSetup(req, names, states, tau, qs + list(samp_q))


# ---------------------------------------------------------------------------------------
# classical laws: the base attitude axes


def locked_inertia(sm, q) -> np.ndarray:
    """Base attitude inertia with the arm locked and the translation free (kg m², base frame):
    H_ω − H_ωL H_L⁻¹ H_Lω (Schur complement of the linear block; wheels counted as locked)."""
    b = sm.blocks(q)
    J = b["H_omega"] - b["H_omegaL"] @ np.linalg.solve(b["H_L"], b["H_omegaL"].T)
    return (J + J.T) / 2


def workspace_configurations(sm, spec) -> list[np.ndarray]:
    ws = spec.workspace
    q0 = np.asarray(sm.q0, dtype=float)
    return [q0] + sample_configurations(sm, q0, ws.samples, float(ws.spread), ws.seed)


def inertia_range(sm, qs) -> tuple[np.ndarray, np.ndarray]:
    """Per base axis (x, y, z): the largest and smallest diagonal locked inertia over qs."""
    d = np.array([np.diag(locked_inertia(sm, q)) for q in qs])
    return d.max(axis=0), d.min(axis=0)


def arm_disturbance_bound(sm, qs, joint_accel: float, joint_rate: float) -> np.ndarray:
    """Per base axis: a bound on the reaction torque of the arm motion on the base (N m),
    Σ_j |H_ωm,ij| q̈_max + max |Coriolis| over joint-rate sign patterns, over the configurations qs.
    Convective terms from the bias forces at base rest (the arm moves, the base is held)."""
    ia = np.asarray(sm.idx.arm, dtype=int)
    ang = np.asarray(sm.idx.base_angular, dtype=int)
    out = np.zeros(3)
    if len(ia) == 0:
        return out
    rng = np.random.default_rng(0)
    patterns = [np.ones(len(ia))] + [rng.choice([-1.0, 1.0], len(ia)) for _ in range(7)]
    for q in qs:
        H = sm.mass_matrix(q)[: sm.nv, : sm.nv]
        inertial = np.abs(H[np.ix_(ang, ia)]).sum(axis=1) * joint_accel
        cor = np.zeros(3)
        for p in patterns:
            v = np.zeros(sm.nv)
            v[ia] = p * joint_rate
            h = sm.bias_forces(q, v, np.zeros(sm.n_modes))[: sm.nv]
            cor = np.maximum(cor, np.abs(h[ang]))
        out = np.maximum(out, inertial + cor)
    return out


def region_of_pd(spec_pd) -> PoleRegion:
    """The region a PD (ω_n, ζ) request implies, used for the pole map: decay ζω_n, disk ω_n."""
    return PoleRegion(float(spec_pd.damping * spec_pd.bandwidth) * (1 - 1e-9) if spec_pd.damping < 1
                      else float(spec_pd.bandwidth * (spec_pd.damping - np.sqrt(spec_pd.damping**2 - 1))) * (1 - 1e-9),
                      float(min(spec_pd.damping, 0.999999)), float(spec_pd.bandwidth) * (1 + 1e-9))


def error_models(setup: LmiSetup) -> list[ErrorModel]:
    return setup.request.linearisations()
