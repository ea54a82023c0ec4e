"""Linear modal analysis of the flexible system (pulsar_simple: two panels, Kraiem 2022 Table 3.3)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import scipy.io

from conftest import MISSIONS, compile_path
from sms_cli.analysis.modal import coupled_modes, export, linearize
from sms_cli.model.modal import coupled_frequencies

# Kraiem 2022 Table 3.3 (L2276-2283): clamped panel frequencies, rad/s, each panel has the same five.
CLAMPED = 2 * np.pi * np.array([0.16, 0.70, 1.08, 1.21, 3.05])


def _pulsar(base_scale: float = 1.0):
    sm = compile_path(MISSIONS / "pulsar_simple.yaml")
    if base_scale != 1.0:
        Y = sm.model.inertias[1]
        sm.model.inertias[1] = pin.Inertia(Y.mass * base_scale, Y.lever, Y.inertia * base_scale)
    return sm


def _freqs(sm, joints="free"):
    return np.sort([m["frequency_rad_s"] for m in coupled_modes(linearize(sm, joints=joints))])


@pytest.mark.parametrize("joints", ["free", "locked"])
def test_coupled_frequencies_lie_above_the_clamped_ones(joints):
    f = _freqs(_pulsar(), joints)
    clamped = np.sort(np.repeat(CLAMPED, 2))
    assert len(f) == 10
    assert np.all(f > clamped * (1 + 1e-6))


def test_coupled_frequencies_converge_to_clamped_as_base_inertia_grows():
    clamped = np.sort(np.repeat(CLAMPED, 2))
    gaps = [np.max(_freqs(_pulsar(s)) / clamped - 1) for s in (1.0, 10.0, 100.0, 1e4)]
    assert all(b < a for a, b in zip(gaps, gaps[1:]))
    assert gaps[-1] < 1e-4
    # the coupling shift scales like 1/(base inertia): ×100 inertia → gap ÷ ~100
    assert gaps[2] / gaps[3] == pytest.approx(100, rel=0.05)


def test_locking_the_joints_lowers_the_coupled_frequencies():
    """More free inertial coordinates (arm, wheels) reduce the modal effective mass → higher frequencies."""
    sm = _pulsar()
    assert np.all(_freqs(sm, "free") >= _freqs(sm, "locked") - 1e-12)


def test_frequencies_agree_with_undamped_generalized_eigenproblem():
    """|λ| of the damped state matrix vs sqrt of eig(K, M) (SystemModel's modal module)."""
    sm = _pulsar()
    np.testing.assert_allclose(_freqs(sm), coupled_frequencies(sm), rtol=1e-5)


def test_damping_ratios_near_the_modal_damping():
    modes = coupled_modes(linearize(_pulsar()))
    z = np.array([m["damping"] for m in modes])
    assert np.all((z > 0.004) & (z < 0.01))  # ζ = 0.005 per clamped mode, raised a little by coupling


def test_state_space_structure_and_export(tmp_path):
    sm = _pulsar()
    lin = linearize(sm)
    n = lin.A.shape[0]
    assert n == 2 * sm.nx and lin.B.shape == (n, len(lin.inputs)) and lin.C.shape == (n, n)
    assert lin.residual < 1e-12  # the initial state is an equilibrium
    assert "tau_arm_joint_1" in lin.inputs and "base_n_z" in lin.inputs
    # a base torque about z accelerates the base yaw rate with the inverse of the system inertia
    j = lin.inputs.index("base_n_z")
    i = lin.states.index("base_rz_rate")
    assert lin.B[i, j] > 0
    files = export(lin, tmp_path / "modal_0", ["npz", "mat"])
    assert [p.suffix for p in files] == [".npz", ".mat"]
    z = np.load(files[0])
    np.testing.assert_array_equal(z["A"], lin.A)
    assert list(z["states"]) == lin.states
    m = scipy.io.loadmat(files[1])
    np.testing.assert_allclose(m["B"], lin.B)
    assert [str(s[0]) if not isinstance(s, str) else s for s in m["inputs"].ravel()] == lin.inputs


def test_spinning_wheels_keep_an_equilibrium_and_add_gyroscopic_coupling():
    sm = _pulsar()
    sm.v0[sm.idx.wheels] = 100.0
    lin = linearize(sm)
    assert lin.residual < 1e-9
    f_spin = np.sort([m["frequency_rad_s"] for m in coupled_modes(lin)])
    assert len(f_spin) >= 10  # panel modes plus gyroscopic (nutation) modes of the base
