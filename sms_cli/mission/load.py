"""Load a mission file: YAML → ``Mission`` with errors that name file, line, column and field.

Paths inside the mission (``robot.urdf``) are resolved relative to the mission file.
"""

from __future__ import annotations

import difflib
import os
import re
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from sms_cli.errors import InputError, Location, Problem
from sms_cli.inputs import absolute
from sms_cli.mission.schema import Mission
from sms_cli.mission.units import SpecError, clip
from sms_cli.mission.yaml_source import SourceMap, load_yaml, load_yaml_text


@dataclass
class LoadedMission:
    """A validated mission with where it came from."""

    mission: Mission
    path: Path
    source: SourceMap
    text: str

    def resolve(self, relative: str, key: tuple[Any, ...] = ()) -> Path:
        """A path written in the mission, relative to the folder of the file that wrote it
        (the mission itself, or the file it ``extends``); ``key`` is where it was written."""
        if "\0" in str(relative):  # no file system takes one; os calls raise ValueError on it
            raise InputError(problems=[Problem(f"the path {relative!r} holds a NUL character (\\0)",
                                               self.source.locate(key) if key else Location(self.path),
                                               ".".join(map(str, key)), "remove the \\0 escape from the quoted path")])
        p = Path(relative)
        base = self.source.file_of(key) if key else self.path
        return p if p.is_absolute() else absolute(Path(base).parent / p)  # a symlink loop is left for the read to report


def _unwrap(tp: Any) -> list[Any]:
    """Model classes reachable from a field annotation (Optional, list, dict, Annotated)."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(tp)[0])
    if origin in (typing.Union, types.UnionType, list, dict, tuple):
        out: list[Any] = []
        for a in typing.get_args(tp):
            out.extend(_unwrap(a))
        return out
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return [tp]
    return []


def _models_at(root: type[BaseModel], loc: tuple[Any, ...]) -> list[type[BaseModel]]:
    """The model classes that could be validating the mapping at ``loc``."""
    current: list[type[BaseModel]] = [root]
    for part in loc:
        if isinstance(part, int):
            continue
        nxt: list[type[BaseModel]] = []
        for m in current:
            f = m.model_fields.get(part)
            if f is not None:
                nxt.extend(_unwrap(f.annotation))
        if not nxt:
            # discriminated unions and dict values show tags in loc: skip them
            continue
        current = nxt
    return current


def _suggest(bad: str, candidates: list[str]) -> str:
    close = difflib.get_close_matches(str(bad), candidates, n=1, cutoff=0.5)
    if close and close[0] == str(bad):
        return f"'{bad}' belongs to another variant of this section; here the valid keys are the ones documented for it (sms schema)"
    if close:
        return f"did you mean '{close[0]}'?"
    return "valid keys here: " + ", ".join(sorted(candidates))


_UNION_MARKERS = ("function-", "tagged-union[", "literal[", "union[", "nullable[")
# the branch labels pydantic puts in the location of a union of plain types (float | str, float | list[float])
_BRANCH_LABEL = re.compile(r"^(?:float|int|str|bool|(?:list|dict|tuple)\[.*\])$")


def _clean_loc(loc) -> tuple:
    """Error location without pydantic's union/validator markers (the mission-file path only)."""
    return tuple(p for p in loc if not (isinstance(p, str) and (p.startswith(_UNION_MARKERS) or p.endswith("Spec")
                                                                 or _BRANCH_LABEL.match(p))))


def _is_branch_noise(kind: str) -> bool:
    """A union branch's complaint that the input is not its type (shown only when no branch says more)."""
    return kind.endswith("_type") or kind == "literal_error"


