"""What travels between the campaign client and its workers: one run to do, and what it gave.

Both are plain, picklable data (no models, no open files), so a run can go to a child process or
a Dask worker on another machine and come back.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

#: Statuses of an attempt. The first three finish a run (``--resume`` does not redo them): ``ok`` ran
#: its stages (its requirements may still fail), ``invalid`` is a draw the mission loader or
#: compiler refuses (a non-physical sample, with the reason), ``diverged`` a simulation that
#: diverged (a result, not a fault). The others cost one attempt and are retried.
FINISHED = ("ok", "invalid", "diverged")
RETRIED = ("failed", "timeout", "crashed", "lost")


@dataclass(frozen=True)
class RunTask:
    """One run of a campaign: the mission tree (``extends`` resolved) with the samples to apply.

    ``samples`` maps each dispersion name to its dotted path and the SI value to write there;
    ``base_dir`` is where the mission's relative paths (its URDF) resolve; ``stages`` the stages
    to execute in order (``simulate``, ``analyze``, ``synthesize``); ``gains_yaml`` the gains.yaml
    text a simulation without its own ``synthesize`` stage reads (the nominal mission's gains)."""

    run: int
    tree: dict[str, Any]
    base_dir: str
    name: str
    stages: tuple[str, ...]
    samples: dict[str, tuple[str, Any]]
    attempt: int = 1
    timeout_s: float | None = None
    gains_yaml: str | None = None
    variants: tuple[tuple[str, dict[str, Any]], ...] = ()


@dataclass
class RunOutcome:
    """What one attempt gave. ``metrics``: every number of the run's results sections, by dotted
    key (``simulate.overall.settling_time_s``); ``params``: the value of each dispersion read back
    from the built model (SI); ``requirements``: the mission's requirements, name → passed (None:
    the metric is missing); ``exit_status``: what ``sms run`` would have exited with."""

    run: int
    status: str
    exit_status: int
    message: str = ""
    metrics: dict[str, float] = field(default_factory=dict)
    params: dict[str, float] = field(default_factory=dict)
    requirements: dict[str, bool | None] = field(default_factory=dict)
    wall_s: float = 0.0
    worker: str = ""
    attempt: int = 1

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def one_line(exc: BaseException) -> str:
    """An exception as one line for the manifest: the first problem of an sms error (field and
    message), else the first line of its text."""
    problems = getattr(exc, "problems", None)
    if problems:
        p = problems[0]
        return " ".join(filter(None, [getattr(p, "field", None) and f"{p.field}:", p.message]))
    text = str(exc).strip().splitlines()
    return text[0] if text else ""
