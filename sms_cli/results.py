"""The results folder: ``results.json`` (one section per stage) plus each stage's artifacts.

Every file is written atomically (temporary file in the same folder, fsync, rename), so an
interrupted run never leaves a half-written file behind: either the old file or the new one.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

RESULTS_FILE = "results.json"


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


@contextlib.contextmanager
def atomic_path(target: Path | str) -> Iterator[Path]:
    """Yield a temporary path next to ``target``; rename it onto ``target`` on success only."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
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
        f = self.file(RESULTS_FILE)
        if not f.exists():
            return {}
        return json.loads(f.read_text(encoding="utf-8"))

    def update(self, section: str, data: Any) -> Path:
        """Replace one stage's section of results.json (atomically)."""
        current = self.read()
        current[section] = _jsonable(data)
        return write_json_atomic(self.file(RESULTS_FILE), current)
