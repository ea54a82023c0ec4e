"""``sms simulate``: compile, simulate, record MCAP, write metrics and plots (``record_simulation``),
or simulate in memory without recording or writing (``simulate_mission``)."""

from __future__ import annotations

import csv
import errno
import io
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sms_cli.errors import InputError, Location, NumericalError, Problem
from sms_cli.mission.load import LoadedMission
from sms_cli.results import ResultsDir, write_text_atomic

if TYPE_CHECKING:
    from sms_cli.model.system import SystemModel
    from sms_cli.sim.engine import SimResult


def versions() -> dict[str, str]:
    import mcap
    import pinocchio
    from google import protobuf

    from sms_cli import __version__

    return {"sms": __version__, "pinocchio": pinocchio.__version__, "numpy": np.__version__,
            "mcap": getattr(mcap, "__version__", "?"), "protobuf": protobuf.__version__}


def _trace_csv(trace: dict, sm) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    wn = [f"wheel_speed_{x.name}" for x in sm.wheels] + [f"wheel_torque_{x.name}" for x in sm.wheels]
    jn = [f"joint_error_{a.name}" for a in sm.arm] + [f"joint_torque_{a.name}" for a in sm.arm]
    w.writerow(["t_s", "phase", "attitude_error_rad", "ee_error_m", "modal_peak", "saturated"] + wn + jn)
    for i in range(trace["t"].size):
        row = [trace["t"][i], int(trace["phase"][i]), trace["att_err"][i], trace["ee_err"][i], trace["modal_peak"][i],
               int(trace["saturated"][i])]
        row += list(trace["wheel_speed"][i]) + list(trace["wheel_torque"][i]) if sm.wheels else []
        row += list(trace["joint_err"][i]) + list(trace["joint_torque"][i]) if sm.arm else []
        w.writerow([f"{x:.9g}" if isinstance(x, float) else x for x in row])
    return buf.getvalue()


class SimulationDiverged(NumericalError):
    """The simulation diverged (exit 3); ``section`` and ``run`` (the ``SimResult``) hold what ran."""

    def __init__(self, message: str, section: dict, run: SimResult):
        super().__init__(message)
        self.section = section
        self.run = run


def prepared_simulation(loaded: LoadedMission, sm=None):
    """(compiled model, simulation spec with every ``duration: auto`` resolved, move plans) of a mission
    with a valid ``simulation:`` section (InputError otherwise); ``sm``: the mission's model when already
    compiled."""
    from sms_cli.model import compile_system
    from sms_cli.sim.validate import validate_simulation

    if loaded.mission.simulation is None and loaded.mission.formation is not None:
        raise InputError(problems=[Problem(
            "this is a two-spacecraft mission (formation:): it runs through `sms simulate` and `sms run`; the Python "
            "API's simulate() covers one-spacecraft missions", loaded.source.locate(("formation",)),
            hint="use sms simulate MISSION.yaml -o DIR (or sms_cli.formation.stage.record_formation)")])
    if loaded.mission.simulation is None:
        raise InputError(problems=[Problem("this mission has no 'simulation:' section", loaded.source.locate(()),
                                           hint="add simulation: {dt, control_rate, attitude, arm, phases: [...]}")])
    sm = compile_system(loaded) if sm is None else sm
    validate_simulation(sm, loaded)  # a bad name is exit 2 before a recording exists
    spec, plans = planned_simulation(sm, loaded)
    return sm, spec, plans


def planned_simulation(sm, loaded: LoadedMission):
    """(spec with the assembly tasks expanded (``sms_cli.sim.assembly``) and ``duration: auto`` phases sized,
    move plans) — ``sms_cli.sim.authority``."""
    from sms_cli.sim.assembly import assembly_phases
    from sms_cli.sim.authority import plan_moves, resolve_durations

    spec = assembly_phases(sm, loaded.mission.simulation, loaded)
    try:
        plans = plan_moves(sm, spec)
    except ValueError as exc:
        raise InputError(problems=[Problem(str(exc), loaded.source.locate(("simulation", "phases")),
                                           "simulation.phases", "give that phase a duration in s")]) from None
    return resolve_durations(spec, plans), plans


