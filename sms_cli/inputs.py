"""Reading the files a user hands to sms (missions, ``extends:`` parents, URDFs) safely.

``read_input_bytes`` accepts only a regular file of at most ``MAX_INPUT_BYTES`` (16 MiB): a FIFO,
a device (``/dev/zero``), a directory, a symlink loop or a larger file is refused at once with
the path and the reason, never read (no hang, no unbounded memory). ``decode_text`` turns the
bytes into text: UTF-8 (with or without a byte-order mark) or UTF-16/UTF-32 with a byte-order
mark; an undecodable byte or a NUL character is reported as file:line:col. Both raise
``InputError`` (exit code 2).
"""

from __future__ import annotations

import codecs
import errno
import os
import stat
from pathlib import Path

from sms_cli.errors import InputError, Location, Problem

#: Largest input file sms reads (bytes): 16 MiB.
MAX_INPUT_BYTES = 16 * 1024 * 1024

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))

# longest first: a UTF-32-LE mark starts with the UTF-16-LE one
_BOMS = ((codecs.BOM_UTF32_LE, "utf-32-le", "UTF-32"), (codecs.BOM_UTF32_BE, "utf-32-be", "UTF-32"),
         (codecs.BOM_UTF8, "utf-8", "UTF-8"), (codecs.BOM_UTF16_LE, "utf-16-le", "UTF-16"),
         (codecs.BOM_UTF16_BE, "utf-16-be", "UTF-16"))


def absolute(path: Path | str) -> Path:
    """``path`` made absolute, symlinks resolved when possible (a symlink loop is left for the read to report)."""
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError):
        return Path(os.path.abspath(path))


def _refuse(path: Path, what: str, where: Location | None, reason: str, hint: str) -> InputError:
    """The error for an unreadable file: at ``where`` naming the path, else at the file itself."""
    if where is None:
        return InputError(problems=[Problem(f"{what}: {reason}", Location(path), hint=hint)])
    return InputError(problems=[Problem(f"{what} {path}: {reason}", where, hint=hint)])


def read_input_bytes(path: Path, what: str, where: Location | None = None, limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of the user's file ``path`` (a regular file of at most ``limit`` bytes, 16 MiB by default).

    ``what`` names the file in messages ("mission file", "URDF"); ``where`` is the place that named
    it (``robot.urdf:`` in a mission), else the message points at the file itself. Opens without
    blocking, so a FIFO or a device is refused, not waited on.
    """
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise _refuse(path, what, where, "no such file",
                      "check the path (a path in a mission is relative to the mission file)") from None
    except PermissionError:
        raise _refuse(path, what, where, "permission denied", "make the file readable") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise _refuse(path, what, where, "symbolic link loop", "point the link at a real file") from None
        if exc.errno == errno.EISDIR:
            raise _refuse(path, what, where, "is a directory, not a file", "give the path of a file") from None
        raise _refuse(path, what, where, f"cannot open ({exc.strerror or 'system error'})",
                      "check the path and the file") from None
    try:
        st = os.fstat(fd)
        for test, kind in _KINDS:
            if test(st.st_mode):
                raise _refuse(path, what, where, f"is {kind}, not a regular file", "give the path of a regular file")
        chunks, size = [], 0
        while size <= limit:  # at most limit + 1 bytes, whatever st_size says
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise _refuse(path, what, where, f"larger than the {limit / 2**20:g} MiB limit of input files",
                          "input files are small text files; check that this is the intended file")
        return b"".join(chunks)
    except OSError as exc:
        raise _refuse(path, what, where, f"cannot read ({exc.strerror or 'system error'})", "check the file") from None
    finally:
        os.close(fd)


def _line_col(text: str) -> tuple[int, int]:
    """1-based (line, column) of the character just after ``text``."""
    return text.count("\n") + 1, len(text) - (text.rfind("\n") + 1) + 1


def decode_text(raw: bytes, path: Path | str, what: str) -> str:
    """``raw`` as text: UTF-8 (optional byte-order mark) or UTF-16/UTF-32 with a byte-order mark.

    An undecodable byte or a NUL character raises ``InputError`` at its line and column.
    """
    codec, name, body = "utf-8", "UTF-8", raw
    for bom, c, n in _BOMS:
        if raw.startswith(bom):
            codec, name, body = c, n, raw[len(bom):]
            break
    try:
        text = body.decode(codec)
    except UnicodeDecodeError as exc:
        line, col = _line_col(body[:exc.start].decode(codec, errors="replace"))
        bad = body[exc.start:exc.end][:4].hex(" ")
        raise InputError(problems=[Problem(f"{what}: not valid {name} text (byte {bad})", Location(path, line, col),
                                           hint="save the file as UTF-8 (or UTF-16 with a byte-order mark)")]) from None
    nul = text.find("\x00")
    if nul >= 0:
        line, col = _line_col(text[:nul])
        raise InputError(problems=[Problem(f"{what}: NUL character (a binary file, or UTF-16 without a byte-order mark?)",
                                           Location(path, line, col),
                                           hint="give a text file saved as UTF-8 (or UTF-16 with a byte-order mark)")])
    return text
