"""Checks of a mission's thrusters against its simulation (``sms compile``, before ``sms simulate``):
the control period is a whole number of firing cycles, and the set has every torque direction the
attitude law asks of it when the thrusters actuate the attitude (``uses_thrusters``). No law of sms
commands a base force today, so force authority is reported (``capability``) but not required."""

from __future__ import annotations

from sms_cli.errors import InputError, Problem
from sms_cli.thrusters.capability import missing_directions


def check_thrusters(sm, loaded) -> None:
    ts, spec = getattr(sm, "thrusters", None), loaded.mission.simulation
    if ts is None or spec is None:
        return
    from sms_cli.sim.timing import uses_thrusters

    problems = []
    where = loaded.source.locate(("thrusters", "firing_cycle"), prefer_key=True)
    period = 1.0 / spec.control_rate
    k = period / ts.firing_cycle
    if abs(k - round(k)) > 1e-9 * max(k, 1) or round(k) < 1:
        problems.append(Problem(
            f"the control period ({period:g} s) is not a whole number of firing cycles ({ts.firing_cycle:g} s): one "
            "allocation per control tick repeats its firing pattern in each cycle of the tick",
            where, "thrusters.firing_cycle",
            f"set simulation.control_rate to {1 / ts.firing_cycle:g} Hz (one cycle per tick) or a divisor of it"))
    if not uses_thrusters(spec):  # reported by sms compile, but nothing fires them
        sm.warnings.append(Problem(
            "no phase uses the thrusters (the attitude law drives the wheels and no phase is free-flying): "
            "the simulation does not fire them", loaded.source.locate(("thrusters",), prefer_key=True), "thrusters",
            "set simulation.attitude_actuator: thrusters (or a free-flying phase), or remove the thrusters: section"))
    if uses_thrusters(spec) and spec.attitude is not None:
        missing = missing_directions(ts, "torque")
        if missing:
            problems.append(Problem(
                f"the thrusters control the attitude but produce no pure torque along {', '.join(missing)}",
                loaded.source.locate(("thrusters",), prefer_key=True), "thrusters",
                "add thrusters whose torque r × d has a component along those axes (layout: cube has full 6-D authority)"))
    if problems:
        raise InputError(f"{loaded.path}: {len(problems)} problem(s) with the thrusters", problems)
