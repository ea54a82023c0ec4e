"""Corpus check: which URDFs of a folder Pinocchio loads, which have a usable mass matrix, and
which ``sms compile`` accepts (with a minimal mission ``name: peer / robot: {urdf: …}``).

For each ``*.urdf`` below the given paths (folders are searched recursively):
  1. Pinocchio loads it with a free-flyer root (``pin.buildModelFromXML``; revolute and prismatic
     joints without <limit> get an unbounded one first, as SPART reads them, since urdfdom refuses them);
  2. its joint-space mass matrix at the neutral configuration is non-singular
     (smallest eigenvalue > 1e-12 × largest, the same test ``sms compile`` applies);
  3. ``sms compile`` (the real command, in-process through typer) exits 0, 2 or something else.

Prints the three counts, every refusal with its first message line, and every exit code other
than 0/2 (exit 4 is a bug). A URDF that Pinocchio loads with a non-singular mass matrix must
compile; one that does not must be refused with exit 2 and a message naming a link.

Usage:
  python benches/bench_urdf_corpus.py PATH [PATH …] [--strict] [--verbose]

To measure the public corpora named in the README, fetch them first, e.g.
  git clone https://github.com/Gepetto/example-robot-data ; python benches/bench_urdf_corpus.py example-robot-data/robots
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import pinocchio as pin  # noqa: E402
from lxml import etree  # noqa: E402
from typer.testing import CliRunner  # noqa: E402

from sms_cli.cli import app  # noqa: E402
from sms_cli.model.build import captured_c_stderr  # noqa: E402


def with_limits(xml: bytes) -> str:
    """The URDF with a <limit> added to revolute/prismatic joints that have none (SPART's convention:
    unbounded). urdfdom refuses such joints; SPART and sms read them as unbounded."""
    root = etree.fromstring(xml)
    for j in root.iter("joint"):
        if j.get("type") in ("revolute", "prismatic") and j.find("limit") is None:
            etree.SubElement(j, "limit", lower="-1e10", upper="1e10", effort="1e10", velocity="1e10")
    return etree.tostring(root, encoding="unicode")


def pinocchio_verdict(path: Path) -> tuple[bool, bool, str]:
    """(loads, mass matrix non-singular, reason) for Pinocchio alone (missing <limit>s filled first)."""
    with captured_c_stderr():
        try:
            model = pin.buildModelFromXML(with_limits(path.read_bytes()), pin.JointModelFreeFlyer())
        except Exception as exc:  # noqa: BLE001 - any failure of the reference loader
            return False, False, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    data = model.createData()
    try:
        M = pin.crba(model, data, pin.neutral(model))
        M = np.triu(M) + np.triu(M, 1).T
        eig = np.linalg.eigvalsh(M)
    except Exception as exc:  # noqa: BLE001
        return True, False, f"mass matrix: {exc}"
    ok = bool(np.all(np.isfinite(eig))) and eig.min() > 1e-12 * max(abs(eig).max(), 1.0)
    return True, ok, "" if ok else f"singular mass matrix (smallest eigenvalue {eig.min():.3g})"


def sms_verdict(path: Path, strict: bool) -> tuple[int, str, float]:
    """(exit code, first line of the message, seconds) of ``sms compile`` on a minimal mission."""
    with tempfile.TemporaryDirectory() as tmp:
        mission = Path(tmp) / "peer.yaml"
        mission.write_text(f"name: peer\nrobot: {{urdf: '{path.resolve()}'}}\n")
        args = ["compile", str(mission)] + (["--strict"] if strict else [])
        t0 = time.perf_counter()
        result = CliRunner().invoke(app, args)
        dt = time.perf_counter() - t0
    text = (result.stderr if hasattr(result, "stderr") else "") or result.output
    first = next((ln for ln in text.splitlines() if ln.startswith("error:") or ln.startswith("/") or ": " in ln), "")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    msg = " | ".join(lines[:3]) if result.exit_code else ""
    return result.exit_code, msg or first, dt


def reason(msg: str) -> str:
    """The kind of a refusal: its first problem without the file, line and names."""
    import re

    parts = [p for p in msg.split(" | ") if not p.startswith("fix:")
             and not re.search(r"problem\(s\)|: the robot's mass matrix is singular$", p)]
    first = parts[0] if parts else msg
    first = re.sub(r"^(error: )?\S+?:\d+(:\d+)?: ", "", first)
    return re.sub(r"'[^']*'", "'…'", re.sub(r"\(line \d+\)", "", first))[:90]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("paths", nargs="+", type=Path)
    ap.add_argument("--strict", action="store_true", help="run sms compile --strict (the lint)")
    ap.add_argument("--verbose", action="store_true", help="print every file's verdict")
    args = ap.parse_args()
    files: list[Path] = []
    for p in args.paths:
        files.extend(sorted(p.rglob("*.urdf")) if p.is_dir() else [p])
    if not files:
        print("no URDF found", file=sys.stderr)
        return 2
    os.environ.setdefault("SMS_NO_PROGRESS", "1")
    loads = usable = accepted = 0
    refusals: list[tuple[Path, str, str]] = []
    wrong: list[tuple[Path, str]] = []
    others: list[tuple[Path, int, str]] = []
    times: list[float] = []
    for f in files:
        p_loads, p_usable, p_why = pinocchio_verdict(f)
        code, msg, dt = sms_verdict(f, args.strict)
        times.append(dt)
        loads += p_loads
        usable += p_usable
        accepted += code == 0
        if code not in (0, 2):
            others.append((f, code, msg))
        elif code == 2:
            refusals.append((f, "usable" if p_usable else ("singular" if p_loads else "not loaded"), msg))
        if code == 0 and not p_usable:
            wrong.append((f, f"accepted although Pinocchio says: {p_why}"))
        if code != 0 and p_usable and not args.strict:
            wrong.append((f, "refused although Pinocchio loads it with a non-singular mass matrix"))
        if args.verbose:
            print(f"{code}  {f}  {msg[:160]}")
    print(f"URDFs {len(files)} · Pinocchio loads {loads} · non-singular mass matrix {usable} · "
          f"sms compile accepts {accepted}{' (--strict)' if args.strict else ''} · other exit codes {len(others)}")
    print(f"sms compile per file: median {np.median(times) * 1e3:.0f} ms, max {max(times) * 1e3:.0f} ms")
    if refusals:
        print("\nrefused (exit 2):")
        for f, kind, msg in refusals:
            print(f"  [{kind}] {f}\n      {msg[:300]}")
        reasons = Counter(reason(msg) for _, _, msg in refusals)
        print("\nreasons (first message, truncated):")
        for why, n in reasons.most_common():
            print(f"  {n:3d}  {why}")
    if others:
        print("\nexit codes other than 0/2 (4 is a bug):")
        for f, code, msg in others:
            print(f"  exit {code}  {f}\n      {msg[:300]}")
    if wrong:
        print("\ndisagreements with Pinocchio:")
        for f, why in wrong:
            print(f"  {f}: {why}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
