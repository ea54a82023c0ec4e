"""The ``compile`` step of ``sms run``: model summary into results.json and ``robot.png``."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def run_compile(loaded, out: Path) -> dict[str, Any]:
    """Compile the mission's model; write the ``compile`` section and the robot drawing."""
    from sms_cli.model import compile_system
    from sms_cli.model.summary import model_summary
    from sms_cli.report.robot import draw_robot
    from sms_cli.results import ResultsDir, _jsonable

    sm = compile_system(loaded)
    summary = _jsonable(model_summary(sm))
    summary["mission_file"] = str(loaded.path)
    if sm.thrusters is not None:
        from sms_cli.thrusters.capability import capability_report

        summary["thrusters"] = _jsonable(capability_report(sm.thrusters))
    if loaded.mission.client is not None:
        from sms_cli.formation.stage import prepared
        from sms_cli.formation.summary import pair_summary

        _, client = prepared(loaded)
        summary["client"] = _jsonable(model_summary(client))
        if client.thrusters is not None:
            from sms_cli.thrusters.capability import capability_report

            summary["client"]["thrusters"] = _jsonable(capability_report(client.thrusters))
        summary["pair"] = _jsonable(pair_summary(loaded, sm, client))
    rd = ResultsDir(out)
    draw_robot(sm, rd.file("robot.png"))
    summary["artifacts"] = ["robot.png"]
    rd.update("compile", summary)
    return summary
