"""``sms campaign``: define the runs → connect the workers → execute → store → statistics.

The order matters for the promise that bad input writes nothing: the campaign file is read and
every dispersion path resolved, and the Dask scheduler reached, before the results folder is
touched.
"""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sms_cli.campaign import paths
from sms_cli.campaign.dispersions import Parameter, draws, new_entropy, run_count
from sms_cli.campaign.schema import CampaignSpec
from sms_cli.campaign.store import CampaignStore, attempts_so_far, finished_runs
from sms_cli.campaign.tasks import RunTask
from sms_cli.errors import InputError, Location, Problem
from sms_cli.mission.load import LoadedMission


@dataclass
class Campaign:
    """A campaign resolved against its mission: the nominal tree, the parameters, the entropy."""

    loaded: LoadedMission
    spec: CampaignSpec
    tree: dict[str, Any]
    parameters: list[Parameter]
    entropy: int
    gains_yaml: str | None = None

    @property
    def runs(self) -> int:
        return run_count(self.spec)

    def samples(self, runs: list[int]) -> dict[int, dict[str, tuple[str, Any]]]:
        """{run: {name: (path, SI value)}} for the given runs; a parameter written to several paths
        has one entry per path (the second and later keyed ``name@path``)."""
        xs = draws(self.spec, self.entropy, runs)
        out = {}
        for r in runs:
            row = {}
            for p in self.parameters:
                for k, (path, v) in enumerate(p.values(xs[r][p.name])):
                    plain = [float(a) for a in v] if isinstance(v, np.ndarray) else float(v)
                    row[p.name if k == 0 else f"{p.name}@{path}"] = (path, plain)
            out[r] = row
        return out

    def tasks(self, runs: list[int], attempts: dict[int, int] | None = None) -> list[RunTask]:
        attempts = attempts or {}
        s = self.samples(runs)
        return [RunTask(run=r, tree=self.tree, base_dir=str(self.loaded.path.parent), name=self.loaded.path.name,
                        stages=self.spec.ordered_stages, samples=s[r], attempt=attempts.get(r, 0) + 1,
                        timeout_s=float(self.spec.timeout), gains_yaml=self.gains_yaml,
                        variants=tuple(self.spec.variants.items())) for r in runs]

    def seed_of(self, run: int) -> dict[str, Any]:
        return {"entropy": str(self.entropy), "run": run}

    def meta(self) -> dict[str, Any]:
        """campaign.json: enough to draw every run again (``--resume``, ``rerun``)."""
        return {
            "mission": str(self.loaded.path), "mission_name": self.loaded.mission.name,
            "mission_sha256": hashlib.sha256(self.loaded.text.encode("utf-8")).hexdigest(),
            "entropy": str(self.entropy), "design": self.spec.design, "runs": self.runs,
            "stages": list(self.spec.ordered_stages), "timeout_s": float(self.spec.timeout),
            "retries": self.spec.retries,
            "parameters": [{"name": p.name, "path": p.spec.paths[0], "paths": p.spec.paths,
                            "distribution": p.spec.distribution,
                            "mode": p.spec.mode, "nominal": p.nominal.tolist() if isinstance(p.nominal, np.ndarray)
                            else p.nominal, **_declared(p)} for p in self.parameters],
            "variants": self.spec.variants,
            "requirements": [r.model_dump(mode="json", exclude_none=True) for r in self.spec.requirements],
        }


def _declared(p: Parameter) -> dict[str, Any]:
    keys = ("low", "high", "mean", "std", "values", "weights", "levels")
    return {k: getattr(p.spec, k) for k in keys if getattr(p.spec, k) is not None}


