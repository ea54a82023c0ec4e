"""`sms warmup`: the kernel calls it plans for missions are those their runs make (a run after it adds no
signature to any kernel), the same kernel with the same argument types is planned once, and the command
says what it did and what it left out."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

from typer.testing import CliRunner

from sms_cli.cli import app

ROOT = Path(__file__).resolve().parents[1]

RUN_AFTER_PLAN = textwrap.dedent('''
    import json, sys
    from pathlib import Path
    from sms_cli.analysis.stage import analyze_mission
    from sms_cli.mission.load import load_mission
    from sms_cli.run.warmup import plan_missions
    from sms_cli.sim.stage import run_simulation

    def signatures():
        out = {}
        for name, mod in list(sys.modules.items()):
            if name.startswith("sms_cli."):
                for attr, obj in vars(mod).items():
                    if hasattr(obj, "signatures") and hasattr(obj, "py_func"):
                        out[f"{name}:{attr}"] = len(obj.signatures)
        return out

    planned, run = [Path(p) for p in sys.argv[1].split(",")], Path(sys.argv[2])
    plan = plan_missions(planned)
    for group in plan.groups:
        for call in group:
            call()
    import sms_cli.sim.compiled.ndi_runner, sms_cli.sim.compiled.runner  # noqa: the loops' modules, when not planned
    before = signatures()
    loaded = load_mission(run)
    if loaded.mission.analysis is not None:
        analyze_mission(loaded, None, plots=False, progress=False)
    run_simulation(loaded, Path(sys.argv[3]), progress=False)
    after = signatures()
    print(json.dumps({"calls": plan.n_calls, "new": {k: after[k] - before.get(k, 0) for k in after
                                                     if after[k] != before.get(k, 0)}}))
''')


def _run_after_plan(tmp_path, planned: list[Path], run: Path) -> dict:
    script = tmp_path / "after_plan.py"
    script.write_text(RUN_AFTER_PLAN)
    out = subprocess.run([sys.executable, str(script), ",".join(map(str, planned)), str(run), str(tmp_path / "out")],
                         capture_output=True, text=True, timeout=900, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_flagship_run_compiles_nothing_after_the_warm_up_planned_without_its_gains(tmp_path):
    """Planned from the shipped flagship file, which has no gains yet (the NDI law gets gains of the right
    shapes), then a run of the flagship with synthesized-like gains, its analysis included: no kernel gains a
    signature (the run's first call of every kernel found it compiled)."""
    from test_compiled_ndi import FLAGSHIP, _gains, _mission_text

    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    pulsar = compile_system(load_mission(ROOT / "missions/pulsar_simple.yaml"))
    mission = tmp_path / "flagship_short.yaml"
    mission.write_text(_mission_text("pulsar_simple.yaml", "compiled", FLAGSHIP, _gains(pulsar)))
    got = _run_after_plan(tmp_path, [ROOT / "missions/pulsar_simple.yaml"], mission)
    assert got["calls"] >= 10
    assert got["new"] == {}


def test_an_arm_mission_on_the_general_compiled_loop_compiles_nothing_after_the_warm_up(tmp_path):
    """The general compiled loop with an arm law, joint stops and the recording (caldera_s2_arm), and its
    analysis's index kernel."""
    mission = ROOT / "missions/caldera_s2_arm.yaml"
    got = _run_after_plan(tmp_path, [mission], mission)
    assert got["new"] == {}


def test_a_two_spacecraft_run_compiles_nothing_after_the_warm_up(tmp_path):
    """Planned from the shipped S6 (the internal pair's reaction, a controlled shape, the HIL export) and the capture
    mission, then short runs of both on the compiled plant step (their recording included): no new signature; the
    plan holds the pair step once (both missions' calls have the same types)."""
    from sms_cli.run.warmup import plan_missions

    planned = [ROOT / "missions/vicariotto_s6_relative_hil.yaml", ROOT / "missions/caldera_capture_tumbling.yaml"]
    plan = plan_missions(planned)
    kernels = [c.kernel for g in plan.groups for c in g]
    assert kernels.count("sms_cli.sim.compiled.pair:pair_rkmk4_step") == 1
    for name, extra in (("vicariotto_s6_relative_hil", "duration: 2 s"), ("caldera_capture_tumbling", "duration: 1.5 s")):
        mission = tmp_path / f"{name}_short.yaml"
        mission.write_text(f"extends: {ROOT / 'missions' / name}.yaml\nformation: {{{extra}}}\n")
        got = _run_after_plan(tmp_path, planned, mission)
        assert got["new"] == {}, name


def test_a_kernel_with_the_same_argument_types_is_planned_once():
    """Two missions on the same loop with the same laws share every call: planning both adds none for the
    second; its calls are those planned for it alone."""
    from sms_cli.run.warmup import plan_missions

    one = plan_missions([ROOT / "missions/caldera_s1_slew.yaml"])
    two = plan_missions([ROOT / "missions/caldera_s1_slew.yaml", ROOT / "missions/caldera_s1_slew.yaml"])
    assert one.n_calls > 0 and two.n_calls == one.n_calls


def test_sms_warmup_says_what_it_compiled_and_what_it_left_to_the_first_run(tmp_path, monkeypatch):
    """The command's summary line, and the note for a mission whose law only `sms synthesize` writes (no
    results/<mission>/gains.yaml where the command runs)."""
    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(app, ["warmup", str(ROOT / "missions/caldera_s1_slew.yaml"),
                                 str(ROOT / "missions/caldera_s1_synthesized.yaml")])
    assert r.exit_code == 0, r.output
    assert "2 mission(s):" in r.output and "kernel call(s)" in r.output
    assert "caldera_s1_synthesized: simulation kernels left to its first run" in r.output


def test_sms_warmup_of_a_bad_mission_is_an_input_error(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nrobot: {urdf: nowhere.urdf}\nsimulation: {dt: 0.01, phases: []}\n")
    r = CliRunner().invoke(app, ["warmup", str(bad)])
    assert r.exit_code == 2 and "Traceback" not in r.output and "bad.yaml" in r.output, r.output