def _base(loaded: LoadedMission) -> dict:
    return {"mission": loaded.mission.name, "mission_file": str(loaded.path)}


def _section(result: SimResult, base: dict, files: dict, plans=()) -> dict:
    """The ``simulate`` section of a run (whole, or what ran of it); ``moves``: the joint-move plans
    (``sms_cli.sim.authority``) with the durations used."""
    return {
        "status": result.status, "divergence": result.divergence or None, "t_end_s": result.t_end, "steps": result.steps,
        "overall": result.overall, "phases": result.phases, "conservation": result.conservation, "timing": result.timing,
        "moves": [p.as_dict() for p in plans], **base, "files": files,
    }


def _diverged_message(result: SimResult, kept: str) -> str:
    return (f"the simulation diverged at t = {result.t_end:.4g} s: {result.divergence}. {kept}"
            "reduce dt, lower the gains or check the model")


def run_simulation(loaded: LoadedMission, out_dir: Path, mcap_path: Path | None = None,
                   progress: bool | None = None) -> dict:
    """Simulate the mission; returns the ``simulate`` section written to results.json (see
    ``record_simulation``; a two-spacecraft mission: ``sms_cli.formation.stage.record_formation``)."""
    if loaded.mission.formation is not None:
        from sms_cli.formation.stage import record_formation

        return record_formation(loaded, out_dir, mcap_path, progress)
    return record_simulation(loaded, out_dir, mcap_path, progress)[0]


def record_simulation(loaded: LoadedMission, out_dir: Path, mcap_path: Path | None = None,
                      progress: bool | None = None, gains_dir: Path | None = None) -> tuple[dict, SimResult]:
    """Simulate the mission, recording ``simulation.mcap`` (or ``mcap_path``) and writing the CSV, the
    plots and the ``simulate`` section; returns the section and the run (metrics and trace arrays).

    What each ending leaves: diverged → everything written, then SimulationDiverged (a NumericalError,
    exit 3). SIGINT/SIGTERM (KeyboardInterrupt, exit 130) → the recording finalised, and the section
    (status ``interrupted``, the time reached), CSV and plots of what ran. A full disk → the
    recording cut back to its last whole chunk (readable), the section says so, DiskFull (exit 3).
    Results of another mission in ``out_dir`` are not mixed in (``ResultsDir.writing``). gains.yaml
    (``attitude: from_gains``, the NDI) is read from ``gains_dir``, by default ``out_dir``."""
    sm, spec, plans = prepared_simulation(loaded)
    results = ResultsDir(out_dir)
    with results.writing(loaded.mission.name, loaded.path):
        return _simulate(loaded, sm, spec, plans, results, Path(mcap_path) if mcap_path else results.file("simulation.mcap"), progress,
                         Path(gains_dir) if gains_dir is not None else results.path)


def simulate_mission(loaded: LoadedMission, progress: bool | None = False,
                     gains_dir: Path | None = None) -> tuple[dict, SimResult]:
    """Simulate the mission without recording and without writing anything; returns the
    ``simulate`` section (``files`` empty) and the run (metrics and trace arrays). ``gains_dir`` is
    where gains.yaml is read for ``attitude: from_gains`` and the NDI. A divergence raises
    SimulationDiverged (exit 3) with what ran; Ctrl-C raises KeyboardInterrupt at once."""
    from sms_cli.sim.engine import Simulation

    sm, spec, plans = prepared_simulation(loaded)
    result = Simulation(sm, spec, None, progress, results_dir=gains_dir, mission_dir=loaded.path.parent).run()
    section = _section(result, _base(loaded), {}, plans)
    if result.status == "diverged":
        raise SimulationDiverged(_diverged_message(result, ""), section, result)
    return section, result


