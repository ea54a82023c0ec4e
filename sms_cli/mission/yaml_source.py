"""YAML reading that remembers where every value came from.

``load_yaml`` returns plain Python data plus a ``SourceMap`` from key paths
(``("wheels", "array", "beta")``) to 1-based (line, column). Duplicate keys are an error
(PyYAML silently keeps the last one). Parse errors become ``InputError`` with the position.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from sms_cli.errors import InputError, Location, Problem

KeyPath = tuple[Any, ...]


@dataclass
class SourceMap:
    """Positions of the values (and keys) of one YAML document."""

    file: Path
    values: dict[KeyPath, tuple[int, int]] = field(default_factory=dict)
    keys: dict[KeyPath, tuple[int, int]] = field(default_factory=dict)
    files: dict[KeyPath, Path] = field(default_factory=dict)  # entries inherited from another file (extends:)

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


def _build(loader: yaml.SafeLoader, node: Node, path: KeyPath, smap: SourceMap) -> Any:
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
            out[key] = _build(loader, value_node, path + (key,), smap)
        return out
    if isinstance(node, SequenceNode):
        return [_build(loader, item, path + (i,), smap) for i, item in enumerate(node.value)]
    return _scalar(loader, node)


def load_yaml(path: Path | str) -> tuple[Any, SourceMap]:
    """Read one YAML document; return (data, source map). Raises InputError on any problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file", [Problem("no such file", Location(path),
                         hint="check the path (relative paths start from the current directory)")]) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(problems=[Problem(f"cannot read file: {exc}", Location(path))]) from None
    return load_yaml_text(text, path)


def load_yaml_text(text: str, path: Path | str = "<string>") -> tuple[Any, SourceMap]:
    """Like ``load_yaml`` but from a string (``path`` is only used in messages)."""
    path = Path(path)
    smap = SourceMap(path)
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            raise InputError(problems=[Problem("the file is empty", Location(path, 1, 1),
                                               hint="start from one of the files in missions/")])
        return _build(loader, node, (), smap), smap
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        loc = Location(path, mark.line + 1, mark.column + 1) if mark else Location(path)
        msg = " ".join(s for s in (exc.context, exc.problem) if s)
        raise InputError(problems=[Problem(f"YAML syntax error: {msg}", loc,
                                           hint="check indentation, colons and quotes around this line")]) from None
    except yaml.YAMLError as exc:
        raise InputError(problems=[Problem(f"YAML error: {exc}", Location(path))]) from None
    finally:
        loader.dispose()
