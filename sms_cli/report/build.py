"""``sms report``: one self-contained HTML file from a results folder (plots embedded as PNG).

Only sections whose data exist appear; a section that cannot be read (damaged results.json) is
left out and named at the top of the report. The bytes depend only on the results folder (and the
mission file, for the robot drawing when ``robot.png`` is absent): no wall-clock time, no
external resources, no scripts.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Any, Callable, TypeVar

from sms_cli.check.metrics import damaged_sections, section
from sms_cli.errors import InputError, Location, Problem, SmsError
from sms_cli.report.model import Figure, Section
from sms_cli.results import RESULTS_FILE, write_text_atomic

T = TypeVar("T")

TEMPLATE = "report.html.j2"


def _robot_png(folder: Path, results: dict[str, Any], mission: Path | None) -> bytes | None:
    f = folder / "robot.png"
    if f.is_file():
        return f.read_bytes()
    path = mission or Path(str(section(results, "compile").get("mission_file") or section(results, "run").get("mission_file") or ""))
    if not str(path) or not Path(path).is_file():
        return None
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.report.robot import draw_robot

    loaded = load_mission(path)
    if loaded.mission.robot is None:
        return None
    return draw_robot(compile_system(loaded))


def _robot_drawing(folder: Path, results: dict[str, Any], mission: Path | None) -> tuple[bytes | None, str]:
    """The drawing and, when the mission file results.json names no longer loads, a note instead
    (an error only for a mission given with --mission)."""
    try:
        return _robot_png(folder, results, mission), ""
    except SmsError as exc:
        if mission is not None:
            raise
        return None, "the robot drawing is left out: " + exc.render().splitlines()[0]


def _simulation_figures(folder: Path, sim: dict[str, Any], wheels: list[dict]) -> tuple[list[Figure], list[str]]:
    """The report-only plots of the recording and the CSV, and notes on what could not be read."""
    import csv

    from sms_cli.report import figures as F

    out: list[Figure] = []
    notes: list[str] = []
    files = sim.get("files") if isinstance(sim.get("files"), dict) else {}
    csv_path = folder / str(files.get("csv") or "simulation.csv")
    try:
        png = F.wheel_momentum_png(csv_path, wheels)
    except (csv.Error, ValueError, KeyError, TypeError, IndexError):
        png = None
        notes.append(f"the wheel-momentum plot is left out: {csv_path} (or the wheels of the compile section) "
                     "could not be read")
    if png:
        out.append(Figure.of_png("Reaction-wheel momentum per wheel and of the array (N m s) against the time: how much of "
                                 "each wheel's capacity (in the legend) the manoeuvre uses.", png, "wheel momentum"))
    mcap = Path(str(files.get("mcap") or "simulation.mcap"))
    if not mcap.is_file():
        mcap = folder / mcap.name
    if mcap.is_file():
        try:
            topics = F.read_topics(mcap, ["/joints/position", "/joints/reference", "/ee/position", "/base/position"])
            for fn, cap in ((F.joint_tracking_png, "Joint positions (solid) against their references (dashed): whether "
                                                   "each joint follows its trajectory (rad for revolute, m for prismatic)."),
                            (F.ee_path_png, "End-effector and base-origin paths in the world frame (equal axes, m): where "
                                            "the end effector goes and how far the base drifts meanwhile.")):
                png = fn(topics)
                if png:
                    out.append(Figure.of_png(cap, png))
        except Exception:  # noqa: BLE001 - a damaged recording must not stop the report
            notes.append(f"the recording {mcap} could not be read (damaged or truncated), so its plots are left out; "
                         f"sms inspect {mcap} shows what it holds")
    return out, notes


def _dicts(x: Any) -> list[dict]:
    """The mappings of a list (anything else: none)."""
    return [v for v in x if isinstance(v, dict)] if isinstance(x, list) else []


def _verdict(run: dict[str, Any], verdicts: list[dict]) -> tuple[str, str]:
    failed = [str(s.get("name")) for s in _dicts(run.get("stages")) if s.get("status") in ("failed", "skipped", "interrupted")]
    bad = [v for v in verdicts if v["status"] != "pass"]
    if run.get("state") in ("killed", "interrupted"):
        return f"the run was {run['state']}: results incomplete" + (f" (stages not ended: {', '.join(failed)})" if failed else ""), "fail"
    if failed:
        return f"stages failed: {', '.join(failed)}" + (f"; {len(bad)} requirement(s) not met" if bad else ""), "fail"
    if bad:
        return f"{len(bad)} of {len(verdicts)} requirements not met", "fail"
    if verdicts:
        return f"all {len(verdicts)} requirements met", "pass"
    return "no requirements defined", "neutral"


def _why(exc: Exception) -> str:
    if isinstance(exc, KeyError):
        return f"it has no '{exc.args[0]}'" if exc.args else "a key is missing"
    return "a list is shorter than expected" if isinstance(exc, IndexError) else "a value has the wrong type"


def collect(folder: Path, mission: Path | None = None, unreadable: list[str] | None = None) -> dict[str, Any]:
    """The template context of a results folder; what cannot be read is appended to ``unreadable``."""
    from sms_cli.check.check import load_results
    from sms_cli.report import sections as S

    if folder.is_file():
        raise InputError(problems=[Problem("is a file; sms report takes the results folder (the one holding results.json)",
                                           Location(folder), hint=f"sms report {folder.parent}")])
    from sms_cli.check.campaign import is_campaign

    campaign = is_campaign(folder)  # a campaign stopped before its summary has no results.json yet
    results, raw = ({}, b"") if campaign and not (folder / RESULTS_FILE).exists() else load_results(folder)[:2]
    problems = list(damaged_sections(results).values())

    def attempt(name: str, build: Callable[[], T]) -> T | None:
        try:
            return build()
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            problems.append(f"section '{name}' is incomplete ({_why(exc)})")
            return None

    run = section(results, "run")
    verdicts = [v for v in _dicts(section(results, "requirements").get("verdicts")) if isinstance(v.get("status"), str)]
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
    name = str(run.get("mission") or section(results, "compile").get("name") or folder.name)
    stage_rows = attempt("run", lambda: [[str(s["name"]), str(s["status"]), f"{s['seconds']:.2f}" if s.get("seconds") else "—",
                                          str(s.get("message") or "").split("\n")[0][:160]] for s in _dicts(run.get("stages"))]) or []
    sections: list[Section | None] = []
    if isinstance(results.get("compile"), dict):
        png, note = _robot_drawing(folder, results, mission)
        sec = attempt("compile", lambda: S.model_section(results["compile"], folder, png))
        if sec is not None and note:
            sec.notes.append(note)
        sections.append(sec)
    for key, build in (("budget", S.budget_section), ("analysis", S.analysis_section), ("synthesis", S.synthesis_section)):
        if isinstance(results.get(key), dict):
            sections.append(attempt(key, lambda: build(results[key], folder)))
    if isinstance(results.get("simulate"), dict) and isinstance(results["simulate"].get("formation"), dict):
        sections.append(attempt("simulate", lambda: S.formation_section(results["simulate"], folder)))
    elif isinstance(results.get("simulate"), dict):
        sim = results["simulate"]
        wheels = _dicts(section(results, "compile").get("wheels"))
        figures, notes = attempt("simulate", lambda: _simulation_figures(folder, sim, wheels)) or ([], [])
        sec = attempt("simulate", lambda: S.simulation_section(sim, folder, wheels, figures))
        if sec is not None:
            sec.notes.extend(notes)
        sections.append(sec)
    if campaign or isinstance(results.get("campaign"), dict):
        from sms_cli.report.campaign import campaign_report_section, statistics

        stats = attempt("campaign", lambda: statistics(folder, results))
        if stats is not None:
            verdicts += [v for v in _dicts(stats.get("requirements")) if isinstance(v.get("status"), str)]
            sections.append(attempt("campaign", lambda: campaign_report_section(folder, stats)))
    front: list[Section | None] = []
    if verdicts:
        front.append(attempt("requirements", lambda: S.requirements_section(verdicts)))
    if run:
        sections.append(attempt("run", lambda: S.provenance_section(run, hashlib.sha256(raw).hexdigest())))
    text, cls = attempt("run", lambda: _verdict(run, verdicts)) or ("", "neutral")
    shown = [s for s in sections if s is not None]
    first = [s for s in front if s is not None]
    if problems:
        first.insert(0, Section("unreadable", "Results that could not be read",
                                intro="results.json is damaged: these parts of it are left out of this report.",
                                notes=problems))
        text = "; ".join(t for t in (text, f"{len(problems)} part(s) of results.json unreadable") if t)
        cls = "fail"
    if unreadable is not None:
        unreadable.extend(problems)
    for k, f in enumerate(f for s in shown for f in s.figures):
        f.id = f"fig-{k + 1}"
    return {"mission": name, "description": str(run.get("description", "")), "date": str(run.get("date", "")),
            "verdict": text, "verdict_class": cls, "stage_rows": stage_rows, "front": first, "sections": shown,
            "n_figures": sum(len(s.figures) for s in shown), "layout": _layout(), "references": _references(run)}


def _references(run: dict[str, Any]) -> list[tuple[str, str]]:
    """The theses the mission cites (its description and, when still there, its file), with titles."""
    from sms_cli.references import cited

    text = str(run.get("description", ""))
    files = run.get("files") if isinstance(run.get("files"), dict) else {}
    path = (files.get("mission") or {}).get("path") if isinstance(files.get("mission"), dict) else None
    try:
        text += "\n" + Path(path).read_text(encoding="utf-8", errors="replace") if path else ""
    except OSError:
        pass
    return cited(text)


def _layout() -> dict[str, int]:
    """The widths the figures are drawn at, for the template's CSS (one source: figstyle)."""
    from sms_cli.report import figstyle

    return {"content_px": figstyle.CONTENT_PX, "gap_px": figstyle.GAP_PX, "half_px": figstyle.HALF_PX}


