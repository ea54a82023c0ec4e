"""Control laws of the simulator (issue 7 item 3): base attitude, arm joints, end-effector tracking.

- ``attitude``: QuaternionPD, MrpFeedback (Basilisk mrpFeedback), SlidingModeAttitude (seed 000),
  TwistingAttitude and BacksteppingAttitude (seed 003);
- ``arm``: JointPD (seed 001), JointSMC (seed 003), ComputedTorque, ComputedTorqueSMC (seed 000);
- ``resolved_rate``: ResolvedRate, generalized-Jacobian end-effector tracking (seed 001);
- ``plant_models``: inertia, internal momentum and joint-space dynamics from the SystemModel;
- ``schema``: mission-file specs (``law:`` discriminator) and the ``build_*`` factories.
Frames and units: ``sms_cli.sim.interfaces``. Importing this package does not import numpy.
"""

from __future__ import annotations

from sms_cli.sim.laws.schema import (
    ArmLawSpec,
    AttitudeLawSpec,
    ResolvedRateSpec,
    build_arm_law,
    build_attitude_law,
    build_resolved_rate,
)

__all__ = [
    "ArmLawSpec",
    "AttitudeLawSpec",
    "ResolvedRateSpec",
    "build_arm_law",
    "build_attitude_law",
    "build_resolved_rate",
]
