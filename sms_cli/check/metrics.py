"""Dotted metric paths into results.json: ``simulate.phases[slew].settling_time_s``.

Syntax: keys separated by dots; a list item by index (``phases[0]`` or ``phases.0``) or by the
value of its ``name`` field (``phases[slew]``, ``scenarios[hipparcos_geo]``). Numeric leaves of a
results tree can be listed with :func:`numeric_leaves` (used to write baselines).
"""

from __future__ import annotations

import difflib
import math
import re
from typing import Any, Iterator

from sms_cli.outputs import kind_of

_TOKEN = re.compile(r"([^.\[\]]+)|\[([^\]]*)\]")


class MetricMissing(LookupError):
    """The path does not lead to a value; the message says where it stops and what exists there."""


def section(results: dict[str, Any], name: str) -> dict[str, Any]:
    """A section of results.json, or {} when it is absent or damaged (not a mapping)."""
    value = results.get(name)
    return value if isinstance(value, dict) else {}


def damaged_sections(results: dict[str, Any]) -> dict[str, str]:
    """Section → what is wrong with it, for every section that is not a mapping (each stage writes one)."""
    return {k: f"section '{k}' is {kind_of(v)}, not a mapping" for k, v in results.items() if not isinstance(v, dict)}


def split_path(path: str) -> list[str | int]:
    """``a.b[0].c[slew]`` → ``['a', 'b', 0, 'c', 'slew']`` (digits become indices)."""
    out: list[str | int] = []
    for key, item in _TOKEN.findall(path):
        tok = key if key else item
        out.append(int(tok) if re.fullmatch(r"-?\d+", tok) else tok)
    return out


def join_path(parts: list[str | int]) -> str:
    s = ""
    for p in parts:
        if isinstance(p, int):
            s += f"[{p}]"
        else:
            s += ("." if s else "") + p
    return s


def resolve(tree: Any, path: str) -> Any:
    """The value at ``path``; raises :class:`MetricMissing` with what is available where it stops."""
    node = tree
    walked: list[str | int] = []
    for part in split_path(path):
        where = join_path(walked) or "results.json"
        if isinstance(node, dict):
            if isinstance(part, int) or part not in node:
                keys = [str(k) for k in node]
                close = difflib.get_close_matches(str(part), keys, n=1, cutoff=0.6)
                hint = f"did you mean '{close[0]}'?" if close else "available: " + ", ".join(keys[:25]) + (
                    " …" if len(keys) > 25 else "")
                if not walked:
                    raise MetricMissing(f"results.json has no section '{part}' (did its stage run?); {hint}")
                raise MetricMissing(f"no key '{part}' under {where}; {hint}")
            node = node[part]
        elif isinstance(node, list):
            if isinstance(part, int):
                if not -len(node) <= part < len(node):
                    raise MetricMissing(f"{where} has {len(node)} items; index {part} is out of range")
                node = node[part]
            else:
                named = [x for x in node if isinstance(x, dict) and str(x.get("name")) == part]
                if not named:
                    names = [str(x.get("name")) for x in node if isinstance(x, dict) and "name" in x]
                    raise MetricMissing(f"no item named '{part}' in {where}" + (
                        f"; names: {', '.join(names)}" if names else f" (a list of {len(node)}: use an index [i])"))
                node = named[0]
        else:
            raise MetricMissing(f"{where} is a value ({node!r}), it has no '{part}'")
        walked.append(part)
    return node


def as_number(value: Any) -> float | bool:
    """A metric value as a number (or bool); raises ValueError naming what it is instead."""
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        return float(value)
    if value is None:
        raise ValueError("the metric is null (not a number: NaN, undefined or not computed)")
    if isinstance(value, (list, dict)):
        kind = "list" if isinstance(value, list) else "mapping"
        raise ValueError(f"the metric is a {kind}, not a number: extend the path to one of its items")
    raise ValueError(f"the metric is text ({value!r}), not a number")


def numeric_leaves(tree: Any, prefix: str = "") -> Iterator[tuple[str, float | bool]]:
    """Every finite number and flag in a tree, with its path (lists of dicts with a ``name``
    are addressed by name, other lists by index)."""
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from numeric_leaves(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(tree, list):
        names = [x.get("name") for x in tree if isinstance(x, dict)]
        by_name = len(names) == len(tree) and all(isinstance(n, str) and n and "]" not in n and not n.lstrip("-").isdigit()
                                                   for n in names) and len(set(names)) == len(names)
        for i, v in enumerate(tree):
            tag = names[i] if by_name else i
            yield from numeric_leaves(v, f"{prefix}[{tag}]")
    elif isinstance(tree, bool):
        yield prefix, tree
    elif isinstance(tree, (int, float)) and math.isfinite(tree):
        yield prefix, float(tree)