# A number as it appears in a table or a caption: sign, digits grouped by narrow no-break spaces,
# decimals, exponent; not part of a word (RW1, sha256 hex).
NUMBER = re.compile(r"(?<![\w.])[-+−]?(?:\d[\d\u202f]*(?:\.\d+)?|\.\d+)(?:[eE][-+]?\d+)?(?![\w])")
UNIT_SPACE = re.compile(r"\b(N|kg) m(?![a-z])( s\b)?")  # N m, N m s, kg m², √kg m: one unit, one line
LONG_NAME = re.compile(r"[\w./-]{25,}")  # metric paths, file paths: may break after . _ /; hashes anywhere
HEX = re.compile(r"[0-9a-f]{25,}")


def numwrap(text: Any):
    """Escaped text with every number in a ``<span class="n">`` the template keeps on one line, and
    long dotted names breakable after their dots and underscores only."""
    from markupsafe import Markup, escape

    def words(part: str) -> str:
        out, last = [], 0
        for m in LONG_NAME.finditer(part):
            name = str(escape(m.group(0)))
            out += [str(escape(part[last:m.start()])), f'<span class="hash">{name}</span>' if HEX.fullmatch(name)
                    else re.sub(r"([._/])", r"\1<wbr>", name)]
            last = m.end()
        return UNIT_SPACE.sub(lambda m: m.group(1) + "\u00a0m" + ("\u00a0s" if m.group(2) else ""),
                              "".join(out) + str(escape(part[last:])))

    raw = str(text)
    out, last = [], 0
    for m in NUMBER.finditer(raw):
        out += [words(raw[last:m.start()]), f'<span class="n">{escape(m.group(0))}</span>']
        last = m.end()
    return Markup("".join(out) + words(raw[last:]))


