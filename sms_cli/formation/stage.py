"""``sms simulate`` on a two-spacecraft mission: compile both spacecraft, check their geometry at t = 0,
simulate, record MCAP (both spacecraft in Foxglove's 3D panel), write relative_motion.csv (the
hardware-in-the-loop export's input), formation.csv, plots and the ``simulate`` section."""

from __future__ import annotations

import csv
import io
import sys
from pathlib import Path

import numpy as np

from sms_cli.errors import NumericalError
from sms_cli.mission.load import LoadedMission
from sms_cli.results import ResultsDir, write_text_atomic

RELATIVE_MOTION = "relative_motion.csv"
TRACE = "formation.csv"


def prepared(loaded: LoadedMission):
    """(servicer SystemModel, client SystemModel) of a mission with ``client:`` (InputError otherwise),
    refused when their bodies overlap at t = 0."""
    from sms_cli.formation.client import compile_client
    from sms_cli.formation.geometry import check_no_overlap
    from sms_cli.model import compile_system

    servicer = compile_system(loaded)
    client = compile_client(loaded)
    check_no_overlap(loaded, servicer, client)
    return servicer, client


def root_link(sm) -> str:
    """The URDF link of a SystemModel's free-flying base (its parent is the world)."""
    return next(link for link, parent in sm.link_parents.items() if parent == "world")


def _relative_motion_csv(trace: dict) -> str:
    """t, both bases' world poses (position m, quaternion xyzw) and body twists (base frames): body 1 = master."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    head = ["t"]
    for k in ("1", "2"):
        head += [f"p{k}_x", f"p{k}_y", f"p{k}_z", f"q{k}_x", f"q{k}_y", f"q{k}_z", f"q{k}_w"]
    for k in ("1", "2"):
        head += [f"v{k}_x", f"v{k}_y", f"v{k}_z", f"w{k}_x", f"w{k}_y", f"w{k}_z"]
    w.writerow(head)
    for i in range(trace["t"].size):
        row = [trace["t"][i], *trace["p1"][i], *trace["q1"][i], *trace["p2"][i], *trace["q2"][i], *trace["V1"][i],
               *trace["V2"][i]]
        w.writerow([repr(float(x)) for x in row])
    return buf.getvalue()


def _trace_csv(trace: dict) -> str:
    """The sampled locked/shape state: twists, errors, momentum, energies, wheel rates."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    tw = ("vx", "vy", "vz", "wx", "wy", "wz")
    head = (["t_s"] + [f"locked_{c}" for c in tw] + [f"shape_{c}" for c in tw]
            + ["shape_error_x_m", "shape_error_y_m", "shape_error_z_m", "shape_error_angle_deg"]
            + [f"momentum_{c}" for c in ("px", "py", "pz", "kx", "ky", "kz")]
            + ["energy_locked_J", "energy_shape_J", "energy_total_J", "lyapunov_J", "saturated"])
    w.writerow(head)
    for i in range(trace["t"].size):
        row = [trace["t"][i], *trace["V_L"][i], *trace["V_E"][i], *trace["shape_position"][i],
               float(np.degrees(trace["shape_angle"][i])), *trace["H_world"][i], trace["T_L"][i], trace["T_E"][i],
               trace["T"][i], trace["W"][i]]
        w.writerow([f"{float(x):.9g}" for x in row] + [int(trace["saturated"][i])])
    return buf.getvalue()


def record_formation(loaded: LoadedMission, out_dir: Path, mcap_path: Path | None = None,
                     progress: bool | None = None) -> dict:
    """Simulate the mission's ``formation:`` section into ``out_dir``; returns the ``simulate`` section.
    Diverged: everything written, then NumericalError (exit 3). Interrupted: what ran is written, then
    KeyboardInterrupt (exit 130)."""
    from sms_cli.formation.metrics import formation_metrics
    from sms_cli.formation.plots import plot_formation
    from sms_cli.formation.recording import formation_timing
    from sms_cli.sim.timing import TIMING_METADATA
    from sms_cli.formation.simulate import FormationSimulation
    from sms_cli.formation.urdf_pair import pair_urdf
    from sms_cli.model.summary import model_summary
    from sms_cli.recording.recorder import McapRecorder
    from sms_cli.sim.stage import versions

    servicer, client = prepared(loaded)
    results = ResultsDir(out_dir)
    with results.writing(loaded.mission.name, loaded.path):
        mcap_path = Path(mcap_path) if mcap_path else results.file("simulation.mcap")
        sim = FormationSimulation(loaded.mission, servicer, client, None, progress, loaded.source.locate)
        urdf = pair_urdf([(b.name, b.system.urdf_text, root_link(b.system)) for b in sim.plant.bodies])
        rec = McapRecorder(mcap_path, mission_text=loaded.text, mission_name=loaded.mission.name,
                           model_summary={f"{b.name}.{k}": v for b in sim.plant.bodies
                                          for k, v in model_summary(b.system).items()},
                           urdf_text=urdf, versions=versions(), record_rate_hz=None,
                           metadata={TIMING_METADATA: formation_timing(loaded.mission.formation)})
        rec.add_transform_tree(sim.links.names, sim.links.parents)
        sim.recorder = rec
        result = None
        try:
            with rec:
                result = sim.run()
                rec.finish("failed" if result.status == "capture_missed" else result.status,
                           {"reason": result.divergence} if result.divergence else None)
        except KeyboardInterrupt:
            if result is None:
                raise
        spec = loaded.mission.formation
        section = {
            "mission": loaded.mission.name, "mission_file": str(loaded.path), "status": result.status,
            "divergence": result.divergence or None, "t_end_s": result.t_end, "steps": result.steps,
            "formation": {"master": sim.names[0], "other": sim.names[1], "relative_motion": RELATIVE_MOTION},
            **formation_metrics(result.trace, spec, sim.names, result.wall_s, result.steps, result.engine),
        }
        if result.capture is not None:
            section["capture"] = result.capture
        write_text_atomic(results.file(RELATIVE_MOTION), _relative_motion_csv(result.trace))
        write_text_atomic(results.file(TRACE), _trace_csv(result.trace))
        plots = plot_formation(result.trace, spec, sim.names, results.path)
        section["files"] = {"mcap": str(mcap_path), "csv": TRACE, "relative_motion": RELATIVE_MOTION,
                            "plots": [p.name for p in plots]}
        results.update("simulate", section)
        if spec.facility is not None and result.status == "completed":
            from sms_cli.hil.stage import run_export

            hil = run_export(results.path, loaded.resolve(spec.facility, ("formation", "facility")))
            section["hil"] = {k: hil[k] for k in ("facility", "moving", "held", "start_offset", "reachability", "workspace")}
            section["files"]["hil"] = [str(Path(f).relative_to(results.path)) for f in hil["files"].values()]
            results.update("simulate", section)
    if result.status == "interrupted":
        print(f"interrupted at t = {result.t_end:.6g} s: what ran is in {results.path}/", file=sys.stderr, flush=True)
        raise KeyboardInterrupt
    if result.status == "capture_missed":
        raise NumericalError(f"{result.divergence}. The run stopped there; what ran is in {mcap_path} and "
                             f"{results.file('results.json')}")
    if result.status == "diverged":
        raise NumericalError(f"the two-spacecraft simulation diverged at t = {result.t_end:.4g} s: {result.divergence}. "
                             f"What ran is in {mcap_path} and {results.file('results.json')}; reduce dt or the gains")
    return section

