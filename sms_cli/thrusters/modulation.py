"""On/off (PWM) modulation of allocated thrusts within one firing cycle T (s).

Thruster i commanded x_i of its max force F_i fires at F_i from the cycle start for
``t_i = Q(x_i / F_i · T)``: the on-time rounded to the nearest multiple of ``quantization · T``, then
set to zero when it is below ``mib`` (the minimum impulse bit read as a minimum firing time,
Vicariotto 2023 L548 "the minimum firing time of a single thruster", Table 3.1 L553: 0.025 s; the
table's "MIB on firing fraction 4 %" (L555) is not 0.025 / 0.2 = 12.5 % and is not used).

Bound (``impulse_error_bound``): the delivered impulse of thruster i over the cycle differs from the
commanded F_i t_i* (t_i* = x_i / F_i · T) by at most F_i e_i with e_i = quantization · T / 2 when the
rounded on-time is ≥ mib, and e_i = t_i* (the whole firing, < mib + quantization · T / 2) when it is
dropped. The cycle-averaged delivered wrench then differs from the allocated one B x by at most
Σ_i |b_i| F_i e_i / T per component.
"""

from __future__ import annotations

import numpy as np


def on_times(thrust: np.ndarray, max_force: np.ndarray, cycle: float, mib: float, quantization: float) -> np.ndarray:
    """(n,) on-times (s) in [0, cycle] for the allocated thrusts (N); see the module docstring."""
    t = np.clip(np.asarray(thrust, float) / max_force, 0.0, 1.0) * cycle
    if quantization > 0:
        step = quantization * cycle
        t = np.minimum(np.rint(t / step) * step, cycle)
    t[t < mib] = 0.0
    return t


def impulse_error_bound(thrust: np.ndarray, max_force: np.ndarray, cycle: float, mib: float,
                        quantization: float) -> np.ndarray:
    """(n,) largest |on-time − x_i/F_i · T| (s) the modulation can make for these thrusts."""
    t_star = np.clip(np.asarray(thrust, float) / max_force, 0.0, 1.0) * cycle
    half = 0.5 * quantization * cycle
    dropped = t_star < mib + half
    return np.where(dropped, np.maximum(t_star, half), half)
