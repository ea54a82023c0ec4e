"""The results folder: ``results.json`` (one section per stage) plus each stage's artifacts.

Every file is written atomically (temporary file in the same folder, fsync, rename), so an
interrupted run never leaves a half-written file behind: either the old file or the new one.
A temporary is named ``.NAME.<pid>-XXXX.part``: one left by a killed process (its PID is gone) is
removed by the next command that writes the folder, which says so.

One writer at a time: a command that writes a results folder holds an exclusive lock on its
``.sms.lock`` (``flock``) while it runs (``ResultsDir.writing``), and every write into a folder
that has one takes it for that write; another process that tries to write the folder meanwhile
gets an ``InputError`` (exit 2) naming the holder (PID, mission, command).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Iterator

from sms_cli.errors import InputError, Location, Problem

RESULTS_FILE = "results.json"
LOCK_FILE = ".sms.lock"


def default_results_dir(mission_path: Path | str) -> Path:
    """A mission's results folder when none is given: ``results/<mission file stem>`` in the current directory."""
    return Path("results") / Path(mission_path).stem
_OLD_PART_AGE_S = 3600  # a temporary without a PID in its name (older sms) is stale after an hour
_held: dict[str, int] = {}  # folders this process holds the lock of (real path → lock fd)


def _jsonable(obj: Any) -> Any:
    """Plain JSON data: numpy scalars/arrays to lists, NaN/inf to None."""
    try:
        import numpy as np  # local: keep CLI start-up light
    except ImportError:  # pragma: no cover
        np = None
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if np is not None:
        if isinstance(obj, np.ndarray):
            return _jsonable(obj.tolist())
        if isinstance(obj, np.generic):
            return _jsonable(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def pid_alive(pid: Any) -> bool:
    """Whether process ``pid`` exists (ours counts; a non-number does not)."""
    try:
        pid = int(pid)
    except (TypeError, ValueError):
        return False
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, owned by someone else
        return True
    return True


def remove_stale_parts(folder: Path) -> list[str]:
    """Remove the ``.NAME.<pid>-XXXX.part`` temporaries whose writer process is gone (and
    PID-less ones of older versions, after an hour); returns their names."""
    removed = []
    now = time.time()
    for f in sorted(Path(folder).glob(".*.part")):
        pid = f.name[:-len(".part")].rsplit(".", 1)[-1].split("-", 1)[0]
        try:
            stale = not pid_alive(pid) if pid.isdigit() else now - f.stat().st_mtime > _OLD_PART_AGE_S
            if stale:
                f.unlink()
                removed.append(f.name)
        except OSError:
            continue
    return removed


def lock_holder(folder: Path | str) -> dict[str, Any]:
    """What the lock file says about the process that holds (or last held) the folder."""
    try:
        data = json.loads((Path(folder) / LOCK_FILE).read_text(encoding="utf-8"))
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


@contextlib.contextmanager
def folder_lock(folder: Path | str, mission: str | None = None) -> Iterator[None]:
    """Hold the write lock of a results folder for the block (re-entrant: an outer holder keeps it).

    Raises InputError (exit 2) naming the folder and the holder when another process holds it.
    On taking it, removes the temporaries killed runs left (``remove_stale_parts``), saying so."""
    folder = Path(folder)
    key = os.path.realpath(folder)
    if key in _held:
        yield
        return
    folder.mkdir(parents=True, exist_ok=True)
    fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        h = lock_holder(folder)
        who = ", ".join(x for x in (f"PID {h['pid']}" if h.get("pid") else "",
                                     f"mission '{h['mission']}'" if h.get("mission") else "",
                                     f"`{h['command']}`" if h.get("command") else "") if x)
        raise InputError(problems=[Problem(
            f"this results folder is being written by another sms process ({who or 'unknown'}); "
            "two writers would mix their results", Location(folder),
            hint=f"wait for it to finish, or write elsewhere: -o {folder.parent / (folder.name + '_2')}")]) from None
    _held[key] = fd
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps({"pid": os.getpid(), "mission": mission,
                                   "command": " ".join(["sms", *sys.argv[1:]])}) + "\n").encode(), 0)
        removed = remove_stale_parts(folder)
        if removed:
            _say(f"{folder}: removed {len(removed)} temporary file(s) left by a killed run: {', '.join(removed)}")
        yield
    finally:
        os.close(_held.pop(key))


