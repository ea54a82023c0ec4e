"""The Python API of sms: load a mission, compile it, run each stage, get typed results.

    import sms_cli as sms

    mission = sms.load_mission("missions/hipparcos_leo.yaml")      # or load_mission_text / load_mission_dict
    budget = sms.budget(mission)                                   # computes; writes nothing
    print(budget.dv_m_s, budget.propellant_kg, budget.closes)
    sms.budget(mission, out="results/leo")                         # also writes what `sms budget -o results/leo` writes

Every stage function takes a mission (a ``LoadedMission``, or the path of a mission file) and
returns a result object: its figures as attributes (SI units, named in the attribute: ``_m_s``,
``_kg``, ``_s``, ``_rad``, ``_deg``, ``_Nm``…) and ``section``, the plain-JSON dict that the same
stage writes into ``results.json`` (NaN and infinity as ``None``). Files are written only when
``out`` names a results folder; then they are exactly the ones the CLI writes there, and
``files`` lists them. Errors are the CLI's: ``InputError`` (exit code 2 in the CLI: the mission,
its URDF or a path is wrong; ``problems`` holds each finding with its file, line, column and
field) and ``NumericalError`` (exit 3: an infeasible or unverified synthesis, a diverged
simulation, a singular model).

Frames (``README.md``, Conventions): "world" is the inertial frame of the simulation, "base" the
frame of the URDF's root link; the analysis's satellite frame is the base frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sms_cli.analysis.modal import LinearModel
from sms_cli.errors import InputError, NumericalError, SmsError
from sms_cli.mission.load import (
    LoadedMission,
    load_mission,
    load_mission_dict,
    load_mission_text,
)
from sms_cli.model.system import SystemModel
from sms_cli.synthesis.gains_io import GainsFile
from sms_cli.synthesis.verify import Check

#: A mission: loaded (``load_mission``, ``load_mission_text``, ``load_mission_dict``) or the path of its file.
MissionLike = LoadedMission | str | os.PathLike
#: A folder (a results folder is created when missing).
PathLike = str | os.PathLike


def _loaded(mission: MissionLike) -> LoadedMission:
    if isinstance(mission, LoadedMission):
        return mission
    if isinstance(mission, (str, os.PathLike)):
        return load_mission(os.fspath(mission))
    raise TypeError(f"expected a LoadedMission or the path of a mission file, got {type(mission).__name__}")


def _folder(out: PathLike | None) -> Path | None:
    """``out`` as a results folder, checked as the CLI checks it before any work (InputError when unusable)."""
    if out is None:
        return None
    from sms_cli.outputs import check_output_dir

    return check_output_dir(Path(out), "results folder")


def _plain(section: dict[str, Any]) -> dict[str, Any]:
    from sms_cli.results import _jsonable

    return _jsonable(section)


def _written(out: Path | None, names: list[str]) -> list[Path]:
    return [] if out is None else [out / "results.json"] + [out / n for n in names]


# ------------------------------------------------------------------ compile


def compile(mission: MissionLike, *, strict: bool = False) -> SystemModel:
    """Compile a mission's robot, wheels, appendages, springs and payloads into a ``SystemModel``,
    with the checks of ``sms compile`` (the ``simulation:`` section's joint and payload names too).

    The model: ``total_mass`` (kg), ``nq``/``nv`` (Pinocchio free-flyer configuration and velocity
    sizes), ``nx`` (``nv`` + flexible modes: the DoF), ``wheels``, ``arm``, ``springs``,
    ``appendages``, ``payloads``, ``q0`` (initial configuration), ``com(q)`` (m, world frame),
    ``warnings`` (accepted findings, each with its URDF or mission line). ``strict`` refuses those
    findings (as ``sms compile --strict``). Raises ``InputError``.
    """
    from sms_cli.model.compiler import compile_system

    loaded = _loaded(mission)
    sm = compile_system(loaded, strict=strict)
    if loaded.mission.simulation is not None:
        from sms_cli.sim.validate import validate_simulation

        validate_simulation(sm, loaded)
    return sm


# ------------------------------------------------------------------ budget


@dataclass(frozen=True)
class ScenarioBudget:
    """One scenario of a ΔV budget (SI units)."""

    name: str
    dv_m_s: float  #: total ΔV with the per-manoeuvre margins (m/s)
    dv_impulsive_m_s: float  #: total impulsive ΔV, without margins (m/s)
    propellant_kg: float  #: propellant used (kg)
    burn_duration_s: float  #: sum of the burn times (s)
    mission_duration_s: float  #: burns plus coasts (s); coasts still to be decided count 0
    dry_mass_kg: float
    wet_mass_kg: float  #: mass at the start (kg)
    final_mass_kg: float  #: mass after the last step, attached targets included (kg)
    residual_propellant_kg: float  #: propellant left at the end (kg)
    required_wet_mass_kg: float | None  #: smallest wet mass that closes the budget (None: none does)
    closes: bool  #: the propellant suffices with the reserve margin
    steps: list[dict[str, Any]]  #: one row per manoeuvre (ΔV, propellant, masses, orbit after: the CSV's columns)


@dataclass(frozen=True)
class BudgetResult:
    """What ``budget`` computed. A mission without ``scenarios:`` has one scenario; its figures are
    also attributes of this object (``dv_m_s``, ``propellant_kg``, …: ``ValueError`` when there
    are several, use ``scenarios``)."""

    scenarios: list[ScenarioBudget]
    section: dict[str, Any]  #: the ``budget`` section of results.json
    files: list[Path] = field(default_factory=list)  #: files written (empty without ``out``)

    def _only(self) -> ScenarioBudget:
        if len(self.scenarios) != 1:
            raise ValueError(f"this budget has {len(self.scenarios)} scenarios: use .scenarios[k]")
        return self.scenarios[0]

    @property
    def dv_m_s(self) -> float:
        """Total ΔV with margins (m/s)."""
        return self._only().dv_m_s

    @property
    def propellant_kg(self) -> float:
        """Propellant used (kg)."""
        return self._only().propellant_kg

    @property
    def wet_mass_kg(self) -> float:
        """Mass at the start (kg)."""
        return self._only().wet_mass_kg

    @property
    def closes(self) -> bool:
        """Whether the propellant suffices with the reserve margin."""
        return self._only().closes


def _scenario(sc: dict[str, Any]) -> ScenarioBudget:
    t, m = sc["totals"], sc["mass"]
    return ScenarioBudget(
        name=sc["name"], dv_m_s=t["dv_m_s"], dv_impulsive_m_s=t["dv_impulsive_m_s"], propellant_kg=t["propellant_kg"],
        burn_duration_s=t["burn_duration_s"], mission_duration_s=t["mission_duration_s"], dry_mass_kg=m["dry_mass_kg"],
        wet_mass_kg=m["wet_mass_kg"], final_mass_kg=m["final_mass_kg"], residual_propellant_kg=m["residual_propellant_kg"],
        required_wet_mass_kg=m["required_wet_mass_kg"], closes=m["closes"], steps=sc["steps"])


def budget(mission: MissionLike, out: PathLike | None = None) -> BudgetResult:
    """Orbital ΔV, propellant and burn-time budget of the mission's ``budget:`` sequence (as ``sms budget``).

    ``out``: a results folder to write ``results.json`` (section ``budget``), ``budget.csv``,
    ``budget_mass.png`` and ``budget_dv.png`` into; nothing is written without it.
    Raises ``InputError`` (no ``budget:`` section, an impossible manoeuvre).
    """
    from sms_cli.orbit.stage import compute_budget, write_budget

    loaded, folder = _loaded(mission), _folder(out)
    data = compute_budget(loaded)
    if folder is not None:
        write_budget(data, folder)
    section = _plain(data)
    return BudgetResult([_scenario(sc) for sc in section["scenarios"]], section, _written(folder, section["artifacts"]))


# ------------------------------------------------------------------ analyze


@dataclass(frozen=True)
class IndexStats:
    """Statistics of one index over the sampled configurations (the index's unit; ``None`` when no sample has it).
    Percentiles are exact up to 200 000 samples, from a uniform subset beyond."""

    min: float | None
    max: float | None
    mean: float | None
    nan: int  #: samples where the index is undefined
    p01: float | None = None
    p05: float | None = None
    p50: float | None = None
    p95: float | None = None
    p99: float | None = None


@dataclass(frozen=True)
class VariantIndices:
    """The indices of one design variant (``nominal``, then the mission's ``analysis.variants``).

    Index names, meanings and units are the columns of ``sms analyze``'s CSV (``sms_cli/analysis/indices.py``):
    ``mu_gjm`` (manipulability of the generalized Jacobian), ``K_m`` (joint share of the base
    attitude disturbance), ``h_ratio`` (arm momentum over the wheels' capacity), ``ee_x``… (m, end
    effector in the satellite frame = base frame)…"""

    name: str
    indices: dict[str, IndexStats]
    singular_fraction: float | None  #: fraction of samples where the generalized Jacobian is singular
    K_m_worst: float | None  #: largest K_m
    h_ratio_worst: float | None  #: largest h_ratio (> 1: the wheels cannot absorb the arm's worst momentum)
    skipped: dict[str, str]  #: index groups not computed, and why
    best: dict[str, list[dict[str, Any]]]  #: per index, the best configurations (value, sample, joint values q, ee position)


@dataclass(frozen=True)
class AnalysisResult:
    """What ``analyze`` computed."""

    samples: int  #: configurations sampled (per variant)
    method: str  #: ``grid`` or ``sobol``
    variants: dict[str, VariantIndices]
    modal: list[dict[str, Any]]  #: per ``analysis.modal`` configuration: coupled modes (rad/s, Hz, damping ratio)
    linear_models: list[LinearModel]  #: per ``analysis.modal`` configuration: ẋ = A x + B u, y = C x + D u (SI)
    section: dict[str, Any]  #: the ``analysis`` section of results.json
    files: list[Path] = field(default_factory=list)  #: files written (empty without ``out``)

    @property
    def nominal(self) -> VariantIndices:
        """The indices of the robot as the mission describes it."""
        return next(iter(self.variants.values()))


def _variant(name: str, v: dict[str, Any]) -> VariantIndices:
    keys = set(IndexStats.__dataclass_fields__)
    return VariantIndices(name, {k: IndexStats(**{f: d[f] for f in keys if f in d}) for k, d in v["indices"].items()},
                          v["singular_fraction"], v["K_m_worst"], v["h_ratio_worst"], v["skipped"], v["best"])


def analyze(mission: MissionLike, out: PathLike | None = None, *, plots: bool | None = None,
            progress: bool = False, csv: bool = False) -> AnalysisResult:
    """Workspace study of the mission's ``analysis:`` section (defaults when it has none), as ``sms analyze``:
    kinematic indices per sampled arm configuration and per design variant, and the linear
    models of ``analysis.modal``.

    ``out``: a results folder; the per-sample tables (``analysis_<variant>.parquet``; ``.csv`` too
    with ``csv``, as ``--csv``) are then streamed there, and the plots (``plots``: default as the
    mission says) and the modal exports (``.npz``/``.mat``) written, as ``sms analyze -o`` does. Without it nothing is written (the per-sample values are then only
    summarised: ``IndexStats``, ``best``). ``progress``: a progress bar on stderr.
    Raises ``InputError``.
    """
    from sms_cli.analysis.stage import analyze_into, analyze_mission

    loaded, folder = _loaded(mission), _folder(out)
    if folder is None:
        data, models = analyze_mission(loaded, None, plots=plots, progress=progress)
    else:
        data, models = analyze_into(loaded, folder, plots=plots, progress=progress, csv=csv)
    section = _plain(data)
    return AnalysisResult(section["samples"], section["method"],
                          {n: _variant(n, v) for n, v in section["variants"].items()},
                          section.get("modal", []), models, section, _written(folder, section["artifacts"]))


# ------------------------------------------------------------------ synthesize


@dataclass(frozen=True)
class SynthesisResult:
    """What ``synthesize`` computed: gains, verified after the solve.

    ``gains`` is the content of gains.yaml: ``actuators``; ``controller.kp``/``kv`` (``units``
    ``acceleration``: 1/s² and 1/s per actuator, for ``lmi``; ``torque``: N m/rad and N m s/rad per
    base axis x, y, z of the base frame, for ``pd``/``lqr``); ``observer.L`` (``lmi``); ``smc``;
    ``simulation`` (the attitude-law block a mission's ``attitude: from_gains`` reads)."""

    law: str  #: ``lmi``, ``pd``, ``lqr`` or ``smc``
    verified: bool  #: every check passed
    checks: list[Check]  #: each check: ``name``, ``passed``, ``detail``, ``value`` against ``limit`` (in the check's unit)
    gains: GainsFile
    gamma: float | None  #: the LMI's guaranteed bound γ on the tracking-error energy (``lmi`` only)
    poles: list[dict[str, Any]]  #: closed-loop poles per linearisation (rad/s, complex arrays) with their ``label``
    section: dict[str, Any]  #: the ``synthesis`` section of results.json
    files: list[Path] = field(default_factory=list)  #: files written (empty without ``out``)


def synthesize(mission: MissionLike, out: PathLike | None = None, *, plots: bool = True) -> SynthesisResult:
    """Controller and observer gains for the mission's ``synthesis:`` request, as ``sms synthesize``:
    the LMI (NDI + observer with pole regions and γ, after Kraiem 2022), PD, LQR or sliding mode,
    each verified independently of its solve.

    ``out``: a results folder to write ``gains.yaml``, the pole map (``plots``) and ``results.json``
    into (a later ``simulate`` with the same folder uses those gains); nothing is written without it.
    Raises ``NumericalError`` when the LMI is infeasible, or when verification fails: then its
    ``result`` attribute is this function's result, with the unverified gains (written to ``out``
    as the CLI does, marked unverified). Raises ``InputError``.
    """
    from sms_cli.results import ResultsDir
    from sms_cli.synthesis.stage import (
        check_verified,
        synthesize_mission,
        write_synthesis,
    )

    loaded, folder = _loaded(mission), _folder(out)
    record = (lambda s: ResultsDir(folder).update("synthesis", s)) if folder is not None else None
    done = synthesize_mission(loaded, on_infeasible=record)
    if folder is not None:
        write_synthesis(done, loaded.mission.name, folder, plots)
    section = _plain(done.section)
    result = SynthesisResult(
        section["law"], section["verification"]["passed"], [Check(**c) for c in section["verification"]["checks"]],
        done.gains, section.get("gamma"), done.poles, section, _written(folder, list(section["files"].values())))
    try:
        check_verified(section, written=folder is not None)
    except NumericalError as exc:
        exc.result = result  # type: ignore[attr-defined]
        raise
    return result


# ------------------------------------------------------------------ simulate


@dataclass(frozen=True)
class SimulationResult:
    """What ``simulate`` computed.

    ``trace``: arrays sampled at the controller rate, one row per control tick (N rows):
    ``t`` (s), ``phase`` (index into the mission's phases), ``att_err`` (rad, angle of the base
    attitude error), ``joint_err`` (N × arm joints: reference − actual, rad or m), ``ee_err`` (m,
    NaN without an end-effector target), ``wheel_speed`` (N × wheels, rad/s relative to the base),
    ``wheel_torque`` (N m), ``joint_torque`` (N m or N), ``base_torque`` (N × 3, the attitude law's
    torque, N m, base frame), ``saturated`` (bool), ``modal_peak`` (largest |η|), ``momentum`` (N × 6:
    linear N s, angular about the world origin N m s, world frame), ``energy`` (J), ``base_reaction``
    (N × 6, [force N; torque N m] in the base frame while a support holds the base, else NaN),
    ``segment`` (bumps at payload attach/release and base hold)."""

    status: str  #: ``completed`` or ``diverged`` (with ``divergence`` saying why)
    divergence: str | None
    t_end_s: float  #: simulated time reached (s)
    steps: int  #: plant integration steps
    settling_time_s: float | None  #: time after which the attitude error stays inside ``settle_tolerance`` (None: never)
    attitude_error_final_deg: float | None  #: attitude error at the end (deg)
    attitude_error_max_deg: float | None
    wheel_speed_peak_rad_s: float | None  #: largest |wheel speed| (rad/s; None without wheels)
    wheel_torque_peak_Nm: float | None
    joint_error_max: float | None  #: largest |joint tracking error| (rad or m; None without arm)
    angular_momentum_drift_rel: float | None  #: largest drift of the world angular momentum, relative
    overall: dict[str, Any]  #: every metric of the whole run (``sms simulate --json``'s ``overall``)
    phases: list[dict[str, Any]]  #: the same metrics per phase, with ``name``, ``kind``, ``duration_s``
    conservation: dict[str, Any]  #: momentum drifts (absolute N s, N m s; relative) and energy change (J)
    trace: dict[str, np.ndarray]
    section: dict[str, Any]  #: the ``simulate`` section of results.json
    files: list[Path] = field(default_factory=list)  #: files written (empty without ``out``)


def _simulation_result(section: dict[str, Any], run: Any, files: list[Path]) -> SimulationResult:
    s = _plain(section)
    o, c = s["overall"], s["conservation"]
    return SimulationResult(
        s["status"], s["divergence"], s["t_end_s"], s["steps"], o.get("settling_time_s"),
        o.get("attitude_error_deg", {}).get("final"), o.get("attitude_error_deg", {}).get("max"),
        o.get("wheel_speed_peak_rad_s"), o.get("wheel_torque_peak_Nm"), o.get("joint_error_max"),
        c.get("angular_momentum_drift_rel"), o, s["phases"], c, run.trace, s, files)


def simulate(mission: MissionLike, out: PathLike | None = None, *, progress: bool = False,
             gains_dir: PathLike | None = None) -> SimulationResult:
    """Nonlinear simulation of the mission's ``simulation:`` phases, as ``sms simulate``.

    Without ``out`` the run is not recorded (no MCAP, not even in memory) and nothing is written:
    the result holds the metrics and the trace arrays. With ``out`` (a results folder) the run is
    recorded to ``out/simulation.mcap`` and ``simulation.csv``, the plots and ``results.json`` are
    written, as ``sms simulate -o out`` does. ``gains_dir``: the folder whose gains.yaml an
    ``attitude: from_gains`` law or the NDI reads (default: ``out``; e.g. the ``out`` of an earlier
    ``synthesize``). ``progress``: a progress line on stderr.

    Raises ``NumericalError`` when the simulation diverges; its ``result`` attribute is this
    function's result for what ran (written to ``out`` first, as the CLI does). Raises ``InputError``.
    """
    from sms_cli.sim.stage import (
        SimulationDiverged,
        record_simulation,
        simulate_mission,
    )

    loaded, folder = _loaded(mission), _folder(out)
    gains = None if gains_dir is None else Path(gains_dir)
    try:
        if folder is None:
            section, run = simulate_mission(loaded, progress, gains)
        else:
            section, run = record_simulation(loaded, folder, None, progress, gains)
    except SimulationDiverged as exc:
        files = [] if folder is None else _written(folder, _sim_files(exc.section))
        exc.result = _simulation_result(exc.section, exc.run, files)  # type: ignore[attr-defined]
        raise
    return _simulation_result(section, run, _written(folder, _sim_files(section)))


def _sim_files(section: dict[str, Any]) -> list[str]:
    f = section.get("files") or {}
    names = [Path(f["mcap"]).name] if "mcap" in f else []
    return names + ([f["csv"]] if "csv" in f else []) + list(f.get("plots", []))


__all__ = [
    "AnalysisResult", "BudgetResult", "Check", "IndexStats", "InputError", "LinearModel", "LoadedMission",
    "MissionLike", "NumericalError", "ScenarioBudget", "SimulationResult", "SmsError", "SynthesisResult",
    "SystemModel", "VariantIndices", "analyze", "budget", "compile", "load_mission", "load_mission_dict",
    "load_mission_text", "simulate", "synthesize",
]