def define(loaded: LoadedMission, entropy: int | None = None) -> Campaign:
    """Resolve the mission's ``campaign:`` section; InputError naming the file and line of a path that
    does not exist (with a did-you-mean) or a mission without one."""
    spec = loaded.mission.campaign
    if spec is None:
        raise InputError(problems=[Problem("this mission has no campaign: section", loaded.source.locate(()),
                                           hint="add one (see `sms schema` or missions/campaign_*.yaml), "
                                                "usually in a file that extends this mission")])
    tree = _tree_of(loaded)
    if loaded.mission.robot is not None:  # the URDF as the file that named it meant it (an extended file's folder)
        tree["robot"] = {**tree["robot"], "urdf": str(loaded.resolve(loaded.mission.robot.urdf, ("robot", "urdf")))}
    sm = _nominal_model(loaded)
    params = []
    for i, d in enumerate(spec.dispersions):
        nominals = []
        for j, path in enumerate(d.paths):
            at = ("campaign", "dispersions", i, "path") + ((j,) if isinstance(d.path, list) else ())
            nominals.append(_nominal_at(loaded, sm, d, path, at))
        params.append(Parameter(d, tuple(nominals)))
    _check_variants(loaded, tree)
    seed = spec.entropy if spec.entropy is not None else entropy if entropy is not None else new_entropy()
    return Campaign(loaded, spec, tree, params, int(seed))


def _check_variants(loaded: LoadedMission, tree: dict[str, Any]) -> None:
    """Each variant's mission must load: its problems are reported at the variant's line."""
    from sms_cli.mission.load import _merge, load_mission_dict

    for name, overlay in loaded.mission.campaign.variants.items():
        where = loaded.source.locate(("campaign", "variants", name))
        try:
            load_mission_dict({k: v for k, v in _merge(tree, overlay).items() if k != "campaign"},
                              base_dir=loaded.path.parent, name=loaded.path.name)
        except InputError as exc:
            p = exc.problems[0]
            raise InputError(problems=[Problem(f"variant {name!r}: {p.field + ': ' if p.field else ''}{p.message}",
                                               where, f"campaign.variants.{name}", hint=p.hint)]) from None


def _nominal_at(loaded: LoadedMission, sm, d, path: str, at: tuple) -> float | np.ndarray:
    """The nominal value of one dispersion path; InputError at the path's line with a did-you-mean."""
    try:
        return paths.nominal(loaded.mission, path, sm)
    except paths.PathError as exc:
        fixes = exc.corrected(path)
        hint = exc.hint or (f"did you mean {' or '.join(fixes)}?" if fixes
                            else "write a dotted path to a number of the mission (see the campaign schema)")
        raise InputError(problems=[Problem(f"dispersion {d.key!r}: {exc}", loaded.source.locate(at),
                                           ".".join(map(str, at)), hint=hint)]) from None


def _tree_of(loaded: LoadedMission) -> dict[str, Any]:
    """The mission's data with its ``extends`` chain applied (a file, or text given to the API)."""
    from sms_cli.mission.load import _extend, _load_tree
    from sms_cli.mission.yaml_source import load_yaml_text

    if loaded.path.is_file() and loaded.path.read_text(encoding="utf-8") == loaded.text:
        return _load_tree(loaded.path)[0]
    data, smap = load_yaml_text(loaded.text, loaded.path)
    return _extend(loaded.path, data, smap)[0]


def _nominal_model(loaded: LoadedMission):
    """The mission's model without dispersions (robot link paths read their nominal value from it)."""
    import sms_cli.api as api

    if loaded.mission.robot is None:
        return None
    return api.compile(loaded)


def folder_plan(folder: Path, resume: bool, restart: bool) -> str:
    """'new', 'resume' or 'restart' for the results folder; InputError when it holds results and
    neither flag says what to do with them (a campaign never deletes earlier results)."""
    state = CampaignStore.state(folder)
    if state == "empty":
        return "new"
    if resume and state == "campaign":
        return "resume"
    if restart:
        return "restart"
    what = "an earlier campaign" if state == "campaign" else "other files"
    hint = ("continue it with --resume, or start over with --restart (the old results move to previous/)"
            if state == "campaign" else "write the campaign to an empty folder, or --restart (the files move to previous/)")
    raise InputError(problems=[Problem(f"the results folder holds {what}", Location(folder), hint=hint)])


