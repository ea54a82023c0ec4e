"""The ``sms`` command line. Thin: parse, call a stage, print, exit with the documented code.

Heavy modules (pinocchio, numpy, scipy, cvxpy, matplotlib) are imported inside commands so
that ``sms --help``, ``sms --version`` and shell completion answer at once.

Conventions: ``--out/-o DIR`` is a results folder on every stage command; a file is ``--output
FILE`` (``report``, ``schema``) or names its kind (``--recording``, ``--junit``, ``--baseline``);
every command that produces figures takes ``--json`` (its result on stdout, nothing else there);
each command's help ends with an example on a shipped mission.
"""

from __future__ import annotations

import json
import re
import sys
import warnings
from pathlib import Path
from typing import Annotated, Callable, Optional, Sequence

import typer

from sms_cli import __version__
from sms_cli.errors import (
    EXIT_INPUT,
    EXIT_INTERRUPTED,
    EXIT_REQUIREMENTS,
    SmsError,
)
from sms_cli.failures import failure, interrupted
from sms_cli.outputs import Output

EXIT_CODES_HELP = (
    "Exit codes: 0 ok · 1 requirements not met · 2 invalid input or usage · "
    "3 numerical failure (infeasible synthesis, diverged simulation, singular model) or the disk is full · "
    "4 internal error (a bug: please report it) · 130 interrupted."
)

app = typer.Typer(
    name="sms",
    help="Mission analysis for space manipulator systems: a URDF robot + a YAML mission → "
    "ΔV budget, workspace maps, gains, simulation (MCAP), report and CI checks.\n\n" + EXIT_CODES_HELP,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)

_state = {"debug": False}



class _Command(typer.core.TyperCommand):
    """A command whose usage line names its arguments as they are (``MISSION.yaml``), not in
    braces that read as a set of choices (typer writes ``{MISSION.yaml}``)."""

    def collect_usage_pieces(self, ctx) -> list[str]:
        pieces = [self.options_metavar] if self.options_metavar else []
        for param in self.get_params(ctx):
            if isinstance(param, typer.core.TyperArgument):
                name = param.metavar or param.name.upper()
                pieces.append(name if param.required else f"[{name}]")
            else:
                pieces.extend(param.get_usage_pieces(ctx))
        return pieces


def command(name: str):
    return app.command(name, cls=_Command)


MissionArg = Annotated[Path, typer.Argument(help="mission YAML file", metavar="MISSION.yaml", show_default=False)]
ResultsArg = Annotated[Path, typer.Argument(help="results folder (with results.json)", metavar="RESULTS_DIR",
                                            show_default=False)]
OutOpt = Annotated[
    Optional[Path],
    typer.Option("--out", "-o", metavar="DIR",
                 help="results folder (default: results/<mission file name>/ in the current directory)"),
]


def mission_opt(help: str):
    return typer.Option("--mission", "-m", metavar="MISSION.yaml", help=help)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"sms {__version__}")
        raise typer.Exit(0)


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="print the version")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="show tracebacks of errors")] = False,
) -> None:
    _state["debug"] = debug


def err(text: str) -> None:
    typer.echo(text, err=True)


#: RuntimeWarnings of floating-point arithmetic (NaN or inf reach the results as null): not shown
_NUMERIC_WARNING = re.compile(r"invalid value|divide by zero|overflow|underflow|empty slice|degrees of freedom", re.I)