def header(text: Any):
    """A column header whose unit (``[kg m²]``) stays on one line."""
    from markupsafe import Markup, escape

    return Markup(re.sub(r"(\[[^\]]*\])", r'<span class="n">\1</span>', str(escape(text))))


def css_string(text: Any):
    """Text for a CSS string literal inside <style> (no HTML escaping there)."""
    from markupsafe import Markup

    out = "".join(c if c.isalnum() or c in " .,:;_-()[]+/" else f"\\{ord(c):x} " for c in str(text))
    return Markup(out)


def render(context: dict[str, Any]) -> str:
    import jinja2

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
                             autoescape=True, trim_blocks=True, lstrip_blocks=True, undefined=jinja2.StrictUndefined)
    env.filters.update(numwrap=numwrap, header=header, css_string=css_string)
    return env.get_template(TEMPLATE).render(**context)


def write_report(folder: Path, target: Path | None = None, mission: Path | None = None,
                 unreadable: list[str] | None = None) -> Path:
    """Render the report of a results folder into ``target`` (default: ``<folder>/report.html``), atomically;
    what could not be read is appended to ``unreadable``."""
    folder = Path(folder)
    target = Path(target) if target is not None else folder / "report.html"
    html = render(collect(folder, mission, unreadable))
    return write_text_atomic(target, html)