def run(campaign: Campaign, folder: Path, *, scheduler: str | None = None, workers: int | None = None,
        resume: bool = False, restart: bool = False, progress: bool | None = None) -> dict[str, Any]:
    """Execute the campaign's missing runs into ``folder``; returns the results.json ``campaign`` section.
    Raises CampaignInterrupted (Ctrl-C: what finished is stored; ``--resume`` goes on)."""
    from sms_cli.campaign.execute import connect, execute
    from sms_cli.campaign.runner import execute_run
    from sms_cli.results import folder_lock

    plan = folder_plan(folder, resume, restart)
    store = CampaignStore(folder, campaign.meta(), campaign.seed_of)
    if plan == "resume":
        store.check_resumable()
    with connect(scheduler, workers) as pool:  # an unreachable scheduler stops here, nothing written
        with folder_lock(folder, campaign.loaded.mission.name):
            if plan == "restart":
                moved = store.archive_previous()
                print(f"  earlier results moved to {moved}", file=sys.stderr)
            done = finished_runs(folder) if plan == "resume" else set()
            todo = [r for r in range(campaign.runs) if r not in done]
            if plan == "resume":
                print(f"  resuming: {len(done)} of {campaign.runs} runs finished, {len(todo)} to run", file=sys.stderr)
            nominal_gains(campaign, folder)
            with store:
                execute(pool, campaign.tasks(todo, attempts_so_far(folder)), execute_run,
                        timeout_s=float(campaign.spec.timeout), retries=campaign.spec.retries,
                        on_outcome=store.record, progress=progress)
    return summarize(campaign, folder)


def needs_nominal_gains(campaign: Campaign) -> bool:
    """Whether the runs simulate with synthesized gains (``attitude: from_gains``, an NDI without
    gains of its own) that they do not synthesize themselves."""
    m = campaign.loaded.mission
    sim = m.simulation
    if m.synthesis is None or sim is None or "simulate" not in campaign.spec.stages or "synthesize" in campaign.spec.stages:
        return False
    ndi_reads_gains = sim.ndi is not None and sim.ndi.gains is None and sim.ndi.kp is None
    return sim.attitude == "from_gains" or ndi_reads_gains


def nominal_gains(campaign: Campaign, folder: Path) -> None:
    """Synthesize the gains once on the nominal mission into ``folder/nominal/`` (kept on resume):
    every run's controller is then the one designed for the nominal plant."""
    if not needs_nominal_gains(campaign):
        return
    import sms_cli.api as api

    target = folder / "nominal"
    if not (target / "gains.yaml").exists():
        print("  synthesizing the gains on the nominal mission (every run uses them)", file=sys.stderr)
        api.synthesize(campaign.loaded, out=target, plots=False)
    campaign.gains_yaml = (target / "gains.yaml").read_text(encoding="utf-8")


def summarize(campaign: Campaign, folder: Path) -> dict[str, Any]:
    """Statistics and plots of what the folder holds → results.json ``campaign`` section."""
    from sms_cli.campaign.plots import write_plots
    from sms_cli.campaign.stats import campaign_section
    from sms_cli.results import ResultsDir

    section = campaign_section(folder)
    section["artifacts"] = write_plots(folder, section)
    rd = ResultsDir(folder)
    with rd.writing(campaign.loaded.mission.name, campaign.loaded.path):
        rd.update("campaign", section)
    return section


def format_campaign(section: dict[str, Any], folder: Path) -> str:
    """The terminal summary: counts, the mission requirements' pass rates, the campaign verdicts."""
    from sms_cli.check.requirements import Verdict, format_verdicts

    r = section["runs"]
    lines = [f"campaign: {r.get('finished', 0)} of {r.get('total', 0)} runs finished "
             f"({r.get('ok', 0)} ok, {r.get('diverged', 0)} diverged, {r.get('invalid', 0)} invalid draws), "
             f"{r.get('attempts', 0)} attempts ({r.get('retried', 0)} retried)"]
    if section.get("pass_rates"):
        lines.append("mission requirements over the runs (Wilson 95 % interval):")
        for p in section["pass_rates"]:
            if p.get("rate") is None:
                continue
            lines.append(f"  {p['name']}: {p['passed']}/{p['n']} = {100 * p['rate']:.1f} % "
                         f"[{100 * p['low']:.1f}, {100 * p['high']:.1f}]")
    if section.get("sensitivities"):
        s = section["sensitivities"][0]
        lines.append(f"strongest sensitivity: {s['metric']} against {s['parameter']}: Spearman rho {s['rho']:+.3f}")
    if section.get("requirements"):
        lines.append(format_verdicts([Verdict(**v) for v in section["requirements"]]).rstrip("\n"))
    lines.append(f"results: {folder}/ (campaign.json, manifest.jsonl, metrics/*.parquet, results.json, plots/)")
    return "\n".join(lines) + "\n"
