"""Modes the measurement does not see are poles of every observer A_e − L C_e: the synthesis says so before solving
when the observer region cannot hold them (``lmi._check_fixed_observer_poles``), instead of a solver stalling on an
LMI with no strictly feasible point. Oracles: the PBH test in closed form (two identical oscillators seen only
through their sum), the eigenvalues of A − L C for random L, and the full PULSAR's base-rate-unobservable beam
modes against the clamped poles of Kraiem 2022 Fig. 2.12."""

from __future__ import annotations

import numpy as np
import pytest

from sms_cli.errors import NumericalError
from sms_cli.synthesis import lmi
from sms_cli.synthesis.regions import PoleRegion, unobservable_eigenvalues

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]


def _twin_oscillators(w: float = 3.0, zeta: float = 0.005) -> tuple[np.ndarray, np.ndarray]:
    """x = [f1, f2, ḟ1, ḟ2] of two identical oscillators, measured through f1 + f2 and ḟ1 + ḟ2: the antisymmetric
    motion f1 = −f2 is unobservable (its eigenvalues −ζw ± i w √(1 − ζ²), repeated with the symmetric ones)."""
    K, D = w * w * np.eye(2), 2 * zeta * w * np.eye(2)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-K, -D]])
    C = np.array([[1.0, 1.0, 0, 0], [0, 0, 1.0, 1.0]])
    return A, C


def test_the_pbh_test_finds_the_unseen_motion_of_repeated_modes():
    A, C = _twin_oscillators()
    lam = unobservable_eigenvalues(A, C)
    want = -0.005 * 3.0 + 1j * 3.0 * np.sqrt(1 - 0.005**2)
    assert len(lam) == 1 and abs(lam[0] - want) < 1e-12
    C_seen = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])  # one oscillator measured alone: the other is unseen too
    assert len(unobservable_eigenvalues(A, C_seen)) == 1
    C_one = np.array([[1.0, 0.3, 0, 0], [0, 0, 1.0, 0.3]])  # any one weighting misses a combination of the twins
    assert len(unobservable_eigenvalues(A, C_one)) == 1
    C_both = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])  # both positions measured: nothing is unseen
    assert len(unobservable_eigenvalues(A, C_both)) == 0


def test_no_observer_gain_moves_an_unobservable_mode():
    A, C = _twin_oscillators()
    lam = unobservable_eigenvalues(A, C)[0]
    rng = np.random.default_rng(3)
    for _ in range(5):
        L = rng.normal(scale=10.0, size=(4, 2))
        assert np.min(np.abs(np.linalg.eigvals(A - L @ C) - lam)) < 1e-9


def _request_with_fixed_mode(zeta_min: float):
    """A chapter 3 toy request whose observer state holds the twin oscillators' unseen mode at ζ 0.005."""
    from test_synthesis_lmi import toy_model

    m = toy_model([10.0] * 3 + [1e2] * 3 + [1.0, 2.0], n_modes=2, seed=1)
    n_f = 2
    A, C = _twin_oscillators()
    # x_e = [f; ω0; ḟ]: the twins' block on the modal coordinates, ω0 measured and decoupled
    A_e = np.zeros((2 * n_f + 3, 2 * n_f + 3))
    f, w, fd = np.arange(n_f), np.arange(n_f, n_f + 3), np.arange(n_f + 3, 2 * n_f + 3)
    A_e[np.ix_(f, fd)] = A[:2, 2:]
    A_e[np.ix_(fd, f)], A_e[np.ix_(fd, fd)] = A[2:, :2], A[2:, 2:]
    C_e = np.zeros((3, 2 * n_f + 3))
    C_e[:, w] = np.eye(3)
    C_e[0, f] += C[0, :2]  # the gyro sees the modes only through their sum (as a symmetric pair of panels)
    model = lmi.ErrorModel(A_e, C_e, m.B_eps[:, : 2 * n_f + 3], label="nominal")
    return lmi.SynthesisRequest([model], PoleRegion(0.3, 0.5, 5.0), PoleRegion(0.001, zeta_min, 40.0),
                                lmi.ellipsoid_from_box([0.01] * (2 * n_f + 3)), relaxation="none")


def test_an_observer_region_on_an_unseen_mode_is_refused_before_solving(monkeypatch):
    """At min_damping 0.005 the unseen mode (ζ 0.005) is on the region's boundary: exit 3 at the observer region,
    naming the mode and the fix, and no solver runs; at 0.004 the check lets it through."""
    solved = []
    monkeypatch.setattr(lmi, "_scale", lambda req: solved.append(True) or (_ for _ in ()).throw(RuntimeError("solved")))
    with pytest.raises(NumericalError) as exc:
        lmi.synthesize(_request_with_fixed_mode(0.005))
    p = exc.value.problems[0]
    assert exc.value.exit_code == 3 and p.field == "synthesis.lmi.observer_region" and not solved
    assert "3 rad/s (ζ 0.005" in p.message and p.hint.endswith("min_damping below 0.005")
    with pytest.raises(RuntimeError, match="solved"):
        lmi.synthesize(_request_with_fixed_mode(0.004))


def test_the_full_pulsars_unseen_modes_are_its_clamped_beam_poles():
    """The modes of pulsar_full's error model that the gyro does not see are the three beam modes that Kraiem 2022
    Fig. 2.12 lists at their clamped frequencies (14.2, 44.8, 87.2 rad/s: the beams' motions that do not turn the
    base), and the shipped observer region holds them strictly."""
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.synthesis.build import lmi_setup

    loaded = load_mission(ROOT / "missions" / "pulsar_full.yaml")
    req = lmi_setup(compile_system(loaded), loaded.mission.synthesis).request
    lam = unobservable_eigenvalues(req.nominal[0].A_e, req.nominal[0].C_e)
    assert np.allclose(np.sort(np.abs(lam)), [14.2, 44.8, 87.2], rtol=1e-6)
    assert req.observer_region.strictly_contains(lam).all()
