"""YAML reading that remembers where every value came from.

``load_yaml`` returns plain Python data plus a ``SourceMap`` from key paths
(``("wheels", "array", "beta")``) to 1-based (line, column). Duplicate keys are an error
(PyYAML silently keeps the last one). Parse errors become ``InputError`` with the position.

Numbers: ``1e2``, ``1E5``, ``-1e-3`` are floats (YAML 1.2; YAML 1.1 reads them as strings).
Bounds: files go through ``sms_cli.inputs`` (regular files of at most 16 MiB, UTF-8 or UTF-16/32
with a byte-order mark), nesting is at most ``MAX_DEPTH`` levels and aliases may repeat at most
``MAX_ALIAS_NODES`` nodes in all (an "alias bomb" is refused before it grows).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import re

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from sms_cli.errors import InputError, Location, Problem
from sms_cli.inputs import decode_text, read_input_bytes

KeyPath = tuple[Any, ...]

#: Deepest nesting of sequences and mappings in a mission file.
MAX_DEPTH = 100
#: Most nodes that aliases (``*name``) may repeat in one file, counted over every expansion.
MAX_ALIAS_NODES = 100_000


class _TooDeep(Exception):
    def __init__(self, mark):
        self.mark = mark


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 exponent floats and a bounded nesting depth (the composer recurses)."""

    depth = 0

    def compose_node(self, parent, index):
        self.depth += 1
        try:
            if self.depth > MAX_DEPTH:
                raise _TooDeep(self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


@dataclass
class SourceMap:
    """Positions of the values (and keys) of one YAML document."""

    file: Path
    values: dict[KeyPath, tuple[int, int]] = field(default_factory=dict)
    keys: dict[KeyPath, tuple[int, int]] = field(default_factory=dict)
    files: dict[KeyPath, Path] = field(default_factory=dict)  # entries inherited from another file (extends:)
    text: str = ""  # the file's text, as decoded

    def file_of(self, path: KeyPath) -> Path:
        """The file that defined the value at ``path`` (or its nearest ancestor)."""
        path = tuple(path)
        while path and path not in self.values and path not in self.keys:
            path = path[:-1]
        return self.files.get(path, self.file)

    def inherit(self, parent: "SourceMap") -> None:
        """Add the parent's positions for every path this file does not define itself."""
        for table, ptable in ((self.values, parent.values), (self.keys, parent.keys)):
            for k, pos in ptable.items():
                if k not in table:
                    table[k] = pos
                    self.files[k] = parent.files.get(k, parent.file)

    def locate(self, path: KeyPath, prefer_key: bool = False) -> Location:
        """Best location for a path: the exact value or key, else the nearest ancestor."""
        path = tuple(path)
        while True:
            table = (self.keys, self.values) if prefer_key else (self.values, self.keys)
            for t in table:
                if path in t:
                    line, col = t[path]
                    return Location(self.files.get(path, self.file), line, col)
            if not path:
                return Location(self.file)
            path = path[:-1]


def _scalar(loader: yaml.SafeLoader, node: ScalarNode) -> Any:
    return loader.construct_object(node, deep=True)


def _at(smap: SourceMap, node: Node) -> Location:
    return Location(smap.file, node.start_mark.line + 1, node.start_mark.column + 1)


class _Budget:
    """Nodes already built (by id) and how many repeats aliases have cost so far."""

    def __init__(self) -> None:
        self.seen: set[int] = set()
        self.repeated = 0


def _build(loader: yaml.SafeLoader, node: Node, path: KeyPath, smap: SourceMap, budget: _Budget) -> Any:
    if id(node) in budget.seen:
        budget.repeated += 1
        if budget.repeated > MAX_ALIAS_NODES or len(path) > MAX_DEPTH:
            raise InputError(problems=[Problem(
                f"aliases expand to more than {MAX_ALIAS_NODES} repeated values (or refer to themselves)",
                _at(smap, node), ".".join(map(str, path[:3])),
                "write the values out, or use fewer nested aliases (*name)")])
    budget.seen.add(id(node))
    smap.values[path] = (node.start_mark.line + 1, node.start_mark.column + 1)
    if isinstance(node, MappingNode):
        loader.flatten_mapping(node)
        out: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            key = _scalar(loader, key_node) if isinstance(key_node, ScalarNode) else None
            if key is None and not isinstance(key_node, ScalarNode):
                raise InputError(problems=[Problem(
                    "complex mapping keys are not supported",
                    Location(smap.file, key_node.start_mark.line + 1, key_node.start_mark.column + 1))])
            if key in out:
                first = smap.keys.get(path + (key,), (0, 0))
                raise InputError(problems=[Problem(
                    f"duplicate key '{key}' (first defined at line {first[0]})",
                    Location(smap.file, key_node.start_mark.line + 1, key_node.start_mark.column + 1),
                    hint="remove one of the two entries; YAML keeps only one of them")])
            smap.keys[path + (key,)] = (key_node.start_mark.line + 1, key_node.start_mark.column + 1)
            out[key] = _build(loader, value_node, path + (key,), smap, budget)
        return out
    if isinstance(node, SequenceNode):
        return [_build(loader, item, path + (i,), smap, budget) for i, item in enumerate(node.value)]
    return _scalar(loader, node)


def load_yaml(path: Path | str, where: Location | None = None, what: str = "mission file") -> tuple[Any, SourceMap]:
    """Read one YAML document; return (data, source map). Raises InputError on any problem.
    ``where`` is the place that named the file (an ``extends:``), for messages about the file itself."""
    path = Path(path)
    text = decode_text(read_input_bytes(path, what, where), path, what)
    return load_yaml_text(text, path)


def load_yaml_text(text: str, path: Path | str = "<string>") -> tuple[Any, SourceMap]:
    """Like ``load_yaml`` but from a string (``path`` is only used in messages)."""
    path = Path(path)
    smap = SourceMap(path, text=text)
    loader = None
    try:
        loader = _Loader(text)
        node = loader.get_single_node()
        if node is None:
            raise InputError(problems=[Problem("the file is empty", Location(path, 1, 1),
                                               hint="start from one of the files in missions/")])
        return _build(loader, node, (), smap, _Budget()), smap
    except _TooDeep as exc:
        raise InputError(problems=[Problem(f"nested more than {MAX_DEPTH} levels deep",
                                           Location(path, exc.mark.line + 1, exc.mark.column + 1),
                                           hint="a mission nests a few levels; check the brackets around this line")]) from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        col = exc.position - (text.rfind("\n", 0, exc.position) + 1) + 1
        raise InputError(problems=[Problem(f"character U+{exc.character:04X} is not allowed in YAML", Location(path, line, col),
                                           hint="remove the control character (the file may be binary)")]) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        loc = Location(path, mark.line + 1, mark.column + 1) if mark else Location(path)
        msg = " ".join(s for s in (exc.context, exc.problem) if s)
        raise InputError(problems=[Problem(f"YAML syntax error: {msg}", loc,
                                           hint="check indentation, colons and quotes around this line")]) from None
    except yaml.YAMLError as exc:
        raise InputError(problems=[Problem(f"YAML error: {exc}", Location(path))]) from None
    finally:
        if loader is not None:
            loader.dispose()
