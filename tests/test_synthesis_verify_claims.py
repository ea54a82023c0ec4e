"""Each check of the LMI gain verifier (``sms_cli.synthesis.verify``) must be able to fail.

Setting the pole-region verdict to ``ok = True`` once left every synthesis test green (issue #11,
§5): the tests only ever fed the verifier gains that pass. Here the verifier gets the real gains
of the shipped flagship ``missions/pulsar_simple.yaml`` (Kraiem 2022 NDI + observer synthesis),
then gains broken one way at a time, and each test asserts

* the unbroken gains pass every check;
* the broken ones fail verification, the failure is the named check (alone, where the break
  touches one quantity only) with its own detail text, and ``raise_if_failed`` names it too;
* the break is real: the broken quantity is recomputed here with plain numpy (poles of
  s² + k_v s + k_p, eigenvalues of A_e − L C_e, damping ratios, the sign of P) and compared
  with the requirement, so a check that passes these gains is wrong, not lenient.

Breaks: gains synthesised for a wider pole region than the mission's (pole checks), a scaled
gain (pole checks, authority), a Lyapunov matrix with one eigenvalue sign-flipped and a solver γ
below what P proves (certificate), an unstable gain and a γ below the true worst cost
(gamma_bound), the fastest actuator's gains raised and a lowered torque limit (authority), an
observer synthesised with less damping than the open-loop modes (flexible_damping). The NDO pole
check (Kraiem 2022 chapter 4 variant) is broken on the toy model of ``test_synthesis_lmi`` with
the disturbance-observer gain Q_d ten times too fast (the flagship has no NDO variant).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sms_cli.errors import NumericalError
from sms_cli.synthesis.lmi import SynthesisRequest, ellipsoid_from_box, synthesize
from sms_cli.synthesis.regions import PoleRegion
from sms_cli.synthesis.verify import raise_if_failed, verify_lmi

ROOT = Path(__file__).resolve().parents[1]
CHECKS = {"controller_poles", "observer_poles", "certificate", "gamma_bound", "actuator_authority",
          "flexible_damping"}


@pytest.fixture(scope="module")
def flagship():
    """(request, result) of pulsar_simple's own LMI synthesis, as ``sms synthesize`` builds them."""
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.synthesis.build import lmi_setup

    loaded = load_mission(ROOT / "missions" / "pulsar_simple.yaml")
    req = lmi_setup(compile_system(loaded), loaded.mission.synthesis).request
    return req, synthesize(req)


def _failures(req, res, *expected, only=False):
    """Verify; assert it fails, that every expected check is among the failures (exactly those
    when ``only``), and that the NumericalError of raise_if_failed names each of them."""
    ver = verify_lmi(req, res)
    names = {c.name for c in ver.failures()}
    assert not ver.passed
    assert set(expected) <= names, (expected, [(c.name, c.detail) for c in ver.failures()])
    if only:
        assert names == set(expected), [(c.name, c.detail) for c in ver.failures()]
    with pytest.raises(NumericalError) as exc:
        raise_if_failed(ver)
    text = exc.value.render()
    for name in expected:
        assert f"failed: {name}: " in text, text
    return {c.name: c for c in ver.failures()}


def _outside(region: PoleRegion, poles: np.ndarray) -> np.ndarray:
    """Poles outside {Re s ≤ −α} ∩ {|s| ≤ r} ∩ {−Re s ≥ ζ|s|}, recomputed here (relative 1e-6)."""
    a = np.abs(poles)
    return ((-poles.real < region.alpha * (1 - 1e-6)) | (a > region.radius * (1 + 1e-6))
            | (-poles.real < region.zeta_min * a * (1 - 1e-6)))


def _controller_poles(res) -> np.ndarray:
    return np.concatenate([np.roots([1.0, kv, kp]) for kp, kv in zip(res.K_p, res.K_v)])


def _observer_poles(req, res) -> list[np.ndarray]:
    return [np.linalg.eigvals(m.A_e - res.L @ m.C_e) for m in list(req.nominal) + list(req.samples)]


def test_the_flagship_gains_pass_every_check(flagship):
    req, res = flagship
    ver = verify_lmi(req, res)
    assert ver.passed, [(c.name, c.detail) for c in ver.failures()]
    assert {c.name for c in ver.checks} == CHECKS
    # and they are inside the regions by an independent recomputation
    assert not np.any(_outside(req.controller_region, _controller_poles(res)))
    assert not any(np.any(_outside(req.observer_region, e)) for e in _observer_poles(req, res))


# ---- pole regions

