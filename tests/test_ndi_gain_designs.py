"""The NDI law's gain designs on its own model (sms_cli.sim.laws.ndi_gains: L: kalman, ndo_bandwidth) and the
refusals of contradictory inputs, on the flagship's model."""

from __future__ import annotations

import numpy as np
import pytest

from sms_cli.errors import InputError
from sms_cli.sim.laws.ndi_gains import kalman_gain, ndo_gain

from test_compiled_ndi import pulsar  # noqa: F401  (the flagship's model, a module fixture)


def test_the_kalman_observer_is_stable_and_damps_more_with_more_process_noise(pulsar):
    """A_e − L C_e is Hurwitz (the open loop has the marginal ω0 mode, Re s = 0), and a larger process/measurement
    ratio adds damping: the sum of the observer's poles (trace of A_e − L C_e) moves left. (Its slowest pole does
    not: a panel mode the gyro does not see keeps its own damping ζΩ.)"""
    rest = pulsar.reduced.at_rest(pulsar.mass_matrix(pulsar.q0))
    assert np.max(np.linalg.eigvals(rest.A_e).real) > -1e-9
    traces = []
    for w in (1e-3, 1e-1):
        L = kalman_gain(pulsar, w, 1e-4)
        assert L.shape == (rest.A_e.shape[0], 3)
        A_L = rest.A_e - L @ rest.C_e
        assert np.max(np.linalg.eigvals(A_L).real) < 0
        traces.append(np.trace(A_L))
    assert traces[1] < traces[0] < np.trace(rest.A_e)


def test_the_ndo_gain_gives_every_actuator_the_bandwidth(pulsar):
    """L_d = Q_d M◇⁻¹ = β I at the design configuration (Kraiem 2022 (4.33))."""
    rest = pulsar.reduced.at_rest(pulsar.mass_matrix(pulsar.q0))
    Q_d = ndo_gain(pulsar, 0.5)
    assert np.allclose(Q_d @ np.linalg.inv(rest.M_dia), 0.5 * np.eye(Q_d.shape[0]), atol=1e-10)
    assert np.allclose(Q_d, Q_d.T, rtol=0, atol=0)


@pytest.mark.parametrize("ndi, field", [
    ({"kp": 1, "kv": 1, "L": "kalman", "disturbance_observer": True, "ndo_bandwidth": 0.5, "Q_d": [[1.0]]}, "Q_d"),
    ({"kp": 1, "kv": 1, "L": "kalman", "ndo_bandwidth": 0.5}, "ndo_bandwidth"),
])
def test_contradictory_disturbance_observer_inputs_are_refused(pulsar, ndi, field):
    from sms_cli.sim.laws.ndi import build_ndi
    from sms_cli.sim.schema import NdiSpec

    with pytest.raises(InputError) as exc:
        build_ndi(NdiSpec(**ndi), pulsar, 0.1)
    assert exc.value.problems[0].field == f"simulation.ndi.{field}"


def test_the_designs_are_made_on_the_laws_model(pulsar):
    """With model errors the gains are designed on the law's copy (what the controller knows), not the plant."""
    from sms_cli.model.model_errors import law_model
    from sms_cli.sim.laws.ndi import build_ndi
    from sms_cli.sim.schema import NdiSpec

    spec = NdiSpec(kp=1, kv=1, L="kalman", disturbance_observer=True, ndo_bandwidth=0.5,
                   model_errors={"inertia": 0.03, "com": 0.1, "modal_frequency": 0.1, "seed": 3})
    law = build_ndi(spec, pulsar, 0.1)
    copy = law_model(pulsar, 0.03, 0.1, 0.1, 3)
    assert law.plant is pulsar and law.sm is not pulsar
    assert np.allclose(law.L, kalman_gain(copy, 1e-2, 1e-4), rtol=1e-10, atol=1e-12)
    assert np.allclose(law.Q_d, ndo_gain(copy, 0.5), rtol=1e-12, atol=0)
    assert not np.allclose(law.Q_d, ndo_gain(pulsar, 0.5), rtol=1e-6, atol=0)


def test_the_law_follows_the_plants_payloads(pulsar):
    """A release on the plant, told to the law (model_changed), releases the tile from the law's copy too, and the
    compiled loop's arrays of the law's model are rebuilt from it."""
    from sms_cli.model.model_errors import law_model
    from sms_cli.sim.laws.ndi import build_ndi
    from sms_cli.sim.schema import NdiSpec

    spec = NdiSpec(kp=1, kv=1, L="kalman", model_errors={"inertia": 0.03, "com": 0.1, "seed": 3})
    law = build_ndi(spec, pulsar, 0.1)
    before = law.model_arrays()[0].copy()
    name = next(iter(pulsar.payloads))
    pulsar.detach_payload(name)
    try:
        law.model_changed(pulsar)
        assert not law.sm.payloads[name].attached
        expected = law_model(pulsar, 0.03, 0.1, 0.0, 3)
        q = pulsar.q0
        assert np.allclose(law.sm.mass_matrix(q), expected.mass_matrix(q), rtol=1e-12, atol=1e-9)
        assert not np.allclose(law.model_arrays()[0], before)
    finally:
        pulsar.attach_payload(name)
        law.model_changed(pulsar)
    assert law.sm.payloads[name].attached
