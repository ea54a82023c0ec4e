"""The timing of a recording, written into it as the MCAP metadata record ``sms.timing`` so that
another engine can replay the run, and read back by ``sms inspect``.

What both simulation loops do (``engine.Simulation.run_python`` and ``compiled.loop.run_ticks``),
with T = 1 / control_rate the control period and dt the plant step (T = n·dt):

- control ticks are at t_k = k·T from t = 0 (a phase lasts a whole number of ticks, so the ticks
  stay on that grid); at t_k the controller reads the state at t_k and its command (wheel and
  joint torques) is held (zero-order hold) over [t_k, t_k + T], i.e. over n plant steps of
  fixed-step RKMK4 (``sms_cli.dynamics.integrator.rkmk4_step``);
- a sample stamped t (a plant-step end) holds the state after the step ending at t and, on the
  torque topics (and ``/base/wrench``, the thruster and disturbance wrench on the base, recorded by
  the missions that have them), the torque applied during that step, (t − dt, t]. At a tick t_k that is the
  command computed at t_(k−1) = t_k − T and held over [t_k − T, t_k]: the command computed at
  t_k is stamped at t_k + T (every plant step of its period when recording every step);
- the sample at t = 0 holds the initial state and zero torques (nothing acted before t = 0).

A recording is replayable from its own topics when every control tick is sampled (the recording
rate is a whole multiple of the control rate, or every plant step is recorded), the applied torque
is the held command (wheel friction and disturbances vary it within a period: then every plant
step must be recorded).
"""

from __future__ import annotations

import math

TIMING_METADATA = "sms.timing"
TIMING_VERSION = "1"
COMMAND_TOPICS = ("/wheels/torque", "/joints/torque", "/base/wrench")
_TOL = 1e-9

HOLD = ("zero-order hold: the command computed from the state at a control tick t_k = k * control_period_s "
        "(from t = 0) is applied over [t_k, t_k + control_period_s]")
COMMAND_STAMP = ("a torque sample (/wheels/torque, /joints/torque; /base/wrench, base frame, when the mission has thrusters "
                 "or disturbances) stamped at t is the torque applied over the plant step "
                 "ending at t, (t - plant_dt_s, t]; at a control tick t_k it is the command computed at t_k - control_period_s "
                 "and applied over [t_k - control_period_s, t_k] (the command computed at t_k is stamped at t_k + control_period_s)")
STATE_STAMP = ("state topics (/attitude, /base/rate, /base/position, /wheels/speed, /joints/position, /joints/rate, "
               "/modes/eta) stamped at t hold the plant state at t, after the plant step ending at t; /attitude/reference "
               "and /joints/reference hold the references the torque stamped at t was computed for")
INITIAL_SAMPLE = ("the sample at t = 0 holds the initial state and zero torques: nothing acted before t = 0; the first "
                  "command, computed from the state at t = 0, is stamped at t = control_period_s (at plant_dt_s when every "
                  "plant step is recorded)")
INTEGRATOR = ("rkmk4: fixed-step classical 4th-order Runge-Kutta-Munthe-Kaas (the base pose on its Lie group, "
              "sms_cli.dynamics.integrator.rkmk4_step), one step of plant_dt_s, the torque constant over the step")
REPLAY = ("from the initial state (the mission in the metadata record 'mission', equal to the t = 0 sample), integrate "
          "plant steps of plant_dt_s with the torque stamped at t_(k+1) applied over [t_k, t_(k+1)]; /events 'phase' "
          "marks the phase starts (base mode, payloads attached or released)")
CAVEATS = ("while a wheel is at its speed limit the limiter reduces its torque within a control period: exact at the "
           "control rate only when no wheel reaches its limit, always exact when every plant step is recorded; "
           "a phase with a fixed base zeroes the base velocity at its start and holds the base (its reaction is "
           "/base/reaction); joint-stop impulses are not recorded inputs (/events marks the stops)")


def _multiple(a: float, b: float) -> int | None:
    """a / b when it is a whole number ≥ 1 (to 1e-9), else None."""
    r = a / b
    n = round(r)
    return n if n >= 1 and abs(r - n) <= _TOL * max(1.0, r) else None


