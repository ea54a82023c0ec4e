"""The kernel warm-up (sms_cli.sim.compiled.warmup, .kernels): lanes, the worker process, and the
claim that the warm-up calls have the real calls' argument types (the run compiles nothing more)."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from sms_cli.sim.compiled.warmup import KernelCall, warm

ROOT = Path(__file__).resolve().parents[1]


TOY = textwrap.dedent('''
    from numba import njit

    @njit(cache=True)
    def double_into(x, out):
        for i in range(x.shape[0]):
            out[i] = 2.0 * x[i]

    @njit(cache=True)
    def add_into(x, y, out):
        for i in range(x.shape[0]):
            out[i] = x[i] + y[i]
''')


def _toy_module(tmp_path, monkeypatch, name: str):
    """TOY's kernels as module ``name`` in tmp_path, with numba's cache there too (workers inherit it)."""
    import importlib

    import numba

    pkg = tmp_path / "src"
    pkg.mkdir()
    (pkg / f"{name}.py").write_text(TOY)
    cache = tmp_path / "cache"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(cache))
    monkeypatch.setenv("PYTHONPATH", str(pkg))
    monkeypatch.syspath_prepend(str(pkg))
    return importlib.import_module(name)


def test_a_worker_lane_compiles_into_the_cache_this_process_then_loads(tmp_path, monkeypatch):
    """Two groups on two lanes: the costlier compiles in a worker process, the other here; this
    process then loads the worker's from the cache (a hit, no compilation of its own)."""
    toy = _toy_module(tmp_path, monkeypatch, "sms_toy_kernels")
    x = np.arange(3.0)
    costly = KernelCall("sms_toy_kernels:double_into", (x, np.empty(3)), cost=2.0)
    cheap = KernelCall("sms_toy_kernels:add_into", (x, x, np.empty(3)), cost=1.0)
    log = io.StringIO()
    report = warm([[cheap], [costly]], lanes=2, stream=log)
    assert report == {"compiled": 2, "lanes": 2, "seconds": report["seconds"]}
    assert "compiling 2 simulation kernels on 2 cores" in log.getvalue() and "kernels ready in" in log.getvalue()
    assert toy.double_into.stats.cache_hits and not toy.double_into.stats.cache_misses  # the worker's machine code
    assert toy.add_into.stats.cache_misses  # compiled here
    again = warm([[cheap], [costly]], lanes=2, stream=io.StringIO())
    assert again["compiled"] == 0 and again["lanes"] == 0  # all cached: nothing said, nothing compiled


def test_a_kernel_this_process_holds_is_cached_without_reading_the_index(tmp_path, monkeypatch):
    """``cached`` on a kernel with machine code in this process answers True without reading numba's
    index files (each run of a campaign paid that read again); before the first call it reads the index
    (empty cache: False)."""
    import sms_cli.sim.compiled.warmup as W

    toy = _toy_module(tmp_path, monkeypatch, "sms_toy_held")
    call = KernelCall("sms_toy_held:add_into", (np.arange(3.0), np.arange(3.0), np.empty(3)))
    reads = []
    index_file = toy.add_into._cache._cache_file
    real = index_file._load_index
    monkeypatch.setattr(index_file, "_load_index", lambda: reads.append(1) or real())
    assert W.cached(call) is False and len(reads) == 1  # nothing compiled anywhere yet
    call()  # compiles (numba reads and writes its index here)
    n = len(reads)
    assert W.cached(call) is True and len(reads) == n  # held here: the index is not read again
    import functools

    timed = functools.wraps(toy.add_into, updated=())(lambda *a: 0)  # a timer around the kernel (only __wrapped__)
    monkeypatch.setattr(toy, "add_into", timed)
    assert W.cached(call) is True  # the kernel behind the wrapper


SIGNATURES = textwrap.dedent('''
    import json, sys
    from pathlib import Path
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system
    from sms_cli.sim.engine import Simulation
    from sms_cli.recording.recorder import McapRecorder
    from sms_cli.sim.stage import planned_simulation
    from sms_cli.model.summary import model_summary
    import sms_cli.sim.compiled.dynamics as D, sms_cli.sim.compiled.loop as L, sms_cli.recording.encoding as B
    import sms_cli.sim.compiled.control as C, sms_cli.sim.compiled.attitude_laws as A, sms_cli.sim.compiled.arm_laws as R
    import sms_cli.sim.compiled.momentum_laws as Mo, sms_cli.sim.compiled.momentum_control as Mc
    import sms_cli.sim.compiled.profiles as Pf, sms_cli.sim.compiled.held_base as Hb, sms_cli.sim.compiled.resolved_rate as Rr
    import sms_cli.sim.compiled.disturbances as Di, sms_cli.sim.compiled.sensors as Se

    loaded = load_mission(sys.argv[1])
    sm = compile_system(loaded)
    spec, _ = planned_simulation(sm, loaded)
    spec = spec.model_copy(update={"phases": spec.phases[:1], **({"engine": sys.argv[4]} if len(sys.argv) > 4 else {})})
    rec = McapRecorder(Path(sys.argv[2]), mission_text=loaded.text, mission_name=loaded.mission.name,
                       model_summary=model_summary(sm), urdf_text=sm.urdf_text, versions={}, record_rate_hz=spec.record_rate)
    links = list(sm.link_parents)
    rec.add_transform_tree(links, [sm.link_parents[n] for n in links])
    with rec:
        sim = Simulation(sm, spec, rec, False, results_dir=sys.argv[3], mission_dir=loaded.path.parent)
        sim.warm_up()
        kernels = {getattr(m, n) for m in (D, L, B, C, A, R, Mo, Mc, Pf, Hb, Rr, Di, Se) for n in dir(m)
                   if hasattr(getattr(m, n), "signatures")}
        before = {k.py_func.__name__: len(k.signatures) for k in kernels}
        res = sim.run()
        rec.finish(res.status)
    after = {k.py_func.__name__: len(k.signatures) for k in kernels}
    print(json.dumps({"engine": res.timing["engine"], "new": {n: after[n] - before[n] for n in after if after[n] != before[n]}}))
''')


