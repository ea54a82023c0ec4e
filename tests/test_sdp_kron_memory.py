"""The declared matrix variables' dense coefficients (p × n × n per block: 13.7 GB at Kraiem 2022's
size with |T| = 20) are neither built by ``direct.structured_problem`` nor formed by the solver's
Kronecker path (``sdp.solve_lmi``, method 'auto'): the quantities that used them (the scalings,
F(x) for the final positivity check) agree with the dense oracle (``LmiBlock.dense``) to round-off."""

import tracemalloc

import numpy as np
import pytest

from sms_cli.synthesis import lmi, matvar, sdp
from sms_cli.synthesis.direct import structured_problem
from sms_cli.synthesis.sdp import LmiBlock, groups, single_thread_blas, solve_lmi
from test_synthesis_ndo_scale import ndo_request


def _problem(tasks=3, n_arm=3, n_modes=8):
    req = ndo_request(tasks, n_arm=n_arm, n_modes=n_modes)
    sc = lmi._scale(req)
    return structured_problem(req, sc, lmi.EPS, lmi.Q_MAX)


def _declared_bytes(blocks) -> int:
    """Bytes the declared variables' dense coefficients would take."""
    return sum(8 * len(t.pos) * b.F0.size for b in blocks for t in b.terms)


def test_structured_problem_keeps_no_declared_coefficients():
    """The blocks hold (and keep alive, e.g. through views) far less than the declared
    coefficients: measured 6 % of them at this size (the undeclared variables' coefficients and F0)."""
    req = ndo_request(3, n_arm=3, n_modes=8)
    sc = lmi._scale(req)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        lay, c, blocks = structured_problem(req, sc, lmi.EPS, lmi.Q_MAX)
        held = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    dec = _declared_bytes(blocks)
    assert dec > 10e6  # the check means something: the declared coefficients would be large
    assert held < 0.1 * dec, (held, dec)


def _no_dense(monkeypatch):
    def refuse(*a, **k):
        raise AssertionError("declared variables' dense coefficients formed")

    monkeypatch.setattr(matvar, "coefficients", refuse)
    monkeypatch.setattr(sdp, "coefficients", refuse)
    dense = LmiBlock.dense
    monkeypatch.setattr(LmiBlock, "dense", lambda b: refuse() if b.terms else dense(b))


def test_build_and_kronecker_solve_never_form_the_declared_coefficients(monkeypatch):
    """With matvar.coefficients and LmiBlock.dense refusing, the problem builds and solves to the
    same optimum as the dense path (the QR fallback, which forms S one block at a time, is not
    needed here: qr_steps == 0)."""
    lay, c, blocks = _problem()
    with single_thread_blas():
        dense = solve_lmi(c, blocks, tol=lmi.IPM_TOL, method="dense")
    _no_dense(monkeypatch)
    lay, c, blocks = _problem()
    with single_thread_blas():
        kron = solve_lmi(c, blocks, tol=lmi.IPM_TOL)
    assert kron.status == dense.status == "optimal" and kron.qr_steps == 0
    assert abs(c @ kron.x - c @ dense.x) <= 1e-4 * (c @ dense.x)
    assert kron.min_eig > -1e-9


def test_kronecker_scalings_and_values_equal_the_dense_ones():
    """The solver's row/column scalings and F(x) from the Kronecker form equal those from the
    formed coefficients (the oracle) to round-off, so the iterates are the dense-coefficient ones."""
    lay, c, blocks = _problem(tasks=2)
    oracle = [LmiBlock(b.idx, b.F0, b.dense(), b.group) for b in blocks]
    assert any(b.terms for b in blocks)
    _, col = groups(blocks, lay.m)
    _, col_o = groups(oracle, lay.m, declared=False)
    assert np.allclose(col, col_o, rtol=1e-13, atol=0)
    gs, _ = groups(blocks, lay.m)
    gs_o, _ = groups(oracle, lay.m)
    for g, go in zip(gs, gs_o):
        assert np.allclose(g.C, go.C, rtol=1e-13, atol=1e-13 * np.max(np.abs(go.C)))
    x = np.random.default_rng(1).normal(size=lay.m)
    for b, o in zip(blocks, oracle):
        ref = o.F0 + np.tensordot(x[o.idx], o.F, axes=1)
        assert np.allclose(b.value(x), ref, rtol=1e-12, atol=1e-12 * max(np.max(np.abs(ref)), 1.0))


def test_block_refuses_coefficients_for_declared_variables():
    lay, c, blocks = _problem(tasks=1)
    b = next(b for b in blocks if b.terms)
    with pytest.raises(ValueError, match="undeclared"):
        LmiBlock(b.idx, b.F0, b.dense(), b.group, b.terms)


def test_chunked_qr_factors_the_whole_of_s(monkeypatch):
    """``_qr_factor`` with chunks of a few blocks' rows gives the R of S whole: RᵀR = SᵀS = M (the
    Schur complement formed densely), as the single QR of small problems does."""
    from test_sdp_kron_schur import _random_blocks, _scalings

    rng = np.random.default_rng(7)
    blocks, m = _random_blocks(rng, nb=5)
    gs, _ = groups(blocks, m)
    G = _scalings(rng, gs)
    At, St = zip(*(g.scaled(Gq) for g, Gq in zip(gs, G)))
    M = sdp.schur_matrix(gs, list(St), m, list(At))
    one = sdp._qr_factor(gs, list(St), m)
    monkeypatch.setattr(sdp, "QR_CHUNK_BYTES", 8 * m * 50)  # 50 rows: two blocks (45 rows each) per chunk
    chunked = sdp._qr_factor(gs, list(St), m)
    for R in (one, chunked):
        assert R.shape == (m, m)
        assert np.allclose(R.T @ R, M, rtol=0, atol=1e-11 * np.max(np.abs(M)))