def uses_thrusters(spec) -> bool:
    """Whether an attitude law acts through thrusters in some phase (the base torque is then not recorded)."""
    if spec.attitude is None or spec.ndi is not None:
        return False
    return any(p.base_mode == "free-flying" or (p.base_mode == "rotation-free-floating" and spec.attitude_actuator == "thrusters")
               for p in spec.phases)


def records_base_wrench(spec) -> bool:
    """Whether the recording has ``/base/wrench``: only when something other than the wheels and the
    joints acts on the base (thrusters, disturbances); otherwise that wrench is zero."""
    return uses_thrusters(spec) or bool(spec.disturbances)


def not_replayable_reasons(spec, real_thrusters: bool = False) -> list[str]:
    """Why a recording of this simulation cannot be replayed from its own topics (empty: it can);
    ``real_thrusters``: the mission's thrusters: section drives the base (sms_cli.thrusters)."""
    rate, r, dt = float(spec.control_rate), spec.record_rate, float(spec.dt)
    out = []
    every_step = r is None or (_multiple(float(r), rate) is not None and float(r) * dt >= 1.0 - _TOL)
    if r is not None and _multiple(float(r), rate) is None:
        below = "below" if float(r) < rate else "not a whole multiple of"
        out.append(f"the recording rate ({float(r):g} Hz) is {below} the control rate ({rate:g} Hz): the torque of some "
                   "control periods is not in the recording (record at the control rate or a multiple of it)")
    fr = spec.wheel_friction
    if (fr.coulomb != 0 or fr.viscous != 0) and not every_step:
        out.append("wheel friction changes the applied wheel torque within each control period: record every plant step "
                   "(record_rate: null)")
    if spec.disturbances and not every_step:
        out.append("a disturbance (a pulse's start or end, an inertial-frame wrench turning with the base) changes the "
                   "wrench on the base within a control period: record every plant step (record_rate: null)")
    if real_thrusters and uses_thrusters(spec):
        out.append("real thrusters switch within plant steps and spend propellant (the base mass changes): /base/wrench "
                   "holds each step's average wrench, not the firings")
    return out


def timing_metadata(spec, real_thrusters: bool = False) -> dict[str, str]:
    """The ``sms.timing`` metadata record of a recording of ``spec`` (a SimulationSpec): strings only."""
    rate, r, dt = float(spec.control_rate), spec.record_rate, float(spec.dt)
    period = 1.0 / rate
    reasons = not_replayable_reasons(spec, real_thrusters)
    return {
        "version": TIMING_VERSION,
        "control_rate_hz": repr(rate),
        "control_period_s": repr(period),
        "plant_dt_s": repr(dt),
        "plant_steps_per_control_period": str(int(round(period / dt))),
        "record_rate_hz": "every plant step" if r is None else repr(float(r)),
        "record_period_s": repr(dt) if r is None else repr(1.0 / float(r)),
        "integrator": INTEGRATOR,
        "hold": HOLD,
        "command_topics": ",".join(COMMAND_TOPICS),
        "command_stamp": COMMAND_STAMP,
        "state_stamp": STATE_STAMP,
        "initial_sample": INITIAL_SAMPLE,
        "replay": REPLAY,
        "caveats": CAVEATS,
        "replayable": "no" if reasons else "yes",
        "not_replayable_because": "; ".join(reasons),
    }


def missing_ticks(sample_ns, control_period_s: float, plant_dt_s: float) -> tuple[int, int, float | None]:
    """(control ticks up to the last sample, how many have no sample, the first missing tick's time
    in s or None) from the log times (ns) of one sampled topic."""
    import numpy as np

    stamps = np.unique(np.fromiter((int(t) for t in sample_ns), dtype=np.int64))
    if stamps.size == 0:
        return 0, 0, None
    tol = max(1000.0, 1e-4 * plant_dt_s * 1e9)  # the summed plant steps drift by far less than 1 µs
    T = control_period_s * 1e9
    ticks = np.arange(int(math.floor(stamps[-1] / T + 1e-6)) + 1) * T
    i = np.minimum(np.searchsorted(stamps, ticks - tol, side="left"), stamps.size - 1)
    gap = np.nonzero(np.abs(stamps[i] - ticks) > tol)[0]
    return int(ticks.size), int(gap.size), (float(ticks[gap[0]] / 1e9) if gap.size else None)
