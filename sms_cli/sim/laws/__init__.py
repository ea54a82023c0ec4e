"""Control laws of the simulator (issue 7 item 3): base attitude, arm joints, end-effector tracking.

- ``attitude``: QuaternionPD, MrpFeedback (Basilisk mrpFeedback), SlidingModeAttitude (Caldera 2019),
  TwistingAttitude and BacksteppingAttitude (Ruggiero 2020);
- ``arm``: JointPD (Chevallard 2019), JointSMC (Ruggiero 2020), ComputedTorque, ComputedTorqueSMC (Caldera 2019);
- ``resolved_rate``: ResolvedRate, generalized-Jacobian end-effector tracking (Chevallard 2019);
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