@contextlib.contextmanager
def atomic_path(target: Path | str) -> Iterator[Path]:
    """Yield a temporary path next to ``target``; rename it onto ``target`` on success only.
    In a results folder (it has a lock file) the write first takes the folder's lock."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    lock = folder_lock(target.parent) if (target.parent / LOCK_FILE).exists() else contextlib.nullcontext()
    with lock:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.{os.getpid()}-", suffix=".part", dir=target.parent)
        os.close(fd)
        tmp_path = Path(tmp)
        try:
            yield tmp_path
            with open(tmp_path, "rb+") as fh:
                os.fsync(fh.fileno())
            os.chmod(tmp_path, 0o644)  # mkstemp creates 0600; results are ordinary files
            os.replace(tmp_path, target)
        finally:
            if tmp_path.exists():
                tmp_path.unlink()


def write_text_atomic(target: Path | str, text: str) -> Path:
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(target)


def write_bytes_atomic(target: Path | str, data: bytes) -> Path:
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)
    return Path(target)


def write_json_atomic(target: Path | str, data: Any) -> Path:
    return write_text_atomic(target, json.dumps(_jsonable(data), indent=2, sort_keys=False) + "\n")


class ResultsDir:
    """One mission's results folder. Stages add their section to results.json."""

    def __init__(self, path: Path | str):
        self.path = Path(path)

    def file(self, name: str) -> Path:
        return self.path / name

    def read(self) -> dict[str, Any]:
        """results.json as a dict ({} when absent). A ``run`` section left at state ``running`` by
        a process that is gone reads as state ``killed``. InputError (exit 2, with the line and
        column and a fix) when the file is not UTF-8, not JSON or not a JSON object."""
        from sms_cli.outputs import kind_of, read_json_file

        f = self.file(RESULTS_FILE)
        if not f.exists():
            return {}
        fix = f"re-run the mission into this folder: sms run MISSION.yaml -o {self.path}"
        data, _ = read_json_file(f, RESULTS_FILE, fix)
        if not isinstance(data, dict):
            raise InputError(problems=[Problem(f"is {kind_of(data)}, not a mapping of stage sections: {RESULTS_FILE} "
                                               "is damaged", Location(f, 1, 1), hint=fix)])
        return with_run_state(data)

    @contextlib.contextmanager
    def writing(self, mission: str, mission_file: Path | str) -> Iterator[dict[str, Any]]:
        """Hold the folder for a command of ``mission`` (``folder_lock``); yields the results kept.

        results.json is started empty (and stderr says why) when it is damaged or holds the
        results of another mission (neither its name nor its mission file is this one's): results
        of two missions are never mixed. A ``run`` left ``running`` by a killed process is reported."""
        with folder_lock(self.path, mission):
            yield self._claim(mission, mission_file)

    def _claim(self, mission: str, mission_file: Path | str) -> dict[str, Any]:
        f = self.file(RESULTS_FILE)
        fresh = False
        try:
            current = self.read()
        except InputError as exc:
            _say(f"{f}: {exc.problems[0].message}; starting it afresh")
            current, fresh = {}, True
        run = current.get("run") if isinstance(current.get("run"), dict) else {}
        if run.get("state") == "killed":
            stage = next((s.get("name") for s in run.get("stages", [])[::-1]
                          if isinstance(s, dict) and s.get("status") != "not configured"), None)
            _say(f"{f}: the previous run ({run.get('command') or 'sms run'}) was killed"
                 + (f" after stage '{stage}'" if stage else "") + "; its results are incomplete")
        other = _other_mission(current, mission, mission_file)
        if other:
            _say(f"{self.path}: it holds the results of another mission ({other}); starting results.json "
                 f"afresh for '{mission}' (files of the other mission that this one does not rewrite stay)")
            fresh = True
        if fresh:
            current = {}
            write_json_atomic(f, current)
        return current

    def update(self, section: str, data: Any) -> Path:
        """Replace one stage's section of results.json (atomically), under the folder's lock."""
        with folder_lock(self.path):
            current = self.read()
            current[section] = _jsonable(data)
            return write_json_atomic(self.file(RESULTS_FILE), current)


def with_run_state(data: dict[str, Any]) -> dict[str, Any]:
    """Results whose ``run`` section, left at state ``running`` by a process that is gone, reads ``killed``."""
    run = data.get("run")
    if isinstance(run, dict) and run.get("state") == "running" and not pid_alive(run.get("pid")):
        data = {**data, "run": {**run, "state": "killed"}}
    return data


def _other_mission(results: dict[str, Any], name: str, mission_file: Path | str) -> str:
    """Describe the mission ``results`` belong to when it is not this one ('' when it is, or unknown)."""
    names, files = set(), set()
    for section in ("run", "compile", "simulate"):
        s = results.get(section)
        if isinstance(s, dict):
            n = s.get("mission") if section != "compile" else s.get("name")
            if isinstance(n, str) and n:
                names.add(n)
            if isinstance(s.get("mission_file"), str) and s["mission_file"]:
                files.add(os.path.realpath(s["mission_file"]))
    if not (names or files) or name in names or os.path.realpath(mission_file) in files:
        return ""
    return ", ".join([f"'{n}'" for n in sorted(names)] + sorted(files))
