"""``sms report``: one self-contained HTML file from a results folder (plots embedded as PNG).

Only sections whose data exist appear. The bytes depend only on the results folder (and the
mission file, for the robot drawing when ``robot.png`` is absent): no wall-clock time, no
external resources, no scripts.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from sms_cli.errors import InputError, Location, Problem
from sms_cli.report.model import Figure, Section, png_uri
from sms_cli.results import RESULTS_FILE, write_text_atomic

TEMPLATE = "report.html.j2"


def _robot_png(folder: Path, results: dict[str, Any], mission: Path | None) -> bytes | None:
    f = folder / "robot.png"
    if f.is_file():
        return f.read_bytes()
    path = mission or Path(results.get("compile", {}).get("mission_file") or results.get("run", {}).get("mission_file") or "")
    if not str(path) or not Path(path).is_file():
        return None
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.report.robot import draw_robot

    loaded = load_mission(path)
    if loaded.mission.robot is None:
        return None
    return draw_robot(compile_system(loaded))


def _simulation_figures(folder: Path, sim: dict[str, Any], wheels: list[dict]) -> list[Figure]:
    from sms_cli.report import figures as F

    out: list[Figure] = []
    png = F.wheel_momentum_png(folder / sim.get("files", {}).get("csv", "simulation.csv"), wheels)
    if png:
        out.append(Figure("Reaction-wheel momentum per wheel and of the array (N m s); capacities in the legend.",
                          png_uri(png), "wheel momentum"))
    mcap = Path(sim.get("files", {}).get("mcap") or "simulation.mcap")
    if not mcap.is_file():
        mcap = folder / mcap.name
    if mcap.is_file():
        try:
            topics = F.read_topics(mcap, ["/joints/position", "/joints/reference", "/ee/position", "/base/position"])
        except Exception as exc:  # noqa: BLE001 - a damaged recording must not stop the report
            topics = {}
            out.append(Figure(f"(the recording {mcap.name} could not be read: {type(exc).__name__})", "", ""))
        for fn, cap in ((F.joint_tracking_png, "Joint positions against their references (rad for revolute, m for prismatic)."),
                        (F.ee_path_png, "End-effector and base-origin paths in the world frame (equal axes, m).")):
            png = fn(topics)
            if png:
                out.append(Figure(cap, png_uri(png), cap))
    return [f for f in out if f.src]


def _verdict(results: dict[str, Any], verdicts: list[dict]) -> tuple[str, str]:
    stages = results.get("run", {}).get("stages", [])
    failed = [s["name"] for s in stages if s.get("status") in ("failed", "skipped", "interrupted")]
    bad = [v for v in verdicts if v["status"] != "pass"]
    if failed:
        return f"stages failed: {', '.join(failed)}" + (f"; {len(bad)} requirement(s) not met" if bad else ""), "fail"
    if bad:
        return f"{len(bad)} of {len(verdicts)} requirements not met", "fail"
    if verdicts:
        return f"all {len(verdicts)} requirements met", "pass"
    return "no requirements defined", "neutral"


def collect(folder: Path, mission: Path | None = None) -> dict[str, Any]:
    """The template context of a results folder."""
    from sms_cli.report import sections as S

    f = folder / RESULTS_FILE
    if not f.is_file():
        raise InputError(problems=[Problem(f"no {RESULTS_FILE} in {folder}", Location(folder),
                                           hint="run the mission first: sms run MISSION.yaml -o " + str(folder))])
    raw = f.read_bytes()
    try:
        results = json.loads(raw)
    except json.JSONDecodeError as exc:
        raise InputError(problems=[Problem(f"not JSON: {exc.msg}", Location(f, exc.lineno, exc.colno))]) from None
    run = results.get("run", {})
    verdicts = list(results.get("requirements", {}).get("verdicts", []))
    if mission is not None:
        from sms_cli.check.requirements import evaluate_all
        from sms_cli.mission.load import load_mission

        loaded = load_mission(mission)
        verdicts = [v.as_dict() for v in evaluate_all(list(loaded.mission.requirements), results)]
        if not run:
            from sms_cli.run.provenance import sha256_file

            run = {"mission": loaded.mission.name, "mission_file": str(loaded.path),
                   "description": loaded.mission.description.strip(),
                   "files": {"mission": {"path": str(loaded.path), "sha256": sha256_file(loaded.path)}}}
    name = run.get("mission") or results.get("compile", {}).get("name") or folder.name
    sections: list[Section] = []
    stage_rows = [[s["name"], s["status"], f"{s['seconds']:.2f}" if s.get("seconds") else "—",
                   (s.get("message") or "").split("\n")[0][:160]] for s in run.get("stages", [])]
    if "compile" in results:
        sections.append(S.model_section(results["compile"], folder, _robot_png(folder, results, mission)))
    if "budget" in results:
        sections.append(S.budget_section(results["budget"], folder))
    if "analysis" in results:
        sections.append(S.analysis_section(results["analysis"], folder))
    if "synthesis" in results:
        sections.append(S.synthesis_section(results["synthesis"], folder))
    if "simulate" in results:
        wheels = results.get("compile", {}).get("wheels", [])
        sections.append(S.simulation_section(results["simulate"], folder, wheels,
                                             _simulation_figures(folder, results["simulate"], wheels)))
    if verdicts:
        sections.append(S.requirements_section(verdicts))
    if run:
        sections.append(S.provenance_section(run, hashlib.sha256(raw).hexdigest()))
    text, cls = _verdict(results, verdicts)
    return {"mission": name, "description": run.get("description", ""), "date": run.get("date", ""),
            "verdict": text, "verdict_class": cls, "stage_rows": stage_rows, "sections": sections,
            "n_figures": sum(len(s.figures) for s in sections)}


def render(context: dict[str, Any]) -> str:
    import jinja2

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
                             autoescape=True, trim_blocks=True, lstrip_blocks=True, undefined=jinja2.StrictUndefined)
    return env.get_template(TEMPLATE).render(**context)


def write_report(folder: Path, target: Path | None = None, mission: Path | None = None) -> Path:
    """Render the report of a results folder into ``target`` (default: ``<folder>/report.html``), atomically."""
    folder = Path(folder)
    target = Path(target) if target is not None else folder / "report.html"
    html = render(collect(folder, mission))
    return write_text_atomic(target, html)