def _simulate(loaded: LoadedMission, sm, spec, plans, results: ResultsDir, mcap_path: Path,
              progress: bool | None, gains_dir: Path) -> tuple[dict, SimResult]:
    from sms_cli.model.summary import model_summary
    from sms_cli.sim.engine import Simulation
    from sms_cli.recording.recorder import McapRecorder
    from sms_cli.sim.timing import TIMING_METADATA, timing_metadata

    summary = model_summary(sm)
    timing = timing_metadata(spec, real_thrusters=sm.thrusters is not None)
    rec = McapRecorder(mcap_path, mission_text=loaded.text, mission_name=loaded.mission.name, model_summary=summary,
                       urdf_text=sm.urdf_text, versions=versions(), record_rate_hz=spec.record_rate,
                       metadata={TIMING_METADATA: timing})
    if timing["not_replayable_because"]:  # said before the run, and by `sms inspect` after it
        print(f"warning: the recording cannot be replayed by another engine: {timing['not_replayable_because']}",
              file=sys.stderr, flush=True)
    links = list(sm.link_parents)
    rec.add_transform_tree(links, [sm.link_parents[n] for n in links])
    base = _base(loaded)
    result = None
    # built before the recording opens: its input errors (a missing gains.yaml, an engine that cannot
    # run the mission) leave no recording behind
    simulation = Simulation(sm, spec, rec, progress, results_dir=gains_dir, mission_dir=loaded.path.parent)
    simulation.check_engine()
    try:
        with rec:  # once recording, a signal is held until the outputs are written
            result = simulation.run()
            rec.finish(result.status, {"reason": result.divergence} if result.divergence else None)
            section = _write_outputs(results, result, sm, spec, mcap_path, base, plans)
    except KeyboardInterrupt:
        if result is None:  # before the first sample (or a second signal): no trace to write
            results.update("simulate", {**base, "status": "interrupted", "t_end_s": rec.sim_time, "steps": rec.steps,
                                        "files": {"mcap": str(mcap_path)}})
        raise
    except OSError as exc:
        if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
            raise
        raise _disk_full(results, rec, mcap_path, base) from None
    if result.status == "interrupted":
        print(f"interrupted at t = {result.t_end:.6g} s: the metrics, CSV and plots of what ran are in {results.path}/, "
              f"the recording in {mcap_path}", file=sys.stderr, flush=True)
        raise KeyboardInterrupt
    if result.status == "diverged":
        raise SimulationDiverged(_diverged_message(result, f"What ran is in {mcap_path} and {results.file('results.json')}; "),
                                 section, result)
    return section, result


def _write_outputs(results: ResultsDir, result, sm, spec, mcap_path: Path, base: dict, plans=()) -> dict:
    """The CSV, the plots and the ``simulate`` section of a run (whole, or what ran of it)."""
    from sms_cli.sim.plots import plot_simulation

    write_text_atomic(results.file("simulation.csv"), _trace_csv(result.trace, sm))
    plots = plot_simulation(result.trace, sm, [p.name for p in spec.phases], results.path)
    section = _section(result, base, {"mcap": str(mcap_path), "csv": "simulation.csv", "plots": [p.name for p in plots]},
                       plans)
    results.update("simulate", section)
    return section


def _disk_full(results: ResultsDir, rec, mcap_path: Path, base: dict):
    """The DiskFull error (exit 3) after the disk filled; records what happened in results.json if it can."""
    from sms_cli.outputs import DiskFull

    messages, until = rec.on_disk
    kept = (f"{mcap_path} keeps {messages} messages up to t = {until:.6g} s and stays readable (sms inspect shows it)"
            if until is not None else f"{mcap_path} holds no complete chunk")
    section = {**base, "status": "failed", "error": "the disk is full", "t_end_s": rec.sim_time, "steps": rec.steps,
               "recorded_until_s": until, "files": {"mcap": str(mcap_path)}}
    try:
        results.update("simulate", section)
        said = f"{results.file('results.json')} says so"
    except OSError:
        said = f"{results.file('results.json')} could not be updated either"
    return DiskFull(problems=[Problem(
        f"the disk filled while simulating (t = {rec.sim_time:.6g} s reached): {kept}; {said}", Location(mcap_path),
        hint="free some space on that disk, or write elsewhere (-o), and run again")])