def test_controller_gains_of_a_wider_region_fail_controller_poles_alone(flagship):
    """Gains synthesised for max_frequency 0.6 rad/s (the mission asks 0.5): their own P and γ are
    valid, so only the pole region of the mission is broken."""
    req, _ = flagship
    wide = synthesize(dataclasses.replace(req, controller_region=PoleRegion(0.05, 0.7, 0.6)))
    assert np.any(_outside(req.controller_region, _controller_poles(wide)))
    f = _failures(req, wide, "controller_poles", only=True)
    assert "pole(s) outside the region" in f["controller_poles"].detail
    assert f["controller_poles"].value < 0


def test_a_scaled_stiffness_gain_fails_controller_poles(flagship):
    req, res = flagship
    bad = dataclasses.replace(res, K_p=res.K_p * 1.05)  # |s| > 0.5 rad/s, ζ < 0.7
    assert np.any(_outside(req.controller_region, _controller_poles(bad)))
    f = _failures(req, bad, "controller_poles")
    assert "pole(s) outside the region" in f["controller_poles"].detail


def test_observer_gains_of_a_wider_region_fail_observer_poles_alone(flagship):
    """L synthesised for max_frequency 150 rad/s (the mission asks 100)."""
    req, _ = flagship
    wide = synthesize(dataclasses.replace(req, observer_region=PoleRegion(0.001, 0.005, 150.0)))
    assert any(np.any(_outside(req.observer_region, e)) for e in _observer_poles(req, wide))
    f = _failures(req, wide, "observer_poles", only=True)
    assert "pole(s) outside the region" in f["observer_poles"].detail
    assert f["observer_poles"].value < 0


def test_a_scaled_observer_gain_fails_observer_poles(flagship):
    req, res = flagship
    bad = dataclasses.replace(res, L=res.L * 1.2)
    assert any(np.any(_outside(req.observer_region, e)) for e in _observer_poles(req, bad))
    f = _failures(req, bad, "observer_poles")
    assert "pole(s) outside the region" in f["observer_poles"].detail


def test_a_too_fast_disturbance_observer_fails_ndo_poles_alone():
    """Kraiem 2022 chapter 4 variant: ε̇_d = −Q_d M⁻¹ ε_d, checked against the observer region
    (radius 20 rad/s). The NDO mode that the synthesis puts on the radius (Q_d ⪯ rM◇ active) is
    moved to 30 rad/s alone: Q_d + ½λ M◇vvᵀM◇ (Q_d v = λM◇v, vᵀM◇v = 1). That is an improving
    direction of the LMI, so the returned P still proves γ and only the NDO poles are wrong.
    (A uniform Q_d × 10 also breaks the certificate, genuinely: P_d = Q_d⁻¹M◇Q_d⁻¹ is part of
    the returned P, and at the optimum the dissipation inequality is active, so already Q_d × 1.02
    makes −(A_clᵀP + PA_cl) indefinite; the Gramian γ stays below the solver's.)"""
    from scipy.linalg import eigh

    from test_synthesis_lmi import toy_model

    m = toy_model([1e3] * 3 + [2e3] * 3 + [0.13, 20.0], n_modes=2, seed=6)
    req = SynthesisRequest([m], PoleRegion(0.3, 0.5, 5.0), PoleRegion(0.3, 0.0, 20.0),
                           ellipsoid_from_box([0.05, 0.05, 0.01, 0.01, 0.01, 0.05, 0.05]),
                           variant="ndi_observer_ndo", E_d=ellipsoid_from_box([0.01, 0.5]))
    res = synthesize(req)
    assert verify_lmi(req, res).passed
    lam, V = eigh(res.Q_d, m.M)
    assert lam[-1] == pytest.approx(20.0, rel=1e-3)  # on the radius
    v = V[:, -1]
    bad = dataclasses.replace(res, Q_d=res.Q_d + 0.5 * lam[-1] * m.M @ np.outer(v, v) @ m.M)
    poles = -np.linalg.eigvals(bad.Q_d @ np.linalg.inv(m.M))
    assert np.sum(_outside(req.observer_region, poles)) == 1
    f = _failures(req, bad, "ndo_poles", only=True)
    assert "pole(s) outside the region" in f["ndo_poles"].detail
    # the uniform mutation: the certificate fails with it (S indefinite), the true cost does not
    ten = verify_lmi(req, dataclasses.replace(res, Q_d=res.Q_d * 10))
    assert {"ndo_poles", "certificate"} <= {c.name for c in ten.failures()}
    assert ten.gramian_cost < res.gamma**2


# ---- certificate

