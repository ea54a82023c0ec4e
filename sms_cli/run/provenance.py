"""Provenance of a run: mission and URDF hashes, package versions, date (``run`` section).

The date is ``SOURCE_DATE_EPOCH`` when set (reproducible builds), else the current UTC time to
the second. Versions come from package metadata (no heavy imports).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import os
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

PACKAGES = ("sms-cli", "pin", "numpy", "scipy", "cvxpy", "clarabel", "mcap", "protobuf", "foxglove-schemas-protobuf", "pydantic", "matplotlib", "jinja2")


def sha256_file(path: Path) -> str | None:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for p in PACKAGES:
        try:
            out[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            continue
    return out


def run_date() -> str:
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    when = dt.datetime.fromtimestamp(int(epoch), dt.timezone.utc) if epoch and epoch.isdigit() else dt.datetime.now(dt.timezone.utc)
    return when.replace(microsecond=0).isoformat().replace("+00:00", "Z")


def provenance(loaded, command: str = "") -> dict[str, Any]:
    """What produced these results: files (with sha256), versions, date, command line."""
    m = loaded.mission
    files = {"mission": {"path": str(loaded.path), "sha256": sha256_file(loaded.path)}}
    inherited = {str(f) for f in (getattr(loaded.source, "files", {}) or {}).values()} - {str(loaded.path)}
    for k, f in enumerate(sorted(inherited)):
        files[f"extends_{k}"] = {"path": f, "sha256": sha256_file(Path(f))}
    if m.robot is not None:
        urdf = loaded.resolve(m.robot.urdf, ("robot", "urdf"))
        files["urdf"] = {"path": str(urdf), "sha256": sha256_file(urdf)}
    return {
        "mission": m.name, "description": m.description.strip(), "mission_file": str(loaded.path),
        "mission_sha256": files["mission"]["sha256"], "files": files, "date": run_date(),
        "versions": versions(), "command": command,
        "platform": f"{platform.system()} {platform.machine()}",
    }
