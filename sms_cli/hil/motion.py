"""Reading a two-spacecraft run for the HIL export: ``results.json``'s ``simulate.formation`` and the
relative-motion table it names.

``<results>/relative_motion.csv`` (written by the two-spacecraft simulation): a header row, then one
row per sample with the columns of :data:`COLUMNS` (any order, more columns allowed):
``t`` (s), for body 1 (the master) and body 2 (the other) the world position of the base frame
``p`` (m), the unit quaternion world<-base ``q`` (x, y, z, w) and the body twist ``v``, ``w`` in the
base frame (m/s, rad/s; Pinocchio's free-flyer velocity, linear first). Every problem is an
``InputError`` (exit 2) naming file:line(:column).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sms_cli.errors import InputError, Location, Problem
from sms_cli.inputs import decode_text, read_input_bytes

#: Columns of relative_motion.csv, in the order the simulation writes them.
COLUMNS = ("t",
           "p1_x", "p1_y", "p1_z", "q1_x", "q1_y", "q1_z", "q1_w",
           "p2_x", "p2_y", "p2_z", "q2_x", "q2_y", "q2_z", "q2_w",
           "v1_x", "v1_y", "v1_z", "w1_x", "w1_y", "w1_z",
           "v2_x", "v2_y", "v2_z", "w2_x", "w2_y", "w2_z")
#: Largest relative_motion.csv read (bytes): a 1 kHz, 1 h run is about 2 GB; 1 GiB is ≈ 30 min at 1 kHz.
MAX_TABLE_BYTES = 1 << 30
#: A recorded quaternion may be off unit length by this much (it is then normalised).
QUATERNION_TOL = 1e-6

_RERUN = "re-run the two-spacecraft mission into this folder: sms simulate MISSION.yaml -o {folder}"


@dataclass(frozen=True)
class Formation:
    """Names of the two spacecraft (body 1 = master, body 2 = other) and the relative-motion table."""

    master: str
    other: str
    table: Path


@dataclass
class RelativeMotion:
    """The absolute motions of both bodies, sample by sample (n samples).

    ``g1``, ``g2``: (n, 7) poses world<-base ``[x y z qx qy qz qw]`` (m, unit quaternion);
    ``V1``, ``V2``: (n, 6) body twists ``[v; ω]`` in each base frame (m/s, rad/s); ``t`` (n,) s."""

    t: np.ndarray
    g1: np.ndarray
    g2: np.ndarray
    V1: np.ndarray
    V2: np.ndarray
    path: Path

    @property
    def n(self) -> int:
        return int(self.t.size)


def _fail(message: str, where: Location, hint: str = "", field: str = "") -> InputError:
    return InputError(problems=[Problem(message, where, field, hint)])


def read_formation(results: Path) -> Formation:
    """``simulate.formation`` of a results folder; InputError when the folder, its results.json or
    the section is missing or malformed."""
    from sms_cli.outputs import key_line, kind_of, read_json_file

    results = Path(results)
    fix = _RERUN.format(folder=results)
    if not results.exists():
        raise _fail("no such results folder", Location(results), "give the folder a two-spacecraft `sms simulate -o` wrote")
    if not results.is_dir():
        raise _fail("is a file, not a results folder", Location(results), "give the folder that holds results.json")
    rj = results / "results.json"
    if not rj.is_file():
        raise _fail("no results.json: not a results folder", Location(results), fix)
    data, raw = read_json_file(rj, "results.json", fix)
    sim = data.get("simulate") if isinstance(data, dict) else None
    formation = sim.get("formation") if isinstance(sim, dict) else None
    if formation is None:
        line = key_line(raw, "simulate")
        what = "has no simulate section" if sim is None else "has a simulate section without 'formation'"
        raise _fail(f"{what}: these are not the results of a two-spacecraft simulation", Location(rj, line),
                    "the HIL export replays a formation: run a mission with two spacecraft (simulate.formation)",
                    "simulate.formation")
    where = Location(rj, key_line(raw, "formation"))
    if not isinstance(formation, dict):
        raise _fail(f"is {kind_of(formation)}, not a mapping {{master, other, relative_motion}}", where, fix,
                    "simulate.formation")
    for key in ("master", "other", "relative_motion"):
        value = formation.get(key)
        if not isinstance(value, str) or not value:
            raise _fail(f"'{key}' is {'missing' if value is None else kind_of(value)}, not a name", where, fix,
                        f"simulate.formation.{key}")
    if formation["master"] == formation["other"]:
        raise _fail(f"master and other are both '{formation['master']}'", where, fix, "simulate.formation")
    table = Path(formation["relative_motion"])
    return Formation(formation["master"], formation["other"], table if table.is_absolute() else results / table)


def _numbers(fields: list[str], line: int, path: Path, header: list[str]) -> list[float]:
    out = []
    for j, text in enumerate(fields):
        try:
            x = float(text)
        except ValueError:
            col = sum(len(f) + 1 for f in fields[:j]) + 1
            raise _fail(f"column '{header[j]}': {text.strip()[:40]!r} is not a number", Location(path, line, col),
                        "the table holds plain decimal numbers; re-run the simulation") from None
        if not np.isfinite(x):
            col = sum(len(f) + 1 for f in fields[:j]) + 1
            raise _fail(f"column '{header[j]}' is {text.strip()} (not finite): the run diverged here",
                        Location(path, line, col), "export the part of the run before the divergence, or fix the run")
        out.append(x)
    return out


def read_relative_motion(path: Path) -> RelativeMotion:
    """Parse and check ``relative_motion.csv`` (see the module docstring)."""
    path = Path(path)
    if not path.exists():
        raise _fail("no relative-motion table (results.json's simulate.formation.relative_motion names it)",
                    Location(path), _RERUN.format(folder=path.parent))
    text = decode_text(read_input_bytes(path, "relative-motion table", limit=MAX_TABLE_BYTES), path,
                       "relative-motion table")
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise _fail("the table is empty (no header row)", Location(path, 1), _RERUN.format(folder=path.parent))
    header = [h.strip() for h in lines[0].split(",")]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise _fail(f"the header lacks column(s) {', '.join(missing)}", Location(path, 1, 1),
                    "the table needs t, p1_*, q1_*, p2_*, q2_*, v1_*, w1_*, v2_*, w2_* (see sms export hil --help)")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise _fail(f"the header names column(s) {', '.join(dup)} twice", Location(path, 1, 1), "keep one of each")
    rows = []
    for i, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != len(header):
            raise _fail(f"{len(fields)} values, the header has {len(header)} columns", Location(path, i, 1),
                        "the file may be cut short: re-run the simulation")
        rows.append((i, _numbers(fields, i, path, header)))
    if not rows:
        raise _fail("the table has a header but no sample", Location(path, 2), _RERUN.format(folder=path.parent))
    lines_of = np.array([i for i, _ in rows])
    table = np.array([r for _, r in rows], dtype=float)
    cols = {name: table[:, header.index(name)] for name in COLUMNS}
    t = cols["t"]
    if t[0] < 0:
        raise _fail(f"t starts at {t[0]!r} s; the export needs t ≥ 0", Location(path, int(lines_of[0]), 1),
                    "shift the times so that the run starts at t = 0")
    back = np.nonzero(np.diff(t) <= 0)[0]
    if back.size:
        k = int(back[0]) + 1
        raise _fail(f"t = {t[k]!r} s does not increase (the row before has {t[k - 1]!r} s)",
                    Location(path, int(lines_of[k]), 1), "each row is a later sample: remove repeated or reordered rows")

    def stack(names: list[str]) -> np.ndarray:
        return np.column_stack([cols[c] for c in names])

    poses = []
    for b in ("1", "2"):
        g = stack([f"p{b}_x", f"p{b}_y", f"p{b}_z", f"q{b}_x", f"q{b}_y", f"q{b}_z", f"q{b}_w"])
        norm = np.linalg.norm(g[:, 3:], axis=1)
        bad = np.nonzero(np.abs(norm - 1.0) > QUATERNION_TOL)[0]
        if bad.size:
            k = int(bad[0])
            raise _fail(f"quaternion q{b} has norm {norm[k]:.9g}, not 1 (tolerance {QUATERNION_TOL:g})",
                        Location(path, int(lines_of[k]), 1), "the attitude must be a unit quaternion world<-base (x, y, z, w)")
        g[:, 3:] /= norm[:, None]
        poses.append(g)
    V1 = stack(["v1_x", "v1_y", "v1_z", "w1_x", "w1_y", "w1_z"])
    V2 = stack(["v2_x", "v2_y", "v2_z", "w2_x", "w2_y", "w2_z"])
    return RelativeMotion(t, poses[0], poses[1], V1, V2, path)


def load_run(results: Path) -> tuple[Formation, RelativeMotion]:
    """The formation and its relative-motion table of a results folder."""
    formation = read_formation(results)
    return formation, read_relative_motion(formation.table)


__all__ = ["COLUMNS", "Formation", "RelativeMotion", "load_run", "read_formation", "read_relative_motion"]
