"""The numba kernels of the momentum-based Lyapunov laws (sms_cli.sim.compiled.momentum_laws), each against an
independent evaluation of its formula written here with numpy/scipy (Vicariotto 2023 ch. 3-4; the equations in
the docstring of sms_cli.sim.laws.momentum), to 1e-12, on random states: random model quantities (any wheel
axes, a CoM off the base origin, a non-symmetric ΛᵀM_θ made symmetric for the shaped X) and the quantities of
the test missions (the laws' classes, Pinocchio's locked/shape quantities). The Lyapunov property of the laws
themselves (Ẇ = −D) is tests/test_momentum_laws.py's."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import ROOT
from sms_cli.sim.compiled import momentum_laws as K

DATA = ROOT / "tests" / "data"
LAWS = ("wheels_free_floating", "free_flying", "hierarchical", "se3_pd", "quaternion_lyapunov")
CODES = {"wheels_free_floating": K.WHEELS_FREE_FLOATING, "free_flying": K.FREE_FLYING, "hierarchical": K.HIERARCHICAL,
         "se3_pd": K.SE3_PD, "quaternion_lyapunov": K.QUATERNION_LYAPUNOV}
TOL = 1e-12


def _unit(rng, n):
    x = rng.normal(size=n)
    return x / np.linalg.norm(x)


def random_model(rng, n=3):
    """Model quantities of a base with n wheels on random axes: I SPD, Λ = I⁻¹GJ, M_θ = J − JGᵀI⁻¹GJ."""
    A = rng.normal(size=(3, 3))
    I = A @ A.T + 3.0 * np.eye(3)
    G = np.stack([_unit(rng, 3) for _ in range(n)], axis=1)
    J = rng.uniform(0.05, 0.2, n)
    Lam = np.linalg.solve(I, G * J)
    Mt = np.diag(J) - (G * J).T @ Lam
    nv = 6 + n
    return dict(wheels=np.arange(6, nv, dtype=np.int64), mass=float(rng.uniform(50, 500)), com_base=rng.normal(size=3) * 0.3,
                Tv=rng.normal(size=(3, nv - 3)), I=I, G=G, J=J, Lam=Lam, M_theta=0.5 * (Mt + Mt.T))


def random_par(rng, n, shaping, translate, threshold=0.05):
    par = np.zeros(K.P_N + n)
    par[K.P_KP:K.P_KP + 3] = rng.uniform(1, 100, 3)
    par[K.P_KD:K.P_KD + 3] = rng.uniform(1, 100, 3)
    par[K.P_KX:K.P_KX + 3] = rng.uniform(1, 100, 3)
    par[K.P_DX:K.P_DX + 3] = rng.uniform(1, 100, 3)
    par[K.P_TRANSLATE] = float(translate)
    par[K.P_SHAPING] = float(shaping)
    par[K.P_THRESHOLD] = threshold
    par[K.P_K] = rng.uniform(1, 100)
    par[K.P_N:] = rng.uniform(0.1, 10, n)
    return par


def random_state(rng, n):
    q = np.concatenate([rng.normal(size=3), _unit(rng, 4), np.zeros(n)])
    v = np.concatenate([rng.normal(size=3), 0.3 * rng.normal(size=3), 300.0 * rng.normal(size=n)])
    return q, v, _unit(rng, 4)


# ---------------------------------------------------------------------------- the formulas, independently
def _vee(S):
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


def reference(law, q, v, ref, m, par, mem):
    """(τ_w, wrench, terms, mem after the call) of ``law`` by the formulas of sms_cli.sim.laws.momentum."""
    mem = mem.copy()
    Kp, Kd, Kx, Dx = (np.diag(par[a:a + 3]) for a in (K.P_KP, K.P_KD, K.P_KX, K.P_DX))
    n = len(m["wheels"])
    Kw = np.diag(par[K.P_N:K.P_N + n])
    shaping, translate = bool(par[K.P_SHAPING]), bool(par[K.P_TRANSLATE])
    R = Rotation.from_quat(q[3:7]).as_matrix()  # world ← base
    Rd = Rotation.from_quat(ref).as_matrix()
    I, Lam, Mt = m["I"], m["Lam"], m["M_theta"]
    w, wd = v[3:6], v[m["wheels"]]
    mu = w + Lam @ wd
    if law == "quaternion_lyapunov":  # Φ = k|q|², γ = k q₀ q of q_ref⁻¹ ⊗ q (the sign of the quaternion cancels)
        e = (Rotation.from_quat(ref).inv() * Rotation.from_quat(q[3:7])).as_quat()
        k = par[K.P_K]
        phi, gamma = k * e[:3] @ e[:3], k * e[3] * e[:3]
    else:  # Φ = ½tr(K_p(1 − R_e)), γ = (skew(K_p R_e))^∨, R_e = R_dᵀR
        Re = Rd.T @ R
        phi = 0.5 * np.trace(Kp @ (np.eye(3) - Re))
        gamma = _vee(0.5 * (Kp @ Re - (Kp @ Re).T))
    X = 0.5 * (Lam.T @ Mt + Mt.T @ Lam) if shaping else Mt
    wheel_law = Mt @ np.linalg.inv(X) @ (Lam.T @ gamma - Kw @ wd)
    c = q[:3] + R @ m["com_base"]
    cdot = R @ (v[:3] + m["Tv"] @ v[3:])

    def wrench_of(tau_c):
        f = np.zeros(3)
        if translate:
            if not mem[K.M_TARGET_SET]:
                mem[K.M_TARGET:K.M_TARGET + 3], mem[K.M_TARGET_SET] = c, 1.0
            f = R.T @ (-Kx @ (c - mem[K.M_TARGET:K.M_TARGET + 3]) - Dx @ cdot)
        return np.concatenate([f, tau_c + np.cross(m["com_base"], f)])

    tw, wrench = np.zeros(n), np.zeros(6)
    if law == "wheels_free_floating":
        tw = wheel_law
    elif law == "free_flying":
        tau_c = -gamma - Kd @ mu + np.cross(I @ mu, Lam @ wd)
        tw = Lam.T @ tau_c + wheel_law - Lam.T @ np.cross(w, I @ mu)
        wrench = wrench_of(tau_c)
    elif law == "hierarchical":
        if mem[K.M_STAGE] == 1 and np.linalg.norm(mu) <= par[K.P_THRESHOLD]:
            mem[K.M_STAGE] = 2.0
        if mem[K.M_STAGE] == 1:
            wrench[3:] = -Kd @ mu + np.cross(I @ mu, Lam @ wd)
        else:
            tw = wheel_law
    else:
        wrench = wrench_of(-gamma - Kd @ w)

    # W and its terms on the state, with the state (target, stage) before the call
    m0 = mem if law != "hierarchical" else None
    t = dict.fromkeys(K.TERM_NAMES, 0.0)
    dx = c - m0[K.M_TARGET:K.M_TARGET + 3] if (m0 is not None and m0[K.M_TARGET_SET]) else np.zeros(3)
    trans = 0.5 * m["mass"] * cdot @ cdot + 0.5 * dx @ Kx @ dx if translate else 0.0
    diss_trans = cdot @ Dx @ cdot if translate else 0.0
    t.update(locked=0.5 * mu @ I @ mu, shape=0.5 * wd @ X @ wd, potential=phi)
    if law == "wheels_free_floating":
        t["W"] = t["shape"] + phi + (0.0 if shaping else t["locked"])
        t["dissipation"] = wd @ Kw @ wd
    elif law == "free_flying":
        t.update(translation=trans, position_error=np.linalg.norm(dx) if translate else 0.0)
        t["W"] = t["locked"] + t["shape"] + phi + trans
        t["dissipation"] = diss_trans + mu @ Kd @ mu + wd @ Kw @ wd
    elif law == "hierarchical":
        pass  # stage-dependent: reference_hierarchical_terms
    else:
        Ib = I - m["G"] @ np.diag(m["J"]) @ m["G"].T
        t = dict.fromkeys(K.TERM_NAMES, 0.0)
        t.update(rotation=0.5 * w @ Ib @ w, potential=phi, translation=trans,
                 position_error=np.linalg.norm(dx) if translate else 0.0)
        t["W"] = t["rotation"] + phi + trans
        t["dissipation"] = diss_trans + w @ Kd @ w
    return tw, wrench, t, mem


def reference_hierarchical_terms(q, v, ref, m, par, stage):
    t = reference("wheels_free_floating", q, v, ref, m, par, np.zeros(K.M_N))[2]
    n = len(m["wheels"])
    Kd, Kw = np.diag(par[K.P_KD:K.P_KD + 3]), np.diag(par[K.P_N:K.P_N + n])
    I, Lam, Mt = m["I"], m["Lam"], m["M_theta"]
    w, wd = v[3:6], v[m["wheels"]]
    mu = w + Lam @ wd
    X = 0.5 * (Lam.T @ Mt + Mt.T @ Lam) if par[K.P_SHAPING] else Mt
    t["stage"] = float(stage)
    if stage == 1:
        t.update(W=t["locked"], dissipation=mu @ Kd @ mu, residual=0.0)
    else:
        R = Rotation.from_quat(q[3:7]).as_matrix()
        Re = Rotation.from_quat(ref).as_matrix().T @ R
        A = np.diag(par[K.P_KP:K.P_KP + 3]) @ Re
        gamma = _vee(0.5 * (A - A.T))
        t.update(W=t["shape"] + t["potential"], dissipation=wd @ Kw @ wd,
                 residual=gamma @ mu + wd @ X @ np.linalg.inv(Mt) @ Lam.T @ np.cross(w, I @ mu))
    return t


def _close(a, b, what):
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = max(float(np.abs(b).max(initial=0.0)), 1.0)
    assert np.abs(a - b).max(initial=0.0) <= TOL * scale, (what, a, b)


def _model_args(m):
    return tuple(m[k] for k in ("wheels", "mass", "com_base", "Tv", "I", "G", "J", "Lam", "M_theta"))


def _call(law, q, v, ref, m, par, mem):
    n = len(m["wheels"])
    tw, wrench, out = np.full(n, np.nan), np.full(6, np.nan), np.full(K.T_N, np.nan)
    mem_law, mem_w = mem.copy(), mem.copy()
    getattr(K, law + "_lyapunov")(q, v, ref, *_model_args(m), par, mem_w, out)
    getattr(K, law)(q, v, ref, *_model_args(m), par, mem_law, tw, wrench)
    assert np.array_equal(mem_w, mem)  # W reads the state, never writes it
    return tw, wrench, dict(zip(K.TERM_NAMES, out)), mem_law


# ---------------------------------------------------------------------------- the tests
def test_rotation_and_potentials_against_scipy():
    rng = np.random.default_rng(7)
    for _ in range(50):
        quat = rng.normal(size=4) * rng.uniform(0.5, 2.0)  # not unit: R of q/|q|
        R = np.empty((3, 3))
        K.rotation_matrix(quat, R)
        _close(R, Rotation.from_quat(quat).as_matrix(), "R")
        q, ref = _unit(rng, 4), _unit(rng, 4)
        kp = rng.uniform(1, 100, 3)
        Rq, Rd = Rotation.from_quat(q).as_matrix(), Rotation.from_quat(ref).as_matrix()
        g = np.empty(3)
        phi = K.trace_potential(kp, Rq, Rd, g)
        A = np.diag(kp) @ Rd.T @ Rq
        _close([phi, *g], [0.5 * np.trace(np.diag(kp) - A), *_vee(0.5 * (A - A.T))], "trace potential")
        # Φ̇ = γᵀω along R(t) = R exp(tω^): the potential's gradient, by a central difference
        w, h = rng.normal(size=3), 1e-6
        Rp, Rm = (Rq @ Rotation.from_rotvec(s * h * w).as_matrix() for s in (1, -1))
        dphi = (K.trace_potential(kp, Rp, Rd, np.empty(3)) - K.trace_potential(kp, Rm, Rd, np.empty(3))) / (2 * h)
        assert abs(dphi - g @ w) <= 1e-7 * max(1.0, abs(g @ w))
        k = rng.uniform(1, 100)
        phi = K.quaternion_potential(k, q, ref, g)
        e = (Rotation.from_quat(ref).inv() * Rotation.from_quat(q)).as_quat()
        _close([phi, *g], [k * e[:3] @ e[:3], *(k * e[3] * e[:3])], "quaternion potential")


VARIANTS = [(law, shaping, translate) for law in LAWS for shaping in (False, True) for translate in (False, True)
            if not (shaping and law in ("se3_pd", "quaternion_lyapunov"))  # no wheel law
            and not (translate and law in ("wheels_free_floating", "hierarchical"))]  # no translation PD


@pytest.mark.parametrize("law,shaping,translate", VARIANTS)
def test_each_law_kernel_is_its_formula_on_random_states(law, shaping, translate):
    """τ_w, the base wrench, the CoM target set on the first call, W and every term, against ``reference``."""
    rng = np.random.default_rng(zlib.crc32(f"{law} {shaping} {translate}".encode()))
    for trial in range(20):
        m = random_model(rng, 3 if shaping or trial % 2 else 4)
        n = len(m["wheels"])
        par = random_par(rng, n, shaping, translate, threshold=rng.choice([0.0, 10.0]))
        q, v, ref = random_state(rng, n)
        mem = np.zeros(K.M_N)
        mem[K.M_STAGE] = float(rng.choice([1, 2]))
        if trial % 3 == 0:  # a CoM target already set (given, or set by an earlier tick)
            mem[K.M_TARGET_SET], mem[K.M_TARGET:K.M_TARGET + 3] = 1.0, rng.normal(size=3)
        tw, wrench, terms, mem_after = _call(law, q, v, ref, m, par, mem)
        rtw, rwrench, rterms, rmem = reference(law, q, v, ref, m, par, mem)
        _close(tw, rtw, "wheel torques")
        _close(wrench, rwrench, "wrench")
        _close(mem_after, rmem, "state")
        if law == "hierarchical":
            rterms = reference_hierarchical_terms(q, v, ref, m, par, int(mem[K.M_STAGE]))
        _close([terms[k] for k in K.TERM_NAMES], [rterms[k] for k in K.TERM_NAMES], "terms")


@pytest.mark.parametrize("law", LAWS)
def test_the_dispatch_by_law_code_is_the_law_kernel(law):
    """``momentum_law``/``momentum_lyapunov`` (a compiled loop's entry) compute what the law's kernels do, bit for bit."""
    rng = np.random.default_rng(5)
    for trial in range(5):
        m = random_model(rng)
        par = random_par(rng, 3, bool(trial % 2), True, threshold=rng.choice([0.0, 10.0]))
        q, v, ref = random_state(rng, 3)
        mem = np.array([float(rng.choice([1, 2])), 0.0, 0.0, 0.0, 0.0])
        tw, wrench, terms, mem_after = _call(law, q, v, ref, m, par, mem)
        tw2, wrench2, out2, mem2 = np.empty(3), np.empty(6), np.empty(K.T_N), mem.copy()
        K.momentum_law(CODES[law], q, v, ref, *_model_args(m), par, mem2, tw2, wrench2)
        K.momentum_lyapunov(CODES[law], q, v, ref, *_model_args(m), par, mem.copy(), out2)
        assert np.array_equal(tw2, tw) and np.array_equal(wrench2, wrench) and np.array_equal(mem2, mem_after)
        assert np.array_equal(out2, [terms[k] for k in K.TERM_NAMES])


def test_the_hierarchical_switch_is_latched_at_the_threshold():
    rng = np.random.default_rng(3)
    m = random_model(rng)
    q, v, ref = random_state(rng, 3)
    mu = np.linalg.norm(v[3:6] + m["Lam"] @ v[6:])
    for threshold, stage, after in ((0.999 * mu, 1, 1), (1.001 * mu, 1, 2), (0.0, 2, 2)):
        par = random_par(rng, 3, True, False, threshold)
        mem = np.array([float(stage), 0, 0, 0, 0])
        tw, wrench, _, mem_after = _call("hierarchical", q, v, ref, m, par, mem)
        assert mem_after[K.M_STAGE] == after
        assert (np.any(tw != 0) and not np.any(wrench)) if after == 2 else (not np.any(tw) and np.any(wrench[3:]) and not np.any(wrench[:3]))


# ---------------------------------------------------------------------------- the laws' classes call the kernels
CASES = [("momentum_ff_wheels", "wheels_free_floating"), ("momentum_shaping", "wheels_free_floating"),
         ("momentum_free_flying", "free_flying"), ("momentum_offset", "free_flying"),
         ("momentum_hierarchical", "hierarchical"), ("momentum_se3_pd", "se3_pd"), ("momentum_quaternion", "quaternion_lyapunov")]


def _par_of_spec(spec, law, n):
    """The kernels' ``par`` of an ``attitude:`` block, field by field (the layout P_* of momentum_laws)."""
    d = spec.model_dump()
    par = np.zeros(K.P_N + n)
    if law == "quaternion_lyapunov":
        par[K.P_KP:K.P_KP + 3] = par[K.P_K] = d["k"]
    else:
        par[K.P_KP:K.P_KP + 3] = d["kp"]
    par[K.P_KD:K.P_KD + 3] = d.get("kd_base") if "kd_base" in d else (d["kd"] if law != "wheels_free_floating" else 0.0)
    par[K.P_N:] = d["kd"] if law == "wheels_free_floating" else d.get("kd_wheels") or 0.0
    par[K.P_SHAPING] = float(bool(d.get("inertia_shaping")))
    par[K.P_THRESHOLD] = d.get("mu_threshold") or 0.0
    if d.get("kp_position") is not None:
        par[K.P_TRANSLATE] = 1.0
        par[K.P_KX:K.P_KX + 3], par[K.P_DX:K.P_DX + 3] = d["kp_position"], d["kd_position"]
    return par


@pytest.mark.parametrize("name,law", CASES)
def test_the_law_classes_pass_pinocchios_quantities(name, law):
    """The class of each test mission (Pinocchio's locked/shape quantities, the mission's gains in ``par``) on random
    states: its actuate and lyapunov_terms are the formulas on ``locked_shape``'s I, Λ, M_θ, G, J, c_b and T."""
    from sms_cli.dynamics.locked import locked_shape
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.sim.interfaces import AttitudeRef, Sensed
    from sms_cli.sim.laws import build_attitude_law

    loaded = load_mission(DATA / f"{name}.yaml")
    sm = compile_system(loaded)
    obj = build_attitude_law(loaded.mission.simulation.attitude, sm)
    assert obj.kernel == law
    par = _par_of_spec(loaded.mission.simulation.attitude, law, len(sm.wheels))
    assert np.array_equal(obj.par, par)  # the mission's gains, where the kernels read them
    ls = locked_shape(sm, sm.q0)
    m = dict(wheels=np.asarray(sm.idx.wheels), mass=ls.mass, com_base=ls.com_base, Tv=ls.T[0:3, 3:], I=ls.I, G=ls.G, J=ls.J,
             Lam=ls.Lambda, M_theta=ls.M_theta)
    rng = np.random.default_rng(11)
    for k in range(10):
        q, v, ref = random_state(rng, len(sm.wheels))
        q, v = np.concatenate([q[:7], sm.q0[7:]]), v[:sm.nv]
        if law == "hierarchical":
            obj.stage = 1 + k % 2
        mem = obj.mem.copy()
        rterms = reference_hierarchical_terms(q, v, ref, m, par, obj.stage) if law == "hierarchical" else \
            reference(law, q, v, ref, m, par, mem)[2]
        terms = obj.lyapunov_terms(q, v, ref)
        assert set(terms) == set(obj.terms)
        _close([terms[k] for k in obj.terms], [rterms[k] for k in obj.terms], "terms")
        rtw, rwrench, _, _ = reference(law, q, v, ref, m, par, mem)
        tw, wrench = obj.actuate(Sensed(0.0, q[3:7], v[3:6], q[:3], v[:3], np.zeros(0), np.zeros(0), v[6:], q, v), AttitudeRef(ref))
        _close(tw, rtw, "wheel torques")
        if law == "wheels_free_floating":
            assert wrench is None
        else:
            _close(wrench, rwrench, "wrench")