def test_a_lyapunov_matrix_that_is_not_positive_fails_the_certificate_alone(flagship):
    req, res = flagship
    w, V = np.linalg.eigh(res.P_e)
    bad_P = res.P_e - 2 * w[0] * np.outer(V[:, 0], V[:, 0])  # smallest eigenvalue → −λ_min
    assert np.min(np.linalg.eigvalsh(bad_P)) < 0
    f = _failures(req, dataclasses.replace(res, P_e=bad_P), "certificate", only=True)
    assert "the returned P proves nothing" in f["certificate"].detail
    assert not np.isfinite(f["certificate"].value)


def test_a_solver_gamma_below_what_P_proves_fails_the_certificate_alone(flagship):
    req, res = flagship
    bad = dataclasses.replace(res, gamma=res.gamma * 0.99)
    f = _failures(req, bad, "certificate", only=True)
    c = f["certificate"]
    assert "the returned P proves γ =" in c.detail and c.value > c.limit * (1 + 1e-3)


# ---- gamma_bound

def test_a_gamma_below_the_worst_cost_fails_gamma_bound(flagship):
    """γ/4: γ² = 0.046 below the worst ∫ε_cᵀε_c (Gramian ≈ 0.073): the bound itself is false."""
    req, res = flagship
    bad = dataclasses.replace(res, gamma=res.gamma * 0.25)
    f = _failures(req, bad, "gamma_bound", "certificate")
    c = f["gamma_bound"]
    assert "vs γ²" in c.detail and c.value > c.limit


def test_an_unstable_gain_fails_gamma_bound(flagship):
    req, res = flagship
    kp = res.K_p.copy()
    kp[0] = -kp[0]
    bad = dataclasses.replace(res, K_p=kp)
    assert np.max(_controller_poles(bad).real) > 0
    f = _failures(req, bad, "gamma_bound", "controller_poles")
    assert "closed loop unstable at 'nominal'" in f["gamma_bound"].detail


# ---- actuator authority

def test_raised_gains_on_one_actuator_fail_actuator_authority(flagship):
    """Actuator 8 (arm_joint_4, the check's most loaded one at 0.40 of its limit): k_p × 16,
    k_v × 4 (bandwidth × 4) push the peak feedback acceleration past its torque limit."""
    req, res = flagship
    kp, kv = res.K_p.copy(), res.K_v.copy()
    kp[8] *= 16
    kv[8] *= 4
    f = _failures(req, dataclasses.replace(res, K_p=kp, K_v=kv), "actuator_authority")
    c = f["actuator_authority"]
    assert c.value > 1 and "(actuator 8)" in c.detail and "peak feedback acceleration / limit" in c.detail


def test_a_torque_limit_below_the_peak_fails_actuator_authority_alone(flagship):
    """The same gains on an actuator 8 with 30 % of its torque (its peak uses 40 %)."""
    req, res = flagship
    acc = np.array(req.accel_limit, dtype=float)
    acc[8] *= 0.3
    f = _failures(dataclasses.replace(req, accel_limit=acc), res, "actuator_authority", only=True)
    c = f["actuator_authority"]
    assert c.value > 1 and "(actuator 8)" in c.detail


# ---- flexible damping

@pytest.fixture(scope="module")
def underdamped_observer(flagship):
    """L synthesised with an observer min_damping of 0.002 (the modes' own is 0.005)."""
    req, _ = flagship
    loose = dataclasses.replace(req, observer_region=PoleRegion(0.001, 0.002, 100.0))
    return loose, synthesize(loose)


def _least_damping(eigs):
    return float(np.min(-eigs.real / np.abs(eigs)))


def test_an_observer_less_damped_than_the_modes_fails_flexible_damping(flagship, underdamped_observer):
    req, _ = flagship
    _, res = underdamped_observer
    zeta_ol = min(_least_damping(e[np.abs(e.imag) > 1e-9]) for e in (np.linalg.eigvals(m.A_e) for m in req.nominal + req.samples))
    zeta_cl = min(_least_damping(e) for e in _observer_poles(req, res))
    assert zeta_cl < zeta_ol
    f = _failures(req, res, "flexible_damping", "observer_poles")
    c = f["flexible_damping"]
    assert "least closed-loop observer damping" in c.detail and c.value < c.limit


def test_flexible_damping_is_the_only_guard_when_the_region_allows_less_damping(underdamped_observer):
    """Against the request it was synthesised for, the observer is inside its region: the loss
    of modal damping is caught by flexible_damping alone."""
    loose, res = underdamped_observer
    f = _failures(loose, res, "flexible_damping", only=True)
    assert f["flexible_damping"].value < f["flexible_damping"].limit
