"""The thrusters' MCAP topics of one sample (wrenches base joint frame [f; n], N and N m; like the
torques, the values applied over the plant step ending at the sample's time, ``sms_cli.sim.timing``):

- ``/thrusters/commanded``: the ideal wrench the attitude law asked for (held over the control tick);
- ``/thrusters/delivered``: the wrench the firings applied, averaged over the plant step;
- ``/thrusters/thrust``: each thruster's thrust averaged over the plant step (N);
- ``/thrusters/propellant``: propellant used since t = 0 and left in the tank (kg).
"""

from __future__ import annotations

import numpy as np

_W = ("fx", "fy", "fz", "nx", "ny", "nz")


def thruster_topics(drive, zero: bool = False) -> dict[str, dict]:
    """Topics of the sample at the end of the last plant step (``zero``: the initial sample)."""
    c = np.zeros(6) if zero else drive.commanded
    d = np.zeros(6) if zero else drive.delivered
    f = np.zeros(drive.ts.n) if zero else drive.thrust_step
    return {"/thrusters/commanded": {k: float(v) for k, v in zip(_W, c)},
            "/thrusters/delivered": {k: float(v) for k, v in zip(_W, d)},
            "/thrusters/thrust": {n: float(v) for n, v in zip(drive.ts.names, f)},
            "/thrusters/propellant": {"used_kg": float(drive.used), "left_kg": float(drive.ts.propellant - drive.used)}}