def _plain_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` for users: one plain line, no source path; numeric ones silenced."""
    text = str(message).strip()
    if issubclass(category, RuntimeWarning) and _NUMERIC_WARNING.search(text):
        return
    if text:
        err("warning: " + text.splitlines()[0][:300])


def _guarded(fn: Callable[[], int | None], outputs: Sequence[Output]) -> int:
    try:
        for o in outputs:
            o.check()
        return fn() or 0
    except SmsError as exc:
        if _state["debug"]:
            raise
        err(f"error: {exc.render()}")
        return exc.exit_code
    except KeyboardInterrupt:
        err("interrupted")
        return EXIT_INTERRUPTED
    except typer.Exit:
        raise
    except Exception as exc:  # noqa: BLE001 - the contract is: never a raw traceback
        if interrupted(exc):  # an interrupt Python wrapped (failures.interrupted)
            err("interrupted")
            return EXIT_INTERRUPTED
        if _state["debug"]:
            raise
        code, message = failure(exc, outputs)
        err(f"error: {message}")
        return code


def run_guarded(fn: Callable[[], int | None], outputs: Sequence[Output] = ()) -> None:
    """Check the paths the command will write, run its body, map every failure to a message and
    an exit code (no traceback; warnings as one plain line unless --debug)."""
    with warnings.catch_warnings():
        if not _state["debug"]:
            warnings.showwarning = _plain_warning
        code = _guarded(fn, outputs)
    raise typer.Exit(code)


def _results_folder(path: Path) -> list[Output]:
    return [Output(path, "results folder", folder=True)]


def print_json(data) -> None:
    """A command's result on stdout as JSON (NaN and inf as null)."""
    from sms_cli.results import _jsonable

    typer.echo(json.dumps(_jsonable(data), indent=2))


def emit(data, as_json: bool, formatter: Callable[[dict], str]) -> None:
    """Print a stage's section: JSON (machine) or its human formatter."""
    if as_json:
        print_json(data)
    else:
        typer.echo(formatter(data))


def default_out(mission_path: Path, out: Path | None) -> Path:
    """Results folder of a mission: ``--out`` or ``results/<mission file stem>``."""
    from sms_cli.results import default_results_dir

    return out if out is not None else default_results_dir(mission_path)


@command("compile")
def compile_cmd(
    mission: MissionArg,
    as_json: Annotated[bool, typer.Option("--json", help="print the summary as JSON")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", "-o", metavar="DIR", help=(
        "write the summary into this results folder (results.json): -o implies --write"))] = None,
    write: Annotated[Optional[bool], typer.Option("--write/--no-write", help=(
        "write the summary into the results folder (default: when -o is given; without -o the folder "
        "is results/<mission file name>/)"), show_default=False)] = None,
    strict: Annotated[bool, typer.Option("--strict", help="refuse, as a lint, what is accepted with a warning: massless "
                                         "or point-mass links, inertias off the triangle inequality, non-physical inertias "
                                         "(also robot.strict in the mission)")] = False,
) -> None:
    """Validate a mission and its robot; print the model summary (DoF, mass, inertia, wheels, modes).

    Example:

    \b
        sms compile missions/pulsar_simple.yaml --strict
        sms compile missions/pulsar_simple.yaml --json -o results/pulsar_simple
    """
    if write is None:
        write = out is not None

    def body() -> int:
        from sms_cli.model.summary import compile_summary, format_summary

        summary = compile_summary(mission, strict=strict)
        if write:
            from sms_cli.results import ResultsDir

            ResultsDir(default_out(mission, out)).update("compile", summary)
        typer.echo(json.dumps(summary, indent=2) if as_json else format_summary(summary))
        return 0

    run_guarded(body, _results_folder(default_out(mission, out)) if write else ())


@command("budget")
def budget_cmd(
    mission: MissionArg,
    out: OutOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the budget as JSON")] = False,
) -> None:
    """ΔV, propellant and burn-time budget of the mission's manoeuvre sequence (writes results.json, CSV, plots).

    Example:

    \b
        sms budget missions/hipparcos_geo.yaml -o results/hipparcos_geo
    """

    def body() -> int:
        from sms_cli.mission.load import load_mission
        from sms_cli.orbit.stage import format_budget, run_budget

        data = run_budget(load_mission(mission), default_out(mission, out))
        emit(data, as_json, format_budget)
        return 0

    run_guarded(body, _results_folder(default_out(mission, out)))


@command("analyze")
def analyze_cmd(
    mission: MissionArg,
    out: OutOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the analysis section as JSON")] = False,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="write the PNG plots (default: as the mission says)")] = True,
    progress: Annotated[Optional[bool], typer.Option("--progress/--no-progress", help="progress bar on stderr (default: when a terminal)")] = None,
    csv: Annotated[bool, typer.Option("--csv", help=(
        "also write the per-sample tables as analysis_<variant>.csv (default: Parquet only, "
        "analysis_<variant>.parquet; the mission's analysis.table: [parquet, csv] asks for both on every run)"))] = False,
) -> None:
    """Workspace maps, kinematic indices (manipulability, K^m/K^r, null-motion, momentum), variants and modal analysis.

    Writes per variant analysis_<variant>.parquet (one row per sample: column sample, the joint
    coordinates q_<joint> and every index, SI, NaN where undefined; .csv with --csv), the plots,
    the modal exports and the analysis section of results.json.

    Example:

    \b
        sms analyze missions/demeter_3dof.yaml -o results/demeter_3dof --no-plots
    """

    def body() -> int:
        from sms_cli.report.figpool import FigurePool

        with FigurePool(None if plots else 0) as pool:  # started first: its imports overlap this process's
            from sms_cli.analysis.stage import format_analysis, run_analysis
            from sms_cli.mission.load import load_mission

            data = run_analysis(load_mission(mission), default_out(mission, out), plots=None if plots else False,
                                progress=progress, pool=pool, csv=csv)
        emit(data, as_json, format_analysis)
        return 0

    run_guarded(body, _results_folder(default_out(mission, out)))


@command("synthesize")
def synthesize_cmd(
    mission: MissionArg,
    out: OutOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the synthesis section as JSON")] = False,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="write the pole map PNG")] = True,
) -> None:
    """Controller/observer gains (Kraiem 2022 LMI, PD, LQR, SMC), verified after the solve; writes gains.yaml.

    Example:

    \b
        sms synthesize missions/caldera_s1_synthesized.yaml -o results/caldera_s1_synthesized
    """

    def body() -> int:
        from sms_cli.mission.load import load_mission
        from sms_cli.synthesis.stage import format_synthesis, run_synthesis

        section = run_synthesis(load_mission(mission), default_out(mission, out), plots=plots)
        emit(section, as_json, format_synthesis)
        return 0

    run_guarded(body, _results_folder(default_out(mission, out)))


@command("simulate")
def simulate_cmd(
    mission: MissionArg,
    out: Annotated[
        Optional[Path],
        typer.Option("--out", "-o", metavar="DIR", help="results folder (default: results/<mission file name>/ in the "
                                                        "current directory); a path ending in .mcap is read as "
                                                        "--recording, as before"),
    ] = None,
    recording: Annotated[Optional[Path], typer.Option("--recording", metavar="FILE.mcap", help=(
        "write the recording here instead of DIR/simulation.mcap"))] = None,
    progress: Annotated[Optional[bool], typer.Option("--progress/--no-progress", help="progress bar (default: on a terminal)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the metrics as JSON")] = False,
) -> None:
    """Nonlinear simulation of the mission's phases; records simulation.mcap (Foxglove) and metrics. A mission
    with client: and formation: sections simulates two spacecraft (locked/shape decomposition, relative laws,
    capture; Vicariotto 2023 ch. 5) and also writes relative_motion.csv for sms export hil.

    Example:

    \b
        sms simulate missions/caldera_s1_slew.yaml -o results/caldera_s1_slew
        sms simulate missions/vicariotto_s6_relative_hil.yaml -o results/s6
    """
    if out is not None and out.suffix == ".mcap":  # the old spelling of --recording
        if recording is not None:
            raise typer.BadParameter("give the recording once: -o DIR --recording FILE.mcap", param_hint="'-o'")
        out, recording = None, out
    folder = default_out(mission, out)
    mcap_path = recording

    def body() -> int:
        from sms_cli.mission.load import load_mission
        from sms_cli.sim.report import format_simulation
        from sms_cli.sim.stage import run_simulation

        section = run_simulation(load_mission(mission), folder, mcap_path, progress)
        emit(section, as_json, format_simulation)
        return 0

    run_guarded(body, _results_folder(folder) + ([Output(mcap_path, "recording", example="simulation.mcap")]
                                                 if mcap_path else []))


@command("run")
def run_cmd(
    mission: MissionArg,
    out: OutOpt = None,
    progress: Annotated[Optional[bool], typer.Option("--progress/--no-progress", help="stage progress bars (default: on a terminal)")] = None,
    report: Annotated[bool, typer.Option("--report/--no-report", help="write report.html into the results folder")] = True,
    as_json: Annotated[bool, typer.Option("--json", help=(
        "print the run summary as JSON: mission, results, stages (name, status, seconds, exit_code, message), "
        "verdicts (name, metric, stage, status, value, bound, unit, message, margin), report, exit_code, passed, "
        "verdict"))] = False,
) -> None:
    """Every stage the mission configures (budget, analyze, synthesize, simulate), requirements, then the report.

    A failing stage is reported and the others go on; the exit code is the worst met.

    Example:

    \b
        sms run missions/pulsar_simple.yaml -o results/pulsar_simple
    """

    def body() -> int:
        from sms_cli.run.orchestrate import format_run, run_mission

        summary = run_mission(mission, default_out(mission, out), progress=progress, report=report, debug=_state["debug"])
        if as_json:
            print_json(summary.as_dict())
        else:
            typer.echo(format_run(summary), nl=False)
        return summary.exit_code

    run_guarded(body, _results_folder(default_out(mission, out)))


class _CampaignGroup(typer.core.TyperGroup):
    """``sms campaign MISSION.yaml`` runs the campaign (the ``start`` command, written or not);
    ``sms campaign rerun RESULTS --run ID`` replays one of its runs."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ("--help", "-h"):
            args = ["start", *args]
        return super().parse_args(ctx, args)


campaign_app = typer.Typer(cls=_CampaignGroup, no_args_is_help=True, rich_markup_mode=None, help=(
    "Monte-Carlo dispersions and parameter sweeps of a mission (its campaign: section), on a local Dask "
    "cluster or a remote scheduler: manifest, Parquet metrics, statistics, pass rates, sensitivities.\n\n"
    "\b\n    sms campaign missions/campaign_caldera_slew.yaml -o results/campaign_caldera_slew\n"
    "    sms campaign rerun results/campaign_caldera_slew --run 17\n\n" + EXIT_CODES_HELP))
app.add_typer(campaign_app, name="campaign")


CampaignArg = Annotated[Path, typer.Argument(help="campaign file: a mission with a campaign: section",
                                             metavar="CAMPAIGN.yaml", show_default=False)]


@campaign_app.command("start", cls=_Command)
def campaign_cmd(
    mission: CampaignArg,
    out: OutOpt = None,
    workers: Annotated[Optional[int], typer.Option("--workers", "-w", min=1, help=(
        "worker processes of the local Dask cluster (default: one per core)"))] = None,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", metavar="tcp://HOST:PORT", help=(
        "run on this Dask scheduler's workers instead of a local cluster"))] = None,
    resume: Annotated[bool, typer.Option("--resume", help=(
        "continue the campaign in the results folder: run only what is missing or failed"))] = False,
    restart: Annotated[bool, typer.Option("--restart", help=(
        "start over in a folder that holds results: they move to previous/<time>/ (nothing is deleted)"))] = False,
    entropy: Annotated[Optional[int], typer.Option("--entropy", min=0, help=(
        "seed entropy when the campaign file gives none (default: drawn and recorded in campaign.json)"))] = None,
    progress: Annotated[Optional[bool], typer.Option("--progress/--no-progress", help="progress bar (default: on a terminal)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the campaign section of results.json as JSON")] = False,
) -> None:
    """Run the mission's campaign: every run's dispersed mission through its stages, then statistics.

    Exit 1 when a campaign requirement fails (judged on its confidence bound), 130 on Ctrl-C (what
    finished is kept: --resume goes on).

    Example:

    \b
        sms campaign missions/campaign_caldera_slew.yaml -o results/campaign_caldera_slew --workers 2
    """
    folder = default_out(mission, out)

    def body() -> int:
        from sms_cli.campaign.stage import define, format_campaign, run
        from sms_cli.mission.load import load_mission

        campaign = define(load_mission(mission), entropy)
        section = run(campaign, folder, scheduler=scheduler, workers=workers, resume=resume, restart=restart,
                      progress=progress)
        emit(section, as_json, lambda s: format_campaign(s, folder))
        return EXIT_REQUIREMENTS if any(v["status"] != "pass" for v in section["requirements"]) else 0

    run_guarded(body, _results_folder(folder))


@campaign_app.command("rerun", cls=_Command)
def campaign_rerun_cmd(
    results: ResultsArg,
    run_id: Annotated[int, typer.Option("--run", "-r", min=0, help="the run to replay (its id in the manifest)")],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", metavar="DIR", help=(
        "where to write the run's results and recording (default: RESULTS_DIR/runs/<id>/)"))] = None,
) -> None:
    """Replay one run of a campaign exactly, with its recording (simulation.mcap), and compare its
    metrics with the campaign's (exit 1 when they differ).

    Example:

    \b
        sms campaign rerun results/campaign_caldera_slew --run 17
    """

    def body() -> int:
        from sms_cli.campaign.rerun import format_rerun, rerun

        outcome = rerun(results, run_id, out)
        typer.echo(format_rerun(outcome))
        return 0 if outcome["identical"] else EXIT_REQUIREMENTS

    run_guarded(body, _results_folder(out) if out is not None else [])


export_app = typer.Typer(no_args_is_help=True, rich_markup_mode=None, help=(
    "Export a run for use outside sms: `hil` maps a two-spacecraft run onto a robotic hardware-in-the-loop "
    "facility (robot poses, reachability, workspace).\n\n"
    "\b\n    sms export hil results/formation --facility missions/facilities/oos_sim.yaml\n\n" + EXIT_CODES_HELP))
app.add_typer(export_app, name="export")


@export_app.command("hil", cls=_Command)
def export_hil_cmd(
    results: ResultsArg,
    facility: Annotated[Path, typer.Option("--facility", "-f", metavar="FACILITY.yaml", show_default=False, help=(
        "facility file: mock-up mounts, robots (URDF), which robot moves, the envelope"))],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", metavar="DIR", help=(
        "write into DIR/hil/ (default: RESULTS_DIR/hil/)"))] = None,
    as_json: Annotated[bool, typer.Option("--json", help=(
        "print the summary as JSON: facility, facility_file, results, formation, moving, held, samples, duration_s, "
        "start_offset, reachability, workspace, files"))] = False,
    require_reachable: Annotated[bool, typer.Option("--require-reachable", help=(
        "exit 1 when a robot cannot reach a commanded pose (default: reported, exit 0)"))] = False,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="write workspace.png")] = True,
) -> None:
    """Hardware-in-the-loop export of a two-spacecraft run (Vicariotto 2023 §6.2): the relative motion as
    commands to the facility robots.

    Reads RESULTS_DIR/results.json (simulate.formation: master, other, relative_motion) and the
    relative-motion table it names (t, p1_*, q1_*, p2_*, q2_*, v1_*, w1_*, v2_*, w2_*: base poses
    world<-base with quaternions x y z w, body twists [v; w] in each base frame). The moving robot
    replays g12 = g1^-1 g2: g1_HW = g2_HW g12^-1 with the other mock-up held at its mount (or the
    mirror, g2_HW = g1_HW g12, with moving: other). Writes DIR/hil/commands.csv and commands.mcap
    (Foxglove /tf of the facility world, mock-ups, robot bases and tools), workspace.json and
    workspace.png (absolute vs relative replay: ranges, rotation, when each leaves the envelope) and,
    when the facility gives robot URDFs, checks each pose by inverse kinematics (1 mm, 0.1 deg, joint
    limits). An unreachable pose is a finding (exit 0) unless --require-reachable (exit 1); a missing or
    malformed results folder or facility file is exit 2.

    Example:

    \b
        sms export hil results/formation --facility missions/facilities/oos_sim.yaml --json
    """
    folder = (out if out is not None else results) / "hil"

    def body() -> int:
        from sms_cli.errors import InputError, Location, Problem
        from sms_cli.hil.stage import all_reachable, format_export, run_export

        summary = run_export(results, facility, out, plots=plots)
        emit(summary, as_json, format_export)
        ok = all_reachable(summary)
        if require_reachable and ok is None:
            raise InputError(problems=[Problem("--require-reachable: the facility file gives no robot URDF to check",
                                               Location(facility), hint="add robot: {urdf, base, tool_frame} to a mock-up")])
        return EXIT_REQUIREMENTS if require_reachable and not ok else 0

    run_guarded(body, [Output(folder, "HIL export folder", folder=True)])


@command("report")
def report_cmd(
    results: ResultsArg,
    output: Annotated[Optional[Path], typer.Option("--output", "-o", metavar="FILE",
                                                   help="HTML file (default: RESULTS_DIR/report.html)")] = None,
    mission: Annotated[Optional[Path], mission_opt("mission file: re-evaluate its requirements")] = None,
    pdf: Annotated[bool, typer.Option("--pdf", help="also print a PDF next to the HTML (needs chromium)")] = False,
) -> None:
    """One self-contained HTML report (plots embedded) of a results folder; optional PDF.

    Sections of results.json that cannot be read are left out and named (exit 2).

    Example:

    \b
        sms report results/pulsar_simple --output reports/pulsar_simple.html --pdf
    """
    target = output if output is not None else results / "report.html"
    outputs = [Output(target, "report", example="report.html")] if output is not None or results.is_dir() else []
    if pdf and outputs:
        outputs.append(Output(target.with_suffix(".pdf"), "PDF", example="report.pdf"))

    def body() -> int:
        from sms_cli.report.build import write_report

        unreadable: list[str] = []
        path = write_report(results, output, mission, unreadable)
        typer.echo(f"report: {path} ({path.stat().st_size / 1e6:.2f} MB)")
        if pdf:
            from sms_cli.report.pdf import print_pdf

            typer.echo(f"pdf: {print_pdf(path)}")
        if unreadable:
            from sms_cli.errors import InputError, Location, Problem

            raise InputError(problems=[Problem(
                "the report leaves out what could not be read: " + "; ".join(unreadable),
                Location(results / "results.json" if results.is_dir() else results),
                hint=f"re-run the mission into this folder: sms run MISSION.yaml -o {results}")])
        return 0

    run_guarded(body, outputs)


@command("check")
def check_cmd(
    results: ResultsArg,
    mission: Annotated[Optional[Path], mission_opt("read the requirements from this mission file "
                                                   "(default: the copy stored by sms run)")] = None,
    baseline: Annotated[Optional[Path], typer.Option("--baseline", "-b", metavar="FILE",
                                                     help="compare with this baseline (JSON)")] = None,
    junit: Annotated[Optional[Path], typer.Option("--junit", metavar="FILE", help=(
        "write a JUnit XML report here (also when the check cannot run: one failing test case with the error)"))] = None,
    write_baseline: Annotated[Optional[Path], typer.Option("--write-baseline", metavar="FILE",
                                                           help="write a baseline of these results here")] = None,
    as_json: Annotated[bool, typer.Option("--json", help=(
        "print the outcome as JSON: mission, results, passed, exit_code, verdicts (name, metric, stage, status, value, bound, "
        "unit, message, margin), drifts (metric, status, value, expected, allowed, message), notes, incomplete"))] = False,
) -> None:
    """Requirements and regression baseline → table, JUnit XML, exit 1 when one fails.

    Example:

    \b
        sms check results/hipparcos_geo --baseline baselines/hipparcos_geo.json --junit hipparcos_geo.xml
    """

    def body() -> int:
        from sms_cli.check.check import run_check

        outcome = run_check(results, mission, baseline, junit, write_baseline)
        if as_json:
            print_json(outcome.as_dict())
        else:
            typer.echo(outcome.format(), nl=False)
        return outcome.exit_code

    run_guarded(body, ([Output(junit, "JUnit report", example="junit.xml")] if junit else [])
                + ([Output(write_baseline, "baseline", example="baseline.json")] if write_baseline else []))


@app.command("schema")
def schema_cmd(
    output: Annotated[Optional[Path], typer.Option("--output", "-o", metavar="FILE",
                                                   help="write to this file instead of stdout")] = None,
) -> None:
    """Print the JSON Schema of mission files, for editors (VS Code's YAML extension, yaml-language-server).

    One schema for every mission file, the one an editor should use: a file with `extends:` is
    checked as partial (its mappings may leave out what they inherit), any other file as complete
    (every required key). Quantities are checked for their bounds and, written with a unit, for a
    unit of their kind; vectors for their length; sms compile checks the rest.
    missions/mission.schema.json is this output; each shipped mission names it on its first line:

    \b
        # yaml-language-server: $schema=./mission.schema.json

    Example:

    \b
        sms schema --output missions/mission.schema.json
    """

    def body() -> int:
        from sms_cli.mission.load import mission_json_schema

        text = json.dumps(mission_json_schema(), indent=2)
        if output:
            from sms_cli.results import write_text_atomic

            write_text_atomic(output, text + "\n")
        else:
            typer.echo(text)
        return 0

    run_guarded(body, [Output(output, "schema", example="mission.schema.json")] if output else [])


@command("inspect")
def inspect_cmd(
    recording: Annotated[Path, typer.Argument(help="MCAP recording written by `sms simulate`", metavar="RECORDING.mcap",
                                              show_default=False)],
    as_json: Annotated[bool, typer.Option("--json", help="print the summary as JSON")] = False,
    repair: Annotated[bool, typer.Option("--repair", help="rewrite what can be read of a killed, truncated or damaged "
                                                          "recording into a complete file (in place, atomically)")] = False,
) -> None:
    """Summarise a simulation recording (MCAP): topics, schemas, message counts, time span, rates, metadata, run status.

    A damaged or unfinished recording is exit 2, saying what can still be read; --repair rewrites that part
    into a complete file.

    Example:

    \b
        sms inspect results/caldera_s1_slew/simulation.mcap --json
    """

    def body() -> int:
        from sms_cli.recording.inspect import format_inspection, format_repair, inspect_recording, repair_recording

        if repair:
            err(format_repair(repair_recording(recording)))
        info = inspect_recording(recording)
        typer.echo(json.dumps(info, indent=2) if as_json else format_inspection(info))
        return 0

    run_guarded(body)


@command("warmup")
def warmup_cmd(
    missions: Annotated[list[Path], typer.Argument(help="mission YAML files", metavar="MISSION.yaml...",
                                                   show_default=False)],
    lanes: Annotated[Optional[int], typer.Option("--lanes", min=1, help=(
        "processes compiling at once (default: the usable cores; SMS_COMPILE_LANES sets it too)"))] = None,
) -> None:
    """Compile the kernels the missions' analysis and simulation use, so that their first run does not pause.

    numba compiles a kernel the first time it runs after an install and caches it (next to the package, or in
    numba's per-user cache); a first `sms run` of the flagship otherwise pauses for about a minute on 2 cores.
    This compiles every kernel the missions' analysis and simulation stages call, in parallel, and writes
    nothing but that cache. The README's setup scripts run it once after installing. A mission whose gains
    only `sms synthesize` can write (attitude: from_gains) keeps its simulation kernels for its first run.

    Example:

    \b
        sms warmup missions/pulsar_simple.yaml missions/caldera_s1_slew.yaml
    """

    def body() -> int:
        from sms_cli.run.warmup import warm_missions

        r = warm_missions(missions, lanes)
        for note in r["notes"]:
            err(f"  {note}")
        typer.echo(f"{r['missions']} mission(s): {r['calls']} kernel call(s), {r['compiled']} compiled on "
                   f"{r['lanes']} lane(s) in {r['seconds']:.1f} s (the others were cached)")
        return 0

    run_guarded(body)


def main() -> None:
    """Console-script entry point. SIGTERM is handled as Ctrl-C: files are finished, exit 130."""
    import signal

    signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        app()
    except KeyboardInterrupt:  # pragma: no cover - outside a command body
        err("interrupted")
        sys.exit(EXIT_INTERRUPTED)
    finally:
        # The command is over (its files closed, fsync'ed and renamed into place): exit without the
        # interpreter's final garbage-collection passes over every object left (0.4 s after `sms
        # analyze` has drawn its figures); objects are still freed, atexit handlers still run.
        import gc

        gc.freeze()


if __name__ == "__main__":  # pragma: no cover
    main()

__all__ = ["app", "main", "run_guarded", "default_out", "EXIT_INPUT"]
