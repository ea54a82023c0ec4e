"""The stages ``sms run`` knows: when each runs, what it needs, and how to call it.

Order: compile → budget → analyze → synthesize → simulate. A stage runs when its mission section
is present (compile: when the mission has a robot). Stage modules are imported only when their
stage runs, so a stage that has not landed yet is reported, not fatal.
"""

from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from sms_cli.errors import InputError, Problem


@dataclass(frozen=True)
class Stage:
    name: str                 # CLI name
    section: str              # results.json section it writes
    mission_key: str          # Mission attribute that configures it ("robot" for compile)
    module: str
    function: str
    needs: tuple[str, ...]    # stages whose failure makes this one pointless
    also: tuple[str, ...] = ()  # other Mission attributes that configure it (simulate: formation)

    def configured(self, mission: Any) -> bool:
        return any(getattr(mission, key, None) is not None for key in (self.mission_key, *self.also))

    def load(self) -> Callable[..., Any]:
        """The stage's entry point; InputError when the stage module is not installed."""
        try:
            mod = importlib.import_module(self.module)
        except ModuleNotFoundError as exc:
            if exc.name and self.module.startswith(exc.name):
                raise InputError(problems=[Problem(
                    f"stage '{self.name}' is not available in this sms installation (no module {self.module})",
                    field=self.mission_key, hint=f"remove the '{self.mission_key}:' section or update sms")]) from None
            raise
        fn = getattr(mod, self.function, None)
        if fn is None:
            raise InputError(f"stage '{self.name}': {self.module} has no {self.function}() (incomplete installation)")
        return fn


STAGES: list[Stage] = [
    Stage("compile", "compile", "robot", "sms_cli.run.compile_stage", "run_compile", ()),
    Stage("budget", "budget", "budget", "sms_cli.orbit.stage", "run_budget", ()),
    Stage("analyze", "analysis", "analysis", "sms_cli.analysis.stage", "run_analysis", ("compile",)),
    Stage("synthesize", "synthesis", "synthesis", "sms_cli.synthesis.stage", "run_synthesis", ("compile",)),
    Stage("simulate", "simulate", "simulation", "sms_cli.sim.stage", "run_simulation", ("compile",), ("formation",)),
]


def call_stage(stage: Stage, fn: Callable[..., Any], loaded: Any, out: Path, progress: bool | None) -> Any:
    """Call a stage entry point ``fn(loaded, out, …)``, passing ``progress`` where it is accepted."""
    params = inspect.signature(fn).parameters
    kwargs = {"progress": progress} if "progress" in params else {}
    return fn(loaded, out, **kwargs)
