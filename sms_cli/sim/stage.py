"""``sms simulate``: compile, simulate, record MCAP, write metrics and plots."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from sms_cli.errors import InputError, NumericalError, Problem
from sms_cli.mission.load import LoadedMission
from sms_cli.results import ResultsDir, write_text_atomic


def versions() -> dict[str, str]:
    import mcap
    import pinocchio

    from sms_cli import __version__

    return {"sms": __version__, "pinocchio": pinocchio.__version__, "numpy": np.__version__,
            "mcap": getattr(mcap, "__version__", "?")}


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


def run_simulation(loaded: LoadedMission, out_dir: Path, mcap_path: Path | None = None,
                   progress: bool | None = None) -> dict:
    """Simulate the mission; returns the ``simulate`` section written to results.json.
    Raises NumericalError (exit 3) after writing everything when the simulation diverged."""
    from sms_cli.model import compile_system
    from sms_cli.model.summary import model_summary
    from sms_cli.sim.engine import Simulation
    from sms_cli.sim.plots import plot_simulation
    from sms_cli.sim.recorder import McapRecorder

    spec = loaded.mission.simulation
    if spec is None:
        raise InputError(problems=[Problem("this mission has no 'simulation:' section", loaded.source.locate(()),
                                           hint="add simulation: {dt, control_rate, attitude, arm, phases: [...]}")])
    sm = compile_system(loaded)
    sm.require_dynamics("the simulation")
    results = ResultsDir(out_dir)
    mcap_path = Path(mcap_path) if mcap_path else results.file("simulation.mcap")
    summary = model_summary(sm)
    rec = McapRecorder(mcap_path, mission_text=loaded.text, mission_name=loaded.mission.name, model_summary=summary,
                       urdf_text=sm.urdf_text, versions=versions(), record_rate_hz=spec.record_rate)
    links = list(sm.link_parents)
    rec.add_transform_tree(links, [sm.link_parents[n] for n in links])
    with rec:
        result = Simulation(sm, spec, rec, progress, results_dir=results.path, mission_dir=loaded.path.parent).run()
        rec.finish(result.status, {"reason": result.divergence} if result.divergence else None)
    write_text_atomic(results.file("simulation.csv"), _trace_csv(result.trace, sm))
    plots = plot_simulation(result.trace, sm, [p.name for p in spec.phases], results.path)
    section = {
        "status": result.status, "divergence": result.divergence or None, "t_end_s": result.t_end, "steps": result.steps,
        "overall": result.overall, "phases": result.phases, "conservation": result.conservation, "timing": result.timing,
        "files": {"mcap": str(mcap_path), "csv": "simulation.csv", "plots": [p.name for p in plots]},
    }
    results.update("simulate", section)
    if result.status == "diverged":
        raise NumericalError(f"the simulation diverged at t = {result.t_end:.4g} s: {result.divergence}. "
                             f"What ran is in {mcap_path} and {results.file('results.json')}; "
                             "reduce dt, lower the gains or check the model")
    return section
