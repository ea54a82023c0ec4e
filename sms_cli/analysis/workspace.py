"""A workspace study: the samples, and one index kernel per design variant (nominal first).

Limits (SI): joint speed rad/s or m/s, joint effort N m or N, wheel speed rad/s; a URDF limit
of 0 or none counts as missing. Variants share the samples, so their indices compare sample by
sample. A variant that only scales wheel spin inertia of base-mounted wheels reuses the
nominal CRBA: the rotor adds δ a aᵀ to its body, so M gains δ u uᵀ with u selecting the base
angular rate along the axis a (R_sat) and the wheel rate (exact; tested against a CRBA).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field

import numpy as np

from sms_cli.analysis.indices import ArmLayout, IndexKernel
from sms_cli.analysis.sampling import JointRange, Sampler
from sms_cli.analysis.schema import AnalysisSpec, VariantSpec
from sms_cli.errors import InputError, Location, Problem


@dataclass
class Variant:
    """One design variant: its kernel and, when it only changes wheel inertia, the mass-matrix update."""

    name: str
    kernel: IndexKernel
    mass_update: tuple[np.ndarray, np.ndarray] | None = None  # (v indices, dense ΔM block)
    limits: dict = field(default_factory=dict)


def _where(loaded, *path) -> Location | None:
    if loaded is None:
        return None
    try:
        return loaded.source.locate(("analysis",) + tuple(path))
    except Exception:  # noqa: BLE001 - a location is a courtesy, never a failure
        return Location(loaded.path)


def _unknown(name: str, known: list[str], loaded, path: tuple, what: str) -> InputError:
    close = difflib.get_close_matches(name, known, n=1)
    hint = f"did you mean '{close[0]}'?" if close else f"known: {', '.join(known) or 'none'}"
    return InputError(problems=[Problem(f"unknown name '{name}'", _where(loaded, *path), what, hint)])


def _per_name(value, names: list[str], default: np.ndarray, loaded, path: tuple, what: str) -> np.ndarray:
    """A limit vector from a scalar or a {name: value} override over ``default``."""
    out = np.array(default, dtype=float)
    if value is None:
        return out
    if isinstance(value, dict):
        for key, v in value.items():
            if key not in names:
                raise _unknown(key, names, loaded, path + (key,), what)
            out[names.index(key)] = float(v)
        return out
    out[:] = float(value)
    return out


def _positive_or_inf(x) -> float:
    x = float(x)
    return x if math.isfinite(x) and x > 0 else math.inf


def actuated_arm(sm, spec: AnalysisSpec, loaded=None) -> list:
    """The arm joints the indices treat as actuated (``analysis.arm_joints``, default all)."""
    if spec.arm_joints is None:
        return list(sm.arm)
    names = [a.name for a in sm.arm]
    for i, n in enumerate(spec.arm_joints):
        if n not in names:
            raise _unknown(n, names, loaded, ("arm_joints", i), "analysis.arm_joints")
    return [sm.arm[names.index(n)] for n in spec.arm_joints]


def joint_ranges(sm, spec: AnalysisSpec, loaded=None) -> tuple[list[JointRange], list[int]]:
    """Sampled joints (positions in the actuated arm list) and their ranges (limits, overrides, symmetry)."""
    arm = actuated_arm(sm, spec, loaded)
    names = [a.name for a in arm]
    samp = spec.sampling
    chosen = samp.joints if samp.joints is not None else names
    sampled = []
    for i, n in enumerate(chosen):
        if n not in names:
            raise _unknown(n, names, loaded, ("sampling", "joints", i), "analysis.sampling.joints")
        sampled.append(names.index(n))
    for n in samp.ranges:
        if n not in chosen:
            raise _unknown(n, chosen, loaded, ("sampling", "ranges", n), "analysis.sampling.ranges")
    ranges = []
    for j in sampled:
        a = arm[j]
        if a.name in samp.ranges:
            lo, hi = samp.ranges[a.name]
            periodic = a.kind != "prismatic" and hi - lo >= 2 * math.pi - 1e-9
        elif math.isfinite(a.lower) and math.isfinite(a.upper) and a.upper > a.lower:
            lo, hi = a.lower, a.upper
            periodic = a.kind != "prismatic" and hi - lo >= 2 * math.pi - 1e-9
        elif a.kind in ("revolute", "continuous"):
            lo, hi, periodic = -math.pi, math.pi, True
        else:
            raise InputError(problems=[Problem(
                f"prismatic joint '{a.name}' has no position limits to sample", _where(loaded, "sampling"),
                "analysis.sampling.ranges", f"add ranges: {{{a.name}: [lower, upper]}}")])
        ranges.append(JointRange(a.name, float(lo), float(hi), periodic))
    if samp.symmetry is not None:
        sym = samp.symmetry
        names_s = [r.name for r in ranges]
        if sym.joint not in names_s:
            raise _unknown(sym.joint, names_s, loaded, ("sampling", "symmetry", "joint"), "analysis.sampling.symmetry")
        k = names_s.index(sym.joint)
        try:
            ranges[k] = ranges[k].halved(sym.keep, sym.about)
        except ValueError as exc:
            raise InputError(problems=[Problem(str(exc), _where(loaded, "sampling", "symmetry", "about"),
                                               "analysis.sampling.symmetry.about")]) from None
    return ranges, sampled


def make_sampler(sm, spec: AnalysisSpec, loaded=None) -> tuple[Sampler, list[int]]:
    ranges, sampled = joint_ranges(sm, spec, loaded)
    s = spec.sampling
    sampler = Sampler(ranges, s.method, s.n, seed=s.seed, chunk=s.chunk)
    if sampler.total > s.max_samples:
        raise InputError(problems=[Problem(
            f"{sampler.total:,} samples ({s.method}, n={s.n}, {len(ranges)} joints) exceed max_samples = {s.max_samples:,}",
            _where(loaded, "sampling", "n"), "analysis.sampling.n",
            "lower n, sample fewer joints, use method: sobol, or raise max_samples")])
    return sampler, sampled


def arm_layout(sm, spec: AnalysisSpec, sampled: list[int], variant: VariantSpec | None = None, loaded=None) -> ArmLayout:
    """Limits and indices of the arm and wheels for the kernel (overrides and variant scales applied)."""
    arm = actuated_arm(sm, spec, loaded)
    names = [a.name for a in arm]
    wnames = [w.name for w in sm.wheels]
    lim = spec.limits
    q_max = _per_name(lim.joint_speed, names, [_positive_or_inf(a.max_velocity) for a in arm], loaded,
                      ("limits", "joint_speed"), "analysis.limits.joint_speed")
    tau_max = _per_name(lim.joint_torque, names, [_positive_or_inf(a.max_effort) for a in arm], loaded,
                        ("limits", "joint_torque"), "analysis.limits.joint_torque")
    om_max = _per_name(lim.wheel_speed, wnames, [_positive_or_inf(w.max_speed) for w in sm.wheels], loaded,
                       ("limits", "wheel_speed"), "analysis.limits.wheel_speed")
    if variant is not None:
        q_max = q_max * variant.joint_speed_scale
        om_max = om_max * variant.wheel_speed_scale
    return ArmLayout(
        names=names, q_index=np.array([a.q_index for a in arm], dtype=int), kinds=[a.kind for a in arm],
        v_arm=np.array([a.v_index for a in arm], dtype=int), v_wheels=np.array([w.v_index for w in sm.wheels], dtype=int),
        wheel_names=wnames, sampled=list(sampled),
        lower=np.array([a.lower for a in arm], dtype=float), upper=np.array([a.upper for a in arm], dtype=float),
        q_max=q_max, tau_max=tau_max, omega_max=om_max)


def _wheel_local_axis(model, jid: int) -> np.ndarray:
    """Unit spin axis of a wheel joint in its own joint frame (from the motion subspace)."""
    import pinocchio as pin

    data = model.createData()
    q = pin.neutral(model)
    pin.computeJointJacobians(model, data, q)
    col = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.LOCAL)[3:6, model.joints[jid].idx_v]
    return col / np.linalg.norm(col)


def variant_model(sm, variant: VariantSpec, loaded=None):
    """(model, mass_update): a copy of the rigid model with the variant's changes applied.

    ``mass_update`` is set when the variant only scales the inertia of wheels mounted on the base
    body: then M_variant = M_nominal + ΔM on the rows/columns (base angular, wheels).
    """
    import pinocchio as pin

    model = pin.Model(sm.model)
    payload_names = list(sm.payloads)
    for i, name in enumerate(variant.attach):
        if name not in sm.payloads:
            raise _unknown(name, payload_names, loaded, ("variants", "attach", i), "analysis.variants.attach")
        p = sm.payloads[name]
        if not p.attached:
            model.inertias[p.joint_id] = model.inertias[p.joint_id] + p.inertia_in_joint
    s = variant.wheel_inertia_scale
    rows, cols_u = [3, 4, 5], []
    base_mounted = True
    for w in sm.wheels:
        if s == 1.0:
            break
        jid = w.joint_id
        a = _wheel_local_axis(model, jid)
        Y = model.inertias[jid]
        delta = (s - 1.0) * float(a @ Y.inertia @ a)
        model.inertias[jid] = pin.Inertia(Y.mass, Y.lever, Y.inertia + delta * np.outer(a, a))
        if model.parents[jid] != sm.base_joint_id:
            base_mounted = False
        cols_u.append((w.v_index, model.jointPlacements[jid].rotation @ a, delta))
    update = None
    if cols_u and base_mounted and not variant.attach:
        idx = np.array(rows + [c[0] for c in cols_u], dtype=int)
        D = np.zeros((len(idx), len(idx)))
        for k, (_, a_base, delta) in enumerate(cols_u):
            u = np.zeros(len(idx))
            u[:3] = a_base
            u[3 + k] = 1.0
            D += delta * np.outer(u, u)
        update = (idx, D)
    return model, update


def build_variants(sm, spec: AnalysisSpec, sampled: list[int], loaded=None) -> list[Variant]:
    """The nominal system and every ``analysis.variants`` entry, each with its index kernel."""
    groups = spec.groups()
    out = []
    for vs in [None] + list(spec.variants):
        layout = arm_layout(sm, spec, sampled, vs, loaded)
        if vs is None:
            model, update = sm.model, None
        else:
            model, update = variant_model(sm, vs, loaded)
        kernel = IndexKernel(model, sm.ee_frame_id, sm.q0, layout, groups, spec.singular_tolerance, spec.task,
                             kinematics_only=bool(sm.kinematics_only))
        limits = {"joint_speed": dict(zip(layout.names, layout.q_max)), "joint_effort": dict(zip(layout.names, layout.tau_max)),
                  "wheel_speed": dict(zip(layout.wheel_names, layout.omega_max))}
        out.append(Variant("nominal" if vs is None else vs.name, kernel, update, limits))
    return out


def evaluate_block(variants: list[Variant], samples: np.ndarray) -> tuple[np.ndarray, list[dict[str, np.ndarray]]]:
    """Indices of every variant at a block of samples: (full configurations, one dict per variant)."""
    nominal = variants[0].kernel
    Q = nominal.configurations(samples)
    Ms, Js = nominal.pinocchio_terms(Q)
    results = []
    for v in variants:
        if v is variants[0]:
            results.append(nominal.from_terms(Q, Ms, Js))
        elif v.mass_update is not None:
            idx, D = v.mass_update
            Mv = Ms.copy()
            Mv[:, idx[:, None], idx[None, :]] += D
            results.append(v.kernel.from_terms(Q, Mv, Js))
        else:
            results.append(v.kernel.evaluate(samples))
    return Q, results
