"""Fuzz campaign: many mutated inputs and process faults through the real ``sms`` command, counted.

Inputs (each in a subprocess with a 3 GiB address-space limit and a timeout, like a user's shell):
  - shipped missions with one or two random edits, through ``sms compile``;
  - shipped URDFs with one or two random edits, through ``sms compile`` with a minimal mission;
  - a real results folder with results.json corrupted, through ``sms check`` and ``sms report``;
  - a real recording with flipped or cut bytes, through ``sms inspect``.
Faults (``--faults N``): SIGINT, SIGTERM or SIGKILL at a random moment of ``sms simulate``; a fault
loses data when, afterwards, results.json does not say what happened, the recording is unreadable
by the ``mcap`` reader (after ``sms inspect --repair`` for SIGKILL), or a ``.part`` file is left
after the next run.

Prints: inputs tried, the exit-code histogram, exit-4 count (target 0), hangs (target 0), exception
names shown (target 0), faults that lost data (target 0), and each failure's reproducer file.

Usage: python benches/fuzz_campaign.py [--inputs 400] [--faults 12] [--seed 0] [--keep DIR]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import random
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fuzz_mutators import corrupt_bytes, mutate_mission, mutate_urdf  # noqa: E402

SMS = str(Path(sys.executable).with_name("sms"))
EXCEPTION_NAMES = re.compile(r"\b(\w+Error|\w+Exception|Traceback|KeyboardInterrupt)\b")
MISSIONS = ["caldera_s1_slew.yaml", "pulsar_simple.yaml", "astrobee_slew_backstepping.yaml", "hipparcos_leo.yaml",
            "demeter_3dof.yaml", "chevallard_deploy_track.yaml", "basilisk_rw_reference.yaml", "caldera_smallsat.yaml"]
URDFS = ["caldera_smallsat.urdf", "pulsar_simple.urdf", "astrobee_arm.urdf", "chevallard_chaser.urdf", "demeter_3dof.urdf"]
TIMEOUT_S = 60


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


def sms(args: list[str], cwd: Path, timeout: float = TIMEOUT_S) -> tuple[int | str, str, float]:
    """(exit code or 'hang', output, seconds) of one ``sms`` command."""
    t0 = time.perf_counter()
    try:
        r = subprocess.run([SMS, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                           preexec_fn=limit_memory, env={**os.environ, "SMS_NO_PROGRESS": "1"}, errors="replace")
        return r.returncode, r.stdout + r.stderr, time.perf_counter() - t0
    except subprocess.TimeoutExpired:
        return "hang", "", time.perf_counter() - t0


class Tally:
    def __init__(self, keep: Path):
        self.codes = collections.Counter()
        self.failures: list[str] = []
        self.numerical: list[str] = []
        self.keep = keep
        self.tried = 0
        self.seconds: list[float] = []

    def add(self, kind: str, code, out: str, dt: float, reproducer: Path) -> None:
        self.tried += 1
        self.codes[code] += 1
        self.seconds.append(dt)
        bad = code not in (0, 1, 2, 3) or EXCEPTION_NAMES.search(out)
        if code == 3:  # allowed (numerical failure), but listed: a user's mistake should rather be exit 2
            first = next((ln for ln in out.splitlines() if ln.strip()), "")
            keep = self.keep / f"numerical_{len(self.numerical):03d}_{kind}{reproducer.suffix}"
            shutil.copy(reproducer, keep)
            self.numerical.append(f"{kind}: {first[:200]} (reproducer {keep})")
        if bad:
            keep = self.keep / f"{len(self.failures):03d}_{kind}{reproducer.suffix}"
            shutil.copy(reproducer, keep)
            first = next((ln for ln in out.splitlines() if ln.strip()), "")
            self.failures.append(f"{kind}: exit {code}: {first[:200]} (reproducer {keep})")


def fuzz_inputs(n: int, rng: random.Random, work: Path, tally: Tally) -> None:
    shutil.copytree(ROOT / "missions", work / "missions")
    shutil.copytree(ROOT / "robots", work / "robots")
    results = work / "results"
    code, out, _ = sms(["simulate", "missions/basilisk_rw_reference.yaml", "-o", str(results)], work, 300)
    assert code == 0, out
    mcap_bytes = (results / "simulation.mcap").read_bytes()
    results_bytes = (results / "results.json").read_bytes()
    for i in range(n):
        kind = rng.choice(["mission", "mission", "mission", "urdf", "urdf", "results", "mcap"])
        if kind == "mission":
            name = rng.choice(MISSIONS)
            path = work / "missions" / "fuzz.yaml"
            path.write_text(mutate_mission((ROOT / "missions" / name).read_text(), rng), errors="surrogateescape")
            tally.add(kind, *sms(["compile", str(path)], work), path)
        elif kind == "urdf":
            name = rng.choice(URDFS)
            (work / "robots" / "fuzz.urdf").write_text(mutate_urdf((ROOT / "robots" / name).read_text(), rng))
            path = work / "missions" / "fuzz_urdf.yaml"
            path.write_text("name: fuzz\nrobot: {urdf: ../robots/fuzz.urdf}\n")
            tally.add(kind, *sms(["compile", str(path)], work), work / "robots" / "fuzz.urdf")
        elif kind == "results":
            folder = work / "bad_results"
            folder.mkdir(exist_ok=True)
            blob = corrupt_bytes(results_bytes, rng, cut=rng.random() < 0.3)
            if rng.random() < 0.5:
                doc = json.loads(results_bytes)
                key = rng.choice(sorted(doc))
                doc[key] = rng.choice([None, [], {}, "x", 1.5, [None], {"a": None}])
                blob = json.dumps(doc).encode()
            (folder / "results.json").write_bytes(blob)
            cmd = rng.choice([["check", str(folder)], ["report", str(folder), "-o", str(work / "r.html")]])
            tally.add(kind, *sms(cmd, work), folder / "results.json")
        else:
            path = work / "fuzz.mcap"
            path.write_bytes(corrupt_bytes(mcap_bytes, rng, cut=rng.random() < 0.3))
            tally.add(kind, *sms(["inspect", str(path)], work), path)
        if (i + 1) % 50 == 0:
            print(f"  {i + 1}/{n} inputs", file=sys.stderr)


def fault_run(sig: int, delay: float, work: Path) -> str:
    """One simulate run hit by ``sig`` after ``delay`` s; '' when nothing was lost, else what was."""
    out = work / f"fault_{sig}_{delay:.2f}"
    shutil.rmtree(out, ignore_errors=True)
    proc = subprocess.Popen([SMS, "simulate", "missions/caldera_s1_slew.yaml", "-o", str(out), "--no-progress"],
                            cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not (out / "simulation.mcap").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    time.sleep(delay)
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        return "hung after the signal"
    lost = []
    mcap = out / "simulation.mcap"
    if sig == signal.SIGKILL and mcap.exists():
        sms(["inspect", "--repair", str(mcap)], work)
    if mcap.exists():
        try:
            from mcap.reader import make_reader

            with open(mcap, "rb") as fh:
                sum(1 for _ in make_reader(fh).iter_messages())
        except Exception as exc:  # noqa: BLE001 - any reader failure is lost data
            lost.append(f"recording unreadable ({type(exc).__name__})")
    status = None
    if (out / "results.json").exists():
        doc = json.loads((out / "results.json").read_text())
        status = (doc.get("simulate") or {}).get("status") or json.dumps(doc.get("run", {}))[:80]
    if sig != signal.SIGKILL and status not in ("interrupted", "ok", "completed"):
        lost.append(f"results.json status {status!r}")
    code, text, _ = sms(["simulate", "missions/basilisk_rw_reference.yaml", "-o", str(out), "--no-progress"], work, 300)
    stray = [p.name for p in out.rglob("*.part")]
    if stray:
        lost.append(f".part files left after the next run: {stray}")
    if code not in (0, 1):
        lost.append(f"the next run into the folder exited {code}: {text.strip()[:120]}")
    return "; ".join(lost)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", type=int, default=400)
    ap.add_argument("--faults", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", type=Path, default=None, help="folder for the reproducers of failures")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="sms-fuzz-"))
    keep = args.keep or work / "failures"
    keep.mkdir(parents=True, exist_ok=True)
    tally = Tally(keep)
    t0 = time.perf_counter()
    fuzz_inputs(args.inputs, rng, work, tally)
    lost = []
    sigs = [signal.SIGINT, signal.SIGTERM, signal.SIGKILL]
    for k in range(args.faults):
        sig = sigs[k % 3]
        why = fault_run(sig, rng.uniform(0.0, 1.5), work)
        if why:
            lost.append(f"{signal.Signals(sig).name}: {why}")
    hist = ", ".join(f"{c}: {n}" for c, n in sorted(tally.codes.items(), key=lambda x: str(x[0])))
    print(f"inputs tried {tally.tried} (seed {args.seed}) · exit codes {{{hist}}} · exit-4 {tally.codes.get(4, 0)} · "
          f"hangs {tally.codes.get('hang', 0)} · failures {len(tally.failures)} · "
          f"median {sorted(tally.seconds)[len(tally.seconds) // 2]:.2f} s, max {max(tally.seconds):.2f} s per command")
    print(f"faults {args.faults} (SIGINT/SIGTERM/SIGKILL during sms simulate) · lost data {len(lost)}")
    for f in tally.failures + lost:
        print("  " + f)
    for f in tally.numerical:
        print("  exit 3 (numerical): " + f)
    print(f"total {time.perf_counter() - t0:.0f} s; work folder {work}")
    return 1 if tally.failures or lost else 0


if __name__ == "__main__":
    sys.exit(main())
