"""``gains.yaml``: the gains ``sms synthesize`` writes and ``sms simulate`` reads.

Format (``format: sms-gains/1``; every list per actuator follows ``actuators``; SI units)::

    format: sms-gains/1
    mission: pulsar_simple            # mission name
    law: lmi                          # lmi | pd | lqr | smc
    variant: ndi_observer             # lmi only: ndi_observer | ndi_observer_ndo
    actuators: [rw1, ..., arm_joint_4]  # wheels first, then arm joints (v-index order)
    controller:
      units: acceleration             # 'acceleration': v = q̈_d + kp ε + kv ε̇ (1/s², 1/s), torque
                                      #   τ = M◇ v + D◇ q̇ + D◇_x x̂ (Kraiem 2022 (3.38)); 'torque':
                                      #   τ = kp ε + kv ε̇ (N m/rad, N m s/rad), ε = q_d − q
      kp: [...]
      kv: [...]
    observer:                         # lmi only
      states: [eta_1, ..., w0_x, w0_y, w0_z, etadot_1, ...]   # x = [η; ω0 (base frame); η̇]
      outputs: [w0_x, w0_y, w0_z]     # y = ω0, base frame, rad/s
      L: [[...], ...]                 # n_e × n_y: x̂̇ = A_e x̂ + B_q u + L (y − C_e x̂)
      Q_d: [[...], ...] | null        # NDO (chapter 4): L_d(q) = Q_d M◇(q)⁻¹, p(q̇) = Q_d q̇
    smc:                              # smc only, per axis of 'axes'
      axes: [x, y, z]
      slope: [...]                    # λ of σ = ė + λ e (1/s)
      c: [...]                        # switching gain (rad/s²), torque = … + c J tanh(μ σ)
      mu: [...]                       # smoothing (s/rad)
      disturbance_bound: [...]        # N m
      twisting: {r1: .., r2: .., C: .., K_m: .., K_M: ..}
    guarantee: {...}                  # γ, regions, initial-error bounds (free-form, for reports)
    verification: {passed: true, checks: [...]}
    simulation: {attitude: {law: smc, k: .., c: .., mu: ..}}   # pd/lqr/smc: sms simulate's law block
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError

from sms_cli.errors import InputError, Problem
from sms_cli.mission.base import StrictModel

FORMAT = "sms-gains/1"


class ControllerGains(StrictModel):
    units: Literal["acceleration", "torque"]
    kp: list[float]
    kv: list[float]


class ObserverGains(StrictModel):
    states: list[str]
    outputs: list[str]
    L: list[list[float]]
    Q_d: list[list[float]] | None = None


class TwistingGains(StrictModel):
    r1: float
    r2: float
    C: float
    K_m: float
    K_M: float


class SmcGainsFile(StrictModel):
    axes: list[str]
    slope: list[float]
    c: list[float]
    mu: list[float]
    disturbance_bound: list[float]
    twisting: TwistingGains | None = None


class GainsFile(StrictModel):
    """The whole ``gains.yaml`` document."""

    format: Literal["sms-gains/1"] = FORMAT
    mission: str
    law: Literal["lmi", "pd", "lqr", "smc"]
    variant: str | None = None
    actuators: list[str] = Field(default_factory=list)
    controller: ControllerGains | None = None
    observer: ObserverGains | None = None
    smc: SmcGainsFile | None = None
    guarantee: dict[str, Any] = Field(default_factory=dict)
    verification: dict[str, Any] = Field(default_factory=dict)
    simulation: dict[str, Any] = Field(
        default_factory=dict, description="pd/lqr/smc: the mission-file 'simulation.attitude' block these gains "
                                          "give (paste it, or let the simulate stage read it)")

    def check_dimensions(self) -> None:
        n = len(self.actuators)
        if self.controller is not None and (len(self.controller.kp) != n or len(self.controller.kv) != n):
            raise ValueError(f"controller.kp and kv need one value per actuator ({n})")
        if self.observer is not None:
            ne, ny = len(self.observer.states), len(self.observer.outputs)
            if len(self.observer.L) != ne or any(len(r) != ny for r in self.observer.L):
                raise ValueError(f"observer.L must be {ne}×{ny} (states × outputs)")
            if self.observer.Q_d is not None and (len(self.observer.Q_d) != n or any(len(r) != n for r in self.observer.Q_d)):
                raise ValueError(f"observer.Q_d must be {n}×{n}")


def write_gains(path: Path | str, gains: GainsFile) -> Path:
    """Validate and write atomically."""
    import yaml

    from sms_cli.results import _jsonable, write_text_atomic

    gains.check_dimensions()
    data = _jsonable(gains.model_dump(mode="python", exclude_none=True))
    text = "# written by sms synthesize; format documented in sms_cli/synthesis/gains_io.py\n"
    text += yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120)
    return write_text_atomic(path, text)


def read_gains(path: Path | str) -> GainsFile:
    """Read and validate; InputError (exit 2) naming the field on any problem."""
    import yaml

    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such gains file", [Problem(f"{p}: no such gains file",
                                                               hint="run 'sms synthesize MISSION' first")])
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
        g = GainsFile.model_validate(data)
        g.check_dimensions()
    except yaml.YAMLError as exc:
        raise InputError(f"{p}: not valid YAML: {exc}") from exc
    except ValidationError as exc:
        probs = [Problem(e["msg"], field=".".join(str(x) for x in e["loc"])) for e in exc.errors()]
        raise InputError(f"{p}: invalid gains file", probs) from exc
    except ValueError as exc:
        raise InputError(f"{p}: invalid gains file: {exc}") from exc
    return g
