"""The ``simulation:`` section against the compiled model: every name it refers to must exist.

``validate_simulation`` runs at ``sms compile`` (and before ``sms simulate`` opens its recording),
so a mistyped joint or payload is exit code 2 with its mission location, not a failure mid-run.
Names checked: waypoint joints (arm joints only: wheels follow the attitude law, spring joints
are passive) and the payloads of ``attach``/``detach``. The section names no frames today (the
end-effector target is of ``robot.end_effector``, checked by the compiler).
"""

from __future__ import annotations

import difflib

from sms_cli.errors import InputError, Problem


def _hint(name: str, candidates: list[str], kind: str) -> str:
    close = difflib.get_close_matches(name, candidates, n=1)
    if close:
        return f"did you mean '{close[0]}'?"
    return f"{kind}: {', '.join(candidates)}" if candidates else f"the model has no {kind}"


def validate_simulation(sm, loaded) -> None:
    """Raise ``InputError`` listing every name in ``loaded.mission.simulation`` that ``sm`` (the
    compiled ``SystemModel``) does not have, each with its mission location and a suggestion."""
    spec = loaded.mission.simulation
    if spec is None:
        return
    arm = [a.name for a in sm.arm]
    wheels = {w.name for w in sm.wheels}
    springs = {s.joint for s in sm.springs}
    payloads = sorted(sm.payloads)
    problems: list[Problem] = []
    for i, phase in enumerate(spec.phases):
        at = ("simulation", "phases", i)
        for j, wp in enumerate(phase.waypoints):
            for name in wp.joints:
                if name in arm:
                    continue
                key = at + ("waypoints", j, "joints", name)
                if name in wheels or name in springs:
                    what = "a reaction wheel (the attitude law drives it)" if name in wheels else "a passive spring joint"
                    msg, hint = f"'{name}' is {what}, not an arm joint", f"waypoints move arm joints only ({', '.join(arm) or 'none'})"
                else:
                    msg, hint = f"no arm joint named '{name}'", _hint(name, arm, "arm joints")
                problems.append(Problem(msg, loaded.source.locate(key, prefer_key=True), ".".join(map(str, key)), hint))
        for verb in ("attach", "detach"):
            for j, name in enumerate(getattr(phase, verb)):
                if name not in sm.payloads:
                    key = at + (verb, j)
                    problems.append(Problem(f"no payload named '{name}'", loaded.source.locate(key),
                                            ".".join(map(str, key)), _hint(name, payloads, "payloads")))
    bias = spec.sensors.joints.bias
    if not isinstance(bias, (int, float)) and len(bias) != len(arm):
        key = ("simulation", "sensors", "joints", "bias")
        problems.append(Problem(f"the joint sensors' bias has {len(bias)} values; the arm has {len(arm)} joint(s)",
                                loaded.source.locate(key), ".".join(key),
                                "give one value, added to every arm joint's angle and rate"))
    if problems:
        raise InputError(f"{loaded.path}: {len(problems)} problem(s) in the simulation section", problems)
    from sms_cli.thrusters.check import check_thrusters

    check_thrusters(sm, loaded)