def validation_problems(exc: ValidationError, root: type[BaseModel], smap: SourceMap,
                        prefix: tuple[Any, ...] = ()) -> list[Problem]:
    """Turn pydantic errors into located problems with fixes."""
    problems: list[Problem] = []
    errors = exc.errors()
    # a union field (a law spec or a keyword such as 'from_gains') reports one error per branch:
    # when a branch recognised the input's tag, the other branches' complaints are noise
    tagged = {_clean_loc(e["loc"]) for e in errors if "tagged-union[" in "".join(map(str, e["loc"]))}
    # likewise when one branch of a union of plain types said more than "not my type"
    telling = [_clean_loc(e["loc"]) for e in errors if not _is_branch_noise(e["type"])]
    for err in errors:
        loc = _clean_loc(err["loc"])
        if err["type"] == "literal_error" and loc in tagged:
            continue
        if _is_branch_noise(err["type"]) and any(t[:len(loc)] == loc for t in telling):
            continue
        full = prefix + loc
        dotted = ".".join(str(p) for p in full) or "(top level)"
        kind = err["type"]
        if kind == "extra_forbidden":
            names: list[str] = []
            for m in _models_at(root, loc[:-1]):
                names.extend(f.alias or n for n, f in m.model_fields.items())
            problems.append(Problem(f"unknown key '{loc[-1]}'", smap.locate(full, prefer_key=True),
                                    dotted, _suggest(loc[-1], sorted(set(names)))))
        elif kind == "missing":
            problems.append(Problem("required key is missing", smap.locate(full[:-1]), dotted,
                                    f"add '{loc[-1]}:' here"))
        elif kind == "finite_number":
            problems.append(Problem("not a finite number (NaN or infinity)", smap.locate(full), dotted,
                                    "write a finite number (.nan and .inf are not accepted)"))
        else:
            cause = (err.get("ctx") or {}).get("error")
            hint = ""
            if isinstance(cause, SpecError):
                full = full + tuple(cause.at)
                dotted = ".".join(str(p) for p in full)
                hint = cause.hint
            msg = err["msg"]
            if msg.startswith("Value error, "):
                msg = msg[len("Value error, "):]
            given = err.get("input")
            if isinstance(given, (str, int, float)) and not isinstance(given, bool):
                shown = clip(given)
                if shown not in msg:
                    msg = f"{msg} (got {shown})"
            problems.append(Problem(msg, smap.locate(full), dotted, hint))
    return problems


_DISCRIMINATORS = ("law", "type", "layout", "kind")


def _merge(parent: Any, child: Any) -> Any:
    """Deep merge for ``extends``: mappings merge key by key; anything else in the child replaces.
    A mapping that names another variant (a different ``law:``/``type:``/``layout:``/``kind:``)
    replaces the inherited one instead of merging into it."""
    if isinstance(parent, dict) and isinstance(child, dict):
        if any(k in parent and k in child and parent[k] != child[k] for k in _DISCRIMINATORS):
            return child
        out = dict(parent)
        for k, v in child.items():
            out[k] = _merge(parent[k], v) if k in parent else v
        return out
    return child


def _load_tree(path: Path, chain: tuple[Path, ...] = (), named_at=None) -> tuple[dict, SourceMap]:
    """A mission file's data with its ``extends`` chain applied (parents first); ``named_at`` is
    the ``extends:`` that named this file."""
    data, smap = load_yaml(path, named_at, "extends" if named_at else "mission file")
    return _extend(path, data, smap, chain)


