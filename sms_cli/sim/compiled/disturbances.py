"""Compiled (numba) disturbance wrenches (``simulation.disturbances``): THE implementation of the external
wrench on the base that both loops add to the plant's generalized forces at each plant step
(``Simulation._disturbance`` calls it; the compiled loop every sub-step).

A disturbance is a row of ``table`` (DIST_COLS): [constant (1) or pulse (0), start (s), duration (s),
inertial (1) or base (0) frame, force (3, N), torque (3, N m)]. A pulse acts for start ≤ t < start + duration.
The wrench [f; n] is in the base frame (an inertial one is rotated by Rᵀ, R = R(q) base → world).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT

DIST_CONSTANT, DIST_START, DIST_DURATION, DIST_INERTIAL, DIST_FORCE, DIST_TORQUE, DIST_COLS = 0, 1, 2, 3, 4, 7, 10


def disturbance_table(disturbances) -> np.ndarray:
    """The rows of ``simulation.disturbances`` (``DisturbanceSpec``) as the kernels take them."""
    table = np.zeros((len(disturbances), DIST_COLS))
    for i, d in enumerate(disturbances):
        table[i, DIST_CONSTANT] = float(d.kind == "constant")
        table[i, DIST_START], table[i, DIST_DURATION] = float(d.start), float(d.duration)
        table[i, DIST_INERTIAL] = float(d.frame == "inertial")
        table[i, DIST_FORCE:DIST_FORCE + 3] = np.asarray(d.force, float)
        table[i, DIST_TORQUE:DIST_TORQUE + 3] = np.asarray(d.torque, float)
    return table


@njit(**JIT)
def disturbance_wrench(table, t, q, out):
    """The sum of the disturbances active at time t (s) on the base at configuration q (quaternion q[3:7],
    xyzw), [f; n] in the base frame, into out (6)."""
    for a in range(6):
        out[a] = 0.0
    x, y, z, w = q[3], q[4], q[5], q[6]
    R = ((1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
         (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
         (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))
    for k in range(table.shape[0]):
        start = table[k, DIST_START]
        if not (table[k, DIST_CONSTANT] != 0.0 or (start <= t < start + table[k, DIST_DURATION])):
            continue
        for part in range(2):
            at = DIST_FORCE if part == 0 else DIST_TORQUE
            f0, f1, f2 = table[k, at], table[k, at + 1], table[k, at + 2]
            if table[k, DIST_INERTIAL] != 0.0:  # world → base: Rᵀ f
                f0, f1, f2 = (R[0][0] * f0 + R[1][0] * f1 + R[2][0] * f2, R[0][1] * f0 + R[1][1] * f1 + R[2][1] * f2,
                              R[0][2] * f0 + R[1][2] * f1 + R[2][2] * f2)
            out[3 * part] += f0
            out[3 * part + 1] += f1
            out[3 * part + 2] += f2


@njit(**JIT)
def disturbance_wrenches(table, ts, qs, out):
    """``disturbance_wrench`` at each (ts[i], qs[i]) into out[i] (the recording's /base/wrench)."""
    for i in range(ts.shape[0]):
        disturbance_wrench(table, ts[i], qs[i], out[i])
