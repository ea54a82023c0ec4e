"""``sms warmup``: compile the numba kernels of given missions ahead of their first run.

numba compiles a kernel on its first call after an install and caches the machine code
(``sms_cli.sim.compiled.warmup``); a mission's first ``sms run`` / ``simulate`` / ``analyze`` would
pause for that (tens of seconds on 2 cores). This module lists, for each mission, the kernel calls
its analysis and simulation stages make, on throw-away arrays of the same types (the objects that
make the calls list them: ``IndexKernel.warm_call``, ``Simulation.kernel_groups``, for a two-spacecraft
mission ``FormationSimulation.kernel_groups``), drops calls another mission already lists with the same
argument types, and compiles the rest in parallel lanes. Nothing is written but numba's cache. The setup scripts call it once after an install.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class WarmPlan:
    """The kernel groups of some missions (callees first in each group) and what was left out and why
    (a simulation whose gains only ``sms synthesize`` writes)."""

    groups: list[list] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    _seen: set = field(default_factory=set)

    def add(self, groups: list[list]) -> None:
        """Append ``groups`` without the calls already planned with the same argument types."""
        for g in groups:
            fresh = [c for c in g if _signature(c) not in self._seen]
            self._seen.update(_signature(c) for c in fresh)
            if fresh:
                self.groups.append(fresh)

    @property
    def n_calls(self) -> int:
        return sum(len(g) for g in self.groups)


def _signature(call) -> tuple:
    """(kernel, numba types of its arguments): two calls with the same signature compile once."""
    from numba import typeof

    return call.kernel, tuple(str(typeof(a)) for a in call.args)


def plan_missions(paths: list[Path]) -> WarmPlan:
    """The kernel calls of the missions at ``paths`` (input errors raise InputError, as in ``sms compile``)."""
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    plan = WarmPlan()
    for path in paths:
        loaded = load_mission(path)
        if loaded.mission.robot is None:  # (a budget-only mission)
            continue
        if loaded.mission.formation is not None:
            _plan_formation(loaded, plan)
        if loaded.mission.analysis is None and loaded.mission.simulation is None:
            continue
        sm = compile_system(loaded)  # once, for both stages
        _plan_analysis(loaded, sm, plan)
        _plan_simulation(loaded, sm, plan)
    return plan


def _plan_analysis(loaded, sm, plan: WarmPlan) -> None:
    """The study's kernels on the nominal system ``sm`` (the variants share its argument types)."""
    from sms_cli.analysis.stage import analysis_kernel_calls
    from sms_cli.analysis.workspace import build_variants, make_sampler

    if loaded.mission.analysis is None or not sm.arm:  # `sms run` analyzes what configures it
        return
    spec = loaded.mission.analysis
    _, sampled = make_sampler(sm, spec, loaded)
    plan.add(analysis_kernel_calls(build_variants(sm, spec, sampled, loaded)[0].kernel))


def _plan_simulation(loaded, sm, plan: WarmPlan) -> None:
    """The calls of the loop ``sms simulate`` would choose for the model ``sm``, with a recorder like its own
    (never opened)."""
    from sms_cli.errors import InputError
    from sms_cli.recording.recorder import McapRecorder
    from sms_cli.results import default_results_dir
    from sms_cli.sim.engine import Simulation
    from sms_cli.sim.stage import prepared_simulation

    mission = loaded.mission
    if mission.simulation is None:  # (two spacecraft: formation:, _plan_formation)
        return
    sm, spec, _ = prepared_simulation(loaded, sm)
    with tempfile.TemporaryDirectory(prefix="sms_warmup_") as tmp:
        rec = McapRecorder(Path(tmp) / "warmup.mcap", mission_text="", mission_name=mission.name, model_summary={},
                           urdf_text=None, versions={}, record_rate_hz=spec.record_rate)
        try:
            sim = Simulation(sm, spec, rec, False, results_dir=default_results_dir(loaded.path),
                             mission_dir=loaded.path.parent, any_gains=True)
        except InputError as exc:  # attitude: from_gains without gains.yaml: only `sms synthesize` knows the law
            plan.notes.append(f"{mission.name}: simulation kernels left to its first run ({exc.problems[0].message})")
            return
        plan.add(sim.kernel_groups())


def _plan_formation(loaded, plan: WarmPlan) -> None:
    """The calls of a two-spacecraft run (``FormationSimulation.kernel_groups``: its engine's plant step, its law's,
    its recording's)."""
    from sms_cli.formation.simulate import FormationSimulation
    from sms_cli.formation.stage import prepared

    servicer, client = prepared(loaded)
    plan.add(FormationSimulation(loaded.mission, servicer, client, None, False, loaded.source.locate).kernel_groups())


def warm_missions(paths: list[Path], lanes: int | None = None) -> dict:
    """Compile the kernels of the missions at ``paths``; progress on stderr. Returns
    {"missions", "calls", "compiled", "lanes", "seconds", "notes"}."""
    from sms_cli.sim.compiled.warmup import warm

    plan = plan_missions(paths)
    result = warm(plan.groups, lanes=lanes, what="mission") if plan.groups else {"compiled": 0, "lanes": 0, "seconds": 0.0}
    return {"missions": len(paths), "calls": plan.n_calls, **result, "notes": plan.notes}