def _extend(path: Path, data: Any, smap: SourceMap, chain: tuple[Path, ...] = ()) -> tuple[dict, SourceMap]:
    """A mission's data (read from ``path``, or written as if it were) with its ``extends`` chain applied."""
    if not isinstance(data, dict):
        raise InputError(problems=[Problem("a mission file is a mapping (key: value) at the top level",
                                           smap.locate(()), hint="start from one of the files in missions/")])
    data = dict(data)  # the caller's mapping (load_mission_dict) keeps its 'extends'
    parent_ref = data.pop("extends", None)
    if parent_ref is None:
        return data, smap
    where = smap.locate(("extends",))
    if not isinstance(parent_ref, str):
        raise InputError(problems=[Problem("extends: expected the path of another mission file", where, "extends")])
    if "\0" in parent_ref:
        raise InputError(problems=[Problem(f"the path {parent_ref!r} holds a NUL character (\\0)", where, "extends",
                                           "remove the \\0 escape from the quoted path")])
    parent_path = absolute(path.parent / parent_ref)
    if parent_path in chain + (absolute(path),):
        raise InputError(problems=[Problem(f"extends forms a cycle through {parent_path.name}", where, "extends")])
    parent_data, parent_smap = _load_tree(parent_path, chain + (absolute(path),), where)
    smap.inherit(parent_smap)
    return _merge(parent_data, data), smap


def load_mission(path: Path | str) -> LoadedMission:
    """Read and validate a mission file (with its ``extends`` chain). Raises ``InputError``
    listing every problem found."""
    path = absolute(path) if os.path.exists(path) else Path(path)
    data, smap = _load_tree(path)
    return _validated(path, data, smap, smap.text)


def _validated(path: Path, data: dict, smap: SourceMap, text: str) -> LoadedMission:
    try:
        mission = Mission.model_validate(data)
    except ValidationError as exc:
        problems = validation_problems(exc, Mission, smap)
        raise InputError(f"{path}: {len(problems)} problem(s) in the mission file", problems) from None
    return LoadedMission(mission, path, smap, text)


def _virtual_path(base_dir: Path | str | None, name: str) -> Path:
    """Where a mission that is not a file "lives": ``name`` in ``base_dir`` (default: the current folder).
    Its relative paths resolve against that folder and its messages name that path."""
    return absolute(Path.cwd() if base_dir is None else base_dir) / name


def load_mission_text(text: str, base_dir: Path | str | None = None, name: str = "<string>") -> LoadedMission:
    """Validate a mission given as YAML text, as ``load_mission`` does a file.

    Paths inside it (``robot.urdf``, ``extends``) resolve against ``base_dir`` (default: the current
    folder); errors name ``base_dir/name`` with the line and column in ``text``. Raises ``InputError``.
    """
    path = _virtual_path(base_dir, name)
    data, smap = load_yaml_text(text, path)
    data, smap = _extend(path, data, smap)
    return _validated(path, data, smap, text)


def _claim_paths(smap: SourceMap, value: Any, at: tuple[Any, ...]) -> None:
    """Mark every key path of ``value`` as written by ``smap``'s mission (no line: position 0), so that
    an error in a value the mapping gives is not reported at the file it ``extends``."""
    smap.values[at] = (0, 0)
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for k, v in items:
        if isinstance(value, dict):
            smap.keys[at + (k,)] = (0, 0)
        _claim_paths(smap, v, at + (k,))


def load_mission_dict(data: dict[str, Any], base_dir: Path | str | None = None, name: str = "<dict>") -> LoadedMission:
    """Validate a mission given as a mapping (what ``yaml.safe_load`` of a mission file returns).

    Paths inside it resolve against ``base_dir`` (default: the current folder); errors name the
    field path (``simulation.phases.0.duration``), there being no line. ``data`` is not modified.
    The mission's text (``LoadedMission.text``, stored in recordings) is ``data`` as YAML.
    Raises ``InputError``.
    """
    import yaml

    path = _virtual_path(base_dir, name)
    smap = SourceMap(path)
    _claim_paths(smap, data, ())
    tree, smap = _extend(path, data, smap)
    try:
        text = yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
    except yaml.YAMLError:  # values YAML cannot represent (numpy scalars) are refused by validation, or shown as text
        text = repr(data)
    return _validated(path, tree, smap, text)


def mission_json_schema() -> dict[str, Any]:
    """JSON Schema of mission files (for editors: yaml-language-server, VS Code); see ``json_schema``."""
    from sms_cli.mission.json_schema import mission_json_schema

    return mission_json_schema(Mission)
