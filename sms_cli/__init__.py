"""sms: mission analysis for space manipulator systems (URDF robot + YAML mission).

The Python API (``sms_cli.api``, reachable from here)::

    import sms_cli as sms

    mission = sms.load_mission("missions/pulsar_simple.yaml")
    model = sms.compile(mission)                 # SystemModel: model.total_mass, model.nx, …
    result = sms.simulate(mission)               # metrics and trace arrays; nothing written
    sms.simulate(mission, out="results/pulsar")  # the files `sms simulate -o results/pulsar` writes

Importing the package is light (the CLI's start-up): the API is imported on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from sms_cli.errors import InputError, NumericalError, SmsError

__version__ = "0.1.0"

if TYPE_CHECKING:
    from sms_cli.api import (
        AnalysisResult,
        BudgetResult,
        Check,
        IndexStats,
        LinearModel,
        LoadedMission,
        MissionLike,
        ScenarioBudget,
        SimulationResult,
        SynthesisResult,
        SystemModel,
        VariantIndices,
        analyze,
        budget,
        compile,
        load_mission,
        load_mission_dict,
        load_mission_text,
        simulate,
        synthesize,
    )

__all__ = [
    "AnalysisResult", "BudgetResult", "Check", "IndexStats", "InputError", "LinearModel", "LoadedMission",
    "MissionLike", "NumericalError", "ScenarioBudget", "SimulationResult", "SmsError", "SynthesisResult",
    "SystemModel", "VariantIndices", "__version__", "analyze", "budget", "compile", "load_mission",
    "load_mission_dict", "load_mission_text", "simulate", "synthesize",
]

_EAGER = {"InputError", "NumericalError", "SmsError", "__version__"}


def __getattr__(name: str) -> Any:
    if name in __all__ and name not in _EAGER:
        import importlib

        return getattr(importlib.import_module("sms_cli.api"), name)
    raise AttributeError(f"module 'sms_cli' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
