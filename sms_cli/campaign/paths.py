"""Dotted paths into a mission (``payloads.tile.mass``, ``simulation.phases.0.duration``).

A part is a field name, a list index, or the ``name`` of a list item. ``nominal`` reads the value
a path holds in the validated mission (SI, defaults filled in); ``write`` puts a value at the
path in the mission's data tree (the mapping the loader validates), creating the mappings the
file left to defaults. ``robot.links.<link>.<mass|com|inertia>`` reads the built model, the
URDF's value being the nominal one.
"""

from __future__ import annotations

import difflib
from typing import Any

import numpy as np
from pydantic import BaseModel


class PathError(ValueError):
    """A path that does not lead to a number: the message, and what could have been meant."""

    def __init__(self, message: str, suggestions: list[str] | None = None, at: int | None = None, hint: str = ""):
        super().__init__(message)
        self.suggestions = suggestions or []
        self.at = at  # index of the part that is wrong
        self.hint = hint

    def corrected(self, path: str) -> list[str]:
        """``path`` with the wrong part replaced by each suggestion."""
        parts = split(path)
        k = len(parts) - 1 if self.at is None else self.at
        return [".".join(parts[:k] + [s] + parts[k + 1:]) for s in self.suggestions]


def split(path: str) -> list[str]:
    return path.split(".")


def _did_you_mean(bad: str, options: list[str]) -> list[str]:
    return difflib.get_close_matches(bad, options, n=1, cutoff=0.5) or ([] if len(options) > 8 else options)


def _child(obj: Any, part: str, where: str) -> Any:
    """obj[part] for a model (field), a list (index or item name) or a mapping (key)."""
    if isinstance(obj, BaseModel):
        fields = list(type(obj).model_fields)
        if part not in fields:
            raise PathError(f"{where or 'the mission'} has no field {part!r}", _did_you_mean(part, fields))
        return getattr(obj, part)
    if isinstance(obj, (list, tuple)):
        if part.lstrip("-").isdigit():
            i = int(part)
            if not 0 <= i < len(obj):
                raise PathError(f"{where} has {len(obj)} item(s): index {i} is out of range")
            return obj[i]
        names = [getattr(x, "name", None) if not isinstance(x, dict) else x.get("name") for x in obj]
        if part in names:
            return obj[names.index(part)]
        known = [n for n in names if isinstance(n, str)]
        raise PathError(f"{where} has no item named {part!r}" + (f" (items: {', '.join(known)})" if known else ""),
                        _did_you_mean(part, known))
    if isinstance(obj, dict):
        if part not in obj:
            keys = [str(k) for k in obj]
            raise PathError(f"{where} has no key {part!r}", _did_you_mean(part, keys))
        return obj[part]
    raise PathError(f"{where} is one number (for every axis or item here), it has no part {part!r}",
                    hint=f"disperse {where} whole, or write it in the mission as a vector to disperse one component")


def _numeric(value: Any, path: str) -> float | np.ndarray:
    if isinstance(value, bool) or value is None:
        raise PathError(f"{path} holds {value!r}, not a number to disperse")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, (list, tuple)) and value and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                            for x in value):
        return np.asarray(value, dtype=float)
    raise PathError(f"{path} holds {type(value).__name__ if not isinstance(value, BaseModel) else 'a section'}, "
                    "not a number or a vector of numbers")


def is_link_path(parts: list[str]) -> bool:
    return len(parts) == 4 and parts[:2] == ["robot", "links"]


def nominal(mission: BaseModel, path: str, sm=None) -> float | np.ndarray:
    """The SI value at ``path`` in the validated mission (``robot.links`` paths: in the built model ``sm``)."""
    parts = split(path)
    if is_link_path(parts) and sm is not None:
        return link_value(sm, parts[2], parts[3])
    obj: Any = mission
    for k, part in enumerate(parts):
        try:
            obj = _child(obj, part, ".".join(parts[:k]))
        except PathError as exc:
            exc.at = k
            raise
    return _numeric(obj, path)


LINK_FIELDS = ("mass", "com", "inertia")


def link_value(sm, link: str, field: str) -> float | np.ndarray:
    """A link's mass (kg), CoM (m, link frame) or six-number inertia (kg m², about the CoM) in the built model."""
    if field not in LINK_FIELDS:
        raise PathError(f"robot.links.{link} has no field {field!r}", _did_you_mean(field, list(LINK_FIELDS)), 3)
    names = list(sm.link_frames)
    if link not in names:
        raise PathError(f"the robot has no link {link!r}", _did_you_mean(link, names), 2)
    mass, com, inertia = sm.link_inertial(link)
    return {"mass": float(mass), "com": np.asarray(com, float), "inertia": np.asarray(inertia, float)}[field]


class Lazy:
    """A value computed on first use (``write`` needs the validated mission only for some paths)."""

    def __init__(self, make):
        self._make, self._value = make, None

    def get(self):
        if self._value is None:
            self._value = self._make()
        return self._value


def write(tree: dict, path: str, value: float | np.ndarray, mission: BaseModel | Lazy) -> None:
    """Set ``path`` in the data tree to ``value`` (SI numbers), creating the mappings the file left to
    defaults. A vector component (``…bias.2``) rewrites the whole vector, from the validated mission's
    SI numbers unless the tree already holds plain numbers there."""
    parts = split(path)
    obj: Any = tree
    for k, part in enumerate(parts[:-1]):
        if isinstance(obj, list):
            obj = _child(obj, part, ".".join(parts[:k]))
            continue
        component = k + 2 == len(parts) and parts[-1].isdigit()
        if component and not _plain_numbers(obj.get(part)):
            validated = mission.get() if isinstance(mission, Lazy) else mission
            obj[part] = [float(x) for x in nominal(validated, ".".join(parts[: k + 1]))]
        obj = obj.setdefault(part, {})
    plain = [float(x) for x in value] if isinstance(value, np.ndarray) else float(value)
    if isinstance(obj, list):
        obj[int(parts[-1])] = plain
    else:
        obj[parts[-1]] = plain


def _plain_numbers(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)
