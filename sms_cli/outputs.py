"""Files sms writes, checked before a command starts work, and files it reads back.

A command checks every path it will write (:class:`Output`) before it computes anything, so a
mistaken path costs nothing and leaves nothing behind. :func:`from_os_error` turns a file-system
failure that still happens (a disk that fills, a permission changed meanwhile) into the error
contract: exit 2 with the path and the reason, or exit 3 when the disk is full.
:func:`read_json_file` reads back a JSON file sms wrote (results.json, a baseline) with the line
of any damage.
"""

from __future__ import annotations

import errno
import json
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from sms_cli.errors import EXIT_NUMERICAL, InputError, Location, Problem, SmsError


class DiskFull(SmsError):
    """The disk (or the user's quota) is full (exit 3, documented as "the disk is full")."""

    exit_code = EXIT_NUMERICAL


def _fail(path: Path, message: str, hint: str) -> InputError:
    return InputError(problems=[Problem(message, Location(path), hint=hint)])


def _nearest_existing(path: Path) -> Path:
    for p in (path, *path.parents):
        if p.exists():
            return p
    return Path(".")


def _probe(folder: Path, target: Path, what: str) -> None:
    """Create and remove a file in ``folder``: the only test of writability that also holds for
    root, read-only mounts and pseudo file systems."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".sms-probe-", dir=folder)
    except OSError as exc:
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise from_os_error(OSError(exc.errno, exc.strerror, os.fspath(target))) from None
        reason = {errno.EACCES: f"you may not write in {folder} (permission denied)",
                  errno.EPERM: f"you may not write in {folder}",
                  errno.EROFS: f"{folder} is on a read-only file system"}.get(exc.errno, f"files cannot be created in {folder}")
        raise _fail(target, f"cannot write the {what}: {reason}", "choose a folder you can write to") from None
    os.close(fd)
    os.unlink(probe)


def check_output_file(path: Path | str, what: str, example: str = "") -> Path:
    """``path`` can be written as a file (InputError, or DiskFull, saying why not)."""
    p = Path(path)
    if p.is_dir():
        raise _fail(p, f"is a folder, but the {what} must be a file",
                    f"name a file, e.g. {p / example}" if example else "name a file inside that folder")
    if p.exists() and not p.is_file():
        raise _fail(p, f"is not an ordinary file (a device, pipe or socket); the {what} would replace it",
                    "name an ordinary file")
    folder = _nearest_existing(p.parent)
    if not folder.is_dir():
        raise _fail(p, f"cannot write the {what} here: {folder} is a file, not a folder",
                    f"choose a path that is not under the file {folder}")
    _probe(folder, p, what)
    return p


def check_output_dir(path: Path | str, what: str) -> Path:
    """``path`` is a folder, or one can be made there, and it can be written (InputError, DiskFull)."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise _fail(p, f"is a file, but the {what} must be a folder", "name a folder (it is created if needed), or move the file away")
    folder = _nearest_existing(p)
    if not folder.is_dir():
        raise _fail(p, f"cannot create the {what} here: {folder} is a file, not a folder",
                    f"choose a path that is not under the file {folder}")
    _probe(folder, p, what)
    return p


@dataclass(frozen=True)
class Output:
    """A path a command will write: a file (``example`` names one, for the hint) or a folder."""

    path: Path
    what: str
    folder: bool = False
    example: str = ""

    def check(self) -> None:
        if self.folder:
            check_output_dir(self.path, self.what)
        else:
            check_output_file(self.path, self.what, self.example)


_PART = re.compile(r"^\.(.+)\.[^.]+\.part$")  # results.atomic_path's temporary names


def _target(name: str | None) -> Path | None:
    if not name:
        return None
    p = Path(os.fsdecode(name))
    m = _PART.match(p.name)
    return p.with_name(m.group(1)) if m else p


_HINTS = {
    errno.EACCES: "choose a path you may write to, or change its permissions",
    errno.EPERM: "choose a path you may write to, or change its permissions",
    errno.EROFS: "choose a path on a writable disk",
    errno.EISDIR: "name a file, not a folder",
    errno.ENOTDIR: "a part of the path is a file, not a folder: choose another path",
    errno.ENOENT: "check that the path exists",
    errno.EEXIST: "a file is in the way: move it, or choose another path",
}


def from_os_error(exc: OSError, outputs: Sequence[Output] = ()) -> SmsError | None:
    """The contract's error for a file-system failure (None when ``exc`` is not one: no errno).

    Names the file the failure is about (the target of a rename, not its temporary), else the
    command's only output."""
    if exc.errno is None:
        return None
    path = _target(exc.filename2) or _target(exc.filename)
    if path is None and len(outputs) == 1:
        path = outputs[0].path
    loc = Location(path) if path is not None else None
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        what = "the disk is full" if exc.errno == errno.ENOSPC else "the disk quota is exceeded"
        return DiskFull(problems=[Problem(f"cannot write: {what}", loc,
                                          hint="free some space on that disk, or write elsewhere (-o)")])
    reason = (exc.strerror or os.strerror(exc.errno)).lower()
    return InputError(problems=[Problem(reason, loc, hint=_HINTS.get(exc.errno, "check the path and try again"))])


def read_json_file(path: Path, what: str, fix: str) -> tuple[Any, bytes]:
    """(data, raw bytes) of a JSON file sms wrote; InputError with the line of any damage."""
    if path.is_dir():
        raise _fail(path, f"is a folder, not the {what}", fix)
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise InputError(problems=[Problem(f"not text (byte 0x{raw[exc.start]:02x} is not UTF-8): the {what} is damaged",
                                           Location(path, line, col), hint=fix)]) from None
    try:
        return json.loads(text), raw
    except json.JSONDecodeError as exc:
        raise InputError(problems=[Problem(f"not JSON: {exc.msg}: the {what} is damaged",
                                           Location(path, exc.lineno, exc.colno), hint=fix)]) from None
    except RecursionError:
        raise InputError(problems=[Problem(f"nested too deeply: the {what} is damaged",
                                           Location(path), hint=fix)]) from None


def key_line(raw: bytes, key: str) -> int:
    """The line where ``"key":`` first appears in a JSON file (0 when it does not): sms writes
    one key a line, so this places a finding about a key's value."""
    m = re.search(re.escape(json.dumps(key).encode("utf-8")) + rb"\s*:", raw)
    return raw.count(b"\n", 0, m.start()) + 1 if m else 0


def kind_of(value: Any) -> str:
    """What a JSON value is, in words (for 'is X, not a mapping' messages)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a flag"
    return {dict: "a mapping", list: "a list", str: "text"}.get(type(value), "a number")
