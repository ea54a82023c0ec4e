"""The compiled wheel pyramid of Caldera 2019 against the thesis's configuration matrix (3.5).

Caldera 2019, §3.2 "Reaction Wheels Dynamic Model" (thesis text lines 370-389):

* L370: "reaction wheels (RWs) in pyramidal configuration with a skew angle β";
* L376, eq. (3.5): Z = [[sin β, 0, −sin β, 0], [0, sin β, 0, −sin β], [cos β, cos β, cos β, cos β]],
  columns = wheel spin axes in the base frame J_0;
* L389, eq. (3.7): τ_rw = pinv(Z)(−τ_c − ω × Z h) — allocation by the pseudo-inverse of Z;
* L792-793: saturation torque 0.4 N m per wheel; "α = 90°" (azimuth step) and "skew angle
  α = 57.6°" (the β of (3.5)).

The numbers below are (3.5) evaluated at β = 57.6° (sin β = 0.844328, cos β = 0.535827), written as
literals rather than recomputed with the compiler's formula, and the reading notes' derived values
(notes 000 §2.3): pinv(Z) rows [±0.5922, 0, 0.4666] and [0, ±0.5922, 0.4666]; body torque capacity
2u sin β = 0.675 N m on x, y and 4u cos β = 0.857 N m on z for u = 0.4 N m. With sin β and cos β
swapped (a 32.4° skew) every one of them is off by more than 0.1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

# (3.5) at β = 57.6°: columns are the spin axes of wheels 1..4
Z_THESIS = np.array([[0.844328, 0.0, -0.844328, 0.0],
                     [0.0, 0.844328, 0.0, -0.844328],
                     [0.535827, 0.535827, 0.535827, 0.535827]])
# notes 000 §2.3, pinv(Z) rows (4 decimals as printed there)
PINV_NOTES = np.array([[0.5922, 0.0, 0.4666],
                       [0.0, 0.5922, 0.4666],
                       [-0.5922, 0.0, 0.4666],
                       [0.0, -0.5922, 0.4666]])


@pytest.fixture(scope="module", params=["caldera_smallsat.yaml", "caldera_s1_slew.yaml"])
def system(request):
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    return compile_system(load_mission(ROOT / "missions" / request.param))


def test_compiled_axes_are_the_columns_of_eq_3_5(system):
    assert [w.name for w in system.wheels] == ["rw1", "rw2", "rw3", "rw4"]
    Z = np.array([w.axis for w in system.wheels]).T
    np.testing.assert_allclose(Z, Z_THESIS, atol=1e-6)
    # the skew angle itself, to the thesis's printed precision (57.6°): angle from the base +z
    skew = np.degrees(np.arccos(Z[2]))
    np.testing.assert_allclose(skew, 57.6, atol=0.05)
    # azimuth step "α = 90°" (L793)
    az = np.degrees(np.arctan2(Z[1], Z[0])) % 360
    np.testing.assert_allclose(az, [0, 90, 180, 270], atol=1e-6)


def test_allocation_is_the_pseudo_inverse_of_eq_3_5(system):
    from sms_cli.sim.actuators import WheelArray
    from sms_cli.sim.schema import AllocationSpec, WheelFriction

    arr = WheelArray(system, AllocationSpec(), WheelFriction())
    np.testing.assert_allclose(arr.A, Z_THESIS, atol=1e-6)
    np.testing.assert_allclose(arr.A_pinv, PINV_NOTES, atol=1e-4)
    # (3.7) with ω = 0: τ_rw = pinv(Z)(−τ_c); a unit z torque needs −1/(4 cos β) on each wheel
    np.testing.assert_allclose(arr.allocate(np.array([0.0, 0.0, 1.0]), np.zeros(4)), [-0.4666] * 4, atol=1e-4)
    np.testing.assert_allclose(arr.allocate(np.array([1.0, 0.0, 0.0]), np.zeros(4)), [-0.5922, 0, 0.5922, 0],
                               atol=1e-4)


def test_body_torque_capacity_of_the_pyramid(system):
    """Notes 000 §2.3: with |τ_w| ≤ u = 0.4 N m (L792) the body can get 0.675 N m on x and y and
    0.857 N m on z."""
    u = np.array([w.max_torque for w in system.wheels])
    np.testing.assert_allclose(u, 0.4)
    Z = np.array([w.axis for w in system.wheels]).T
    np.testing.assert_allclose(Z @ (u * np.array([1, 0, -1, 0])), [0.675, 0, 0], atol=1e-3)
    np.testing.assert_allclose(Z @ (u * np.array([0, 1, 0, -1])), [0, 0.675, 0], atol=1e-3)
    np.testing.assert_allclose(Z @ u, [0, 0, 0.857], atol=1e-3)
