"""Above CLARABEL_MAX_ROWS a stalled dedicated solver is an exit-3 error naming what to relax, not a hand-over to
Clarabel (which at these sizes runs for tens of minutes and past 13 GB); below it, the fallback still happens."""

from __future__ import annotations

import pytest

from sms_cli.errors import NumericalError
from sms_cli.synthesis import lmi


def _fail_ipm_and_watch_clarabel(monkeypatch) -> list:
    called = []
    monkeypatch.setattr(lmi, "_synthesize_ipm", lambda req, sc, rho: None)

    def builder(*a, **k):
        called.append(True)
        raise RuntimeError("Clarabel reached")

    monkeypatch.setattr(lmi, "_builder", builder)
    return called


def test_a_thesis_size_lmi_is_not_handed_to_clarabel(monkeypatch):
    from test_synthesis_ndo_scale import ndo_request

    req = ndo_request(1)  # n_q 14, n_e 47: the full form has 4 n_q + n_e = 103 rows
    assert 4 * req.nominal[0].n_q + req.nominal[0].n_e > lmi.CLARABEL_MAX_ROWS
    called = _fail_ipm_and_watch_clarabel(monkeypatch)
    with pytest.raises(NumericalError) as exc:
        lmi.synthesize(req)
    assert not called
    assert exc.value.exit_code == 3 and exc.value.problems[0].field == "synthesis.lmi"
    assert "103-row" in exc.value.problems[0].message and "initial_errors" in exc.value.problems[0].hint


def test_a_small_lmi_still_falls_back_to_clarabel(monkeypatch):
    from test_synthesis_ndo_scale import ndo_request

    req = ndo_request(1, n_arm=1, n_modes=2)
    assert 4 * req.nominal[0].n_q + req.nominal[0].n_e <= lmi.CLARABEL_MAX_ROWS
    called = _fail_ipm_and_watch_clarabel(monkeypatch)
    with pytest.raises(RuntimeError, match="Clarabel reached"):
        lmi.synthesize(req)
    assert called


def test_a_run_that_stops_halving_its_gap_is_stopped():
    """The stall rule of sdp.py: STALL_ITERATIONS iterations without halving the gap, μ or a residual, at any gap (the
    full PULSAR's chapter 4 problem sat at 1.5e-2 with steps of 1e-6 until max_iter before it; Table 4.3's |T| = 20
    problem halves μ and its residuals for tens of iterations while its relative gap sits near 1)."""
    from sms_cli.synthesis.sdp import STALL_ITERATIONS, stalled

    n = STALL_ITERATIONS
    assert not stalled([1.0] * n)  # too few iterations to tell
    assert stalled([1.0] + [0.6] * n)  # 0.6 > 0.5: not halved over the window
    assert not stalled([1.0] + [0.6] * (n - 1) + [0.49])  # halved on the last one
    assert not stalled([2.0 ** -k for k in range(3 * n)])  # a converging run
    assert stalled([1e-2] * (n + 1))
    # several measures (gap, μ, residuals): progress in any one of them is progress; a stall is none halving
    flat, falling = [1.0] * (n + 1), [2.0 ** -k for k in range(n + 1)]
    assert stalled(flat, flat, flat) and not stalled(flat, falling, flat) and not stalled(flat, flat, falling)