@pytest.mark.parametrize("mission, engine", [("missions/basilisk_rw_reference", "compiled"),
                                             ("tests/data/compiled_law_smc", "compiled"),
                                             ("tests/data/compiled_law_quaternion_pd", "compiled"),
                                             ("missions/astrobee_arm", "compiled"),
                                             ("missions/caldera_s2_arm", "compiled"),
                                             ("missions/astrobee_slew_backstepping", "compiled"),
                                             ("missions/caldera_eo", "compiled"),
                                             ("missions/chevallard_deploy_track", "compiled"),
                                             ("tests/data/noisy_caldera_eo", "compiled"),
                                             ("tests/data/noisy_caldera_s2_arm", "compiled"),
                                             ("tests/data/compiled_disturbances", "compiled"),
                                             ("tests/data/compiled_law_backstepping", "python"),
                                             ("tests/data/momentum_offset", "python"),
                                             ("tests/data/momentum_hierarchical", "compiled"),
                                             ("missions/vicariotto_s3d_hierarchical", "compiled")])
def test_the_run_compiles_nothing_after_the_warm_up(tmp_path, mission, engine):
    """Every kernel the run calls was called by the warm-up with the same argument types: no
    dispatcher gains a signature during the run (the compiled loop with mrp_feedback, with smc and a
    rigid body, with quaternion_pd and the SystemModel's body, with an arm: its model-free law and joint
    stops (astrobee_arm), its computed-torque law on the attitude-held model with wheels (caldera_s2_arm),
    the online inertia J(q) with an arm (astrobee_slew_backstepping), a smooth attitude profile (caldera_eo), a held
    base with joint stops and end-effector tracking (chevallard_deploy_track; its first phase: the held base),
    disturbances (compiled_disturbances); the compiled loop with a flexible panel, an arm law on its augmented
    model, joint stops, a recording and a noisy gyro (noisy_caldera_eo); the
    compiled loop with noisy, biased sensors (noisy_caldera_s2_arm); the Python loop running an attitude law's kernels, with the
    SystemModel's online body; the Python loop running a momentum law's kernels, the law and its W; the compiled loop
    running a momentum law, its W each step and at each phase start; with real thrusters, the law's quantities at the
    current mass)."""
    script = tmp_path / "sigs.py"
    script.write_text(SIGNATURES)
    out = subprocess.run([sys.executable, str(script), str(ROOT / f"{mission}.yaml"), str(tmp_path / "r.mcap"),
                          str(tmp_path), *(["python"] if engine == "python" else [])], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["engine"] == engine
    assert got["new"] == {}


ANALYSIS = textwrap.dedent('''
    import io, json, sys
    from contextlib import redirect_stderr
    import sms_cli.sim.compiled.warmup as W
    from sms_cli.analysis import kernels as K
    from sms_cli.analysis.stage import analyze_mission
    from sms_cli.mission.load import load_mission

    W.cached = lambda call: False  # as on a cold cache: the warm-up says what it compiles
    err = io.StringIO()
    with redirect_stderr(err):
        analyze_mission(load_mission(sys.argv[1]), None, plots=False, progress=False)
    print(json.dumps({"said": err.getvalue(), "signatures": len(K.block_indices.signatures)}))
''')


def test_the_analysis_shows_its_kernel_compilation_and_compiles_nothing_after_it(tmp_path):
    """`sms analyze` warms ``block_indices`` and the statistics' kernels with the pause on stderr (the first analysis after an
    install compiles it for tens of seconds, silently before), on the real call's types: the study
    adds no signature (one in all)."""
    script = tmp_path / "analysis.py"
    script.write_text(ANALYSIS)
    out = subprocess.run([sys.executable, str(script), str(ROOT / "missions/demeter_3dof.yaml")], capture_output=True,
                         text=True, timeout=600, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert "analysis kernels on" in got["said"] and "compiled block_indices" in got["said"]
    assert "compiled _slice_add" in got["said"]  # the study's statistics, compiled with it
    assert got["signatures"] == 1
