"""Bulk encoding of MCAP Message records from byte templates (numba): the recorder's
``write_block`` path, which turns n samples × m messages into framed records in one call.

A template is the recorder's JSON text of one message with number slots: ``%.12g`` (a float,
printed with 12 significant digits, ``null`` when not finite) or ``%d`` (a float holding an
integer value, printed as an integer: timestamps, and /tf poses pre-scaled to integer counts
of 1e-9). ``%%`` is a literal ``%``. The output is what the per-sample path writes
(``MESSAGE_HEADER`` + payload per message); ``format_g12`` agrees with C's ``%.12g`` except,
rarely, in the 12th digit (tests/test_mcap_block.py bounds how rarely).
"""

from __future__ import annotations

import math
import re

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT as _JIT

FLOAT_G12, INTEGER = 0, 1
_SLOT = re.compile(rb"%%|%\.12g|%d")
HEADER_BYTES = 31  # opcode u8, record length u64, channel u16, sequence u32, log time u64, publish time u64
MAX_NUMBER_BYTES = 24  # "-1.23456789012e-308" is 19; an int64 is at most 20
_POW10 = np.array([10.0 ** k for k in range(301)])  # exact up to 1e22, nearest double above


class Templates:
    """Several message templates compiled into flat arrays for ``encode_records``: message j's
    pieces are ``piece_start[j]:piece_start[j + 1]``; piece k is the literal
    ``lit[lit_start[k]:lit_start[k] + lit_len[k]]`` followed by a number of format ``code[k]``
    (−1: none). Numbers are read in order from one row of values per sample."""

    def __init__(self, templates: list[bytes]):
        lits, codes, starts = [], [], [0]
        for tpl in templates:
            pos, buf = 0, b""
            for m in _SLOT.finditer(tpl):
                buf += tpl[pos:m.start()]
                pos = m.end()
                if m.group() == b"%%":
                    buf += b"%"
                    continue
                lits.append(buf)
                codes.append(FLOAT_G12 if m.group() == b"%.12g" else INTEGER)
                buf = b""
            lits.append(buf + tpl[pos:])
            codes.append(-1)
            starts.append(len(lits))
        self.lit = np.frombuffer(b"".join(lits), dtype=np.uint8).copy() if lits else np.zeros(0, np.uint8)
        self.lit_len = np.array([len(x) for x in lits], dtype=np.int64)
        self.lit_start = np.concatenate([[0], np.cumsum(self.lit_len)[:-1]]).astype(np.int64)
        self.code = np.array(codes, dtype=np.int64)
        self.piece_start = np.array(starts, dtype=np.int64)
        self.n_messages = len(templates)
        self.n_values = int(np.count_nonzero(self.code >= 0))
        self.literal_bytes = int(self.lit_len.sum())

    def capacity(self, n_samples: int) -> int:
        """Bytes enough for n samples of every message."""
        return n_samples * (self.literal_bytes + MAX_NUMBER_BYTES * self.n_values + HEADER_BYTES * self.n_messages)


@njit(**_JIT)
def _write_uint(out, pos, value, nbytes):
    for k in range(nbytes):
        out[pos + k] = (value >> (8 * k)) & 0xFF
    return pos + nbytes


@njit(**_JIT)
def _write_int(out, pos, v):
    """Decimal digits of an int64."""
    if v < 0:
        out[pos] = 45  # '-'
        pos += 1
        v = -v
    n = 1
    probe = v // 10
    while probe > 0:
        n += 1
        probe //= 10
    for k in range(n - 1, -1, -1):
        out[pos + k] = 48 + v % 10
        v //= 10
    return pos + n


@njit(**_JIT)
def _shift(x, k):
    """x · 10^k without overflowing the power for subnormal x or huge k."""
    while k > 300:
        x *= 1e300
        k -= 300
    while k < -300:
        x /= 1e300
        k += 300
    return x * _POW10[k] if k >= 0 else x / _POW10[-k]


@njit(**_JIT)
def _decimal_exponent(x):
    """floor(log10(x)) for finite x > 0, from the binary exponent (off by one at worst next to a
    power of ten, which format_g12 corrects)."""
    _, e2 = math.frexp(x)  # x ∈ [2^(e2−1), 2^e2)
    e = int(math.floor((e2 - 1) * 0.30102999566398120))
    k = e + 1
    if k >= 0:
        if k <= 300 and x >= _POW10[k]:
            e = k
    elif -k <= 300 and x * _POW10[-k] >= 1.0:
        e = k
    return e


@njit(**_JIT)
def format_g12(x, out, pos):
    """Write x as C's ``%.12g`` would (``null`` when not finite); returns the new position."""
    if not math.isfinite(x):
        for c in (110, 117, 108, 108):  # null
            out[pos] = c
            pos += 1
        return pos
    if x == 0.0:
        if math.copysign(1.0, x) < 0:
            out[pos] = 45
            pos += 1
        out[pos] = 48
        return pos + 1
    if x < 0:
        out[pos] = 45
        pos += 1
        x = -x
    e = _decimal_exponent(x)
    m = _shift(x, 11 - e)
    if m < 1e11 - 0.5:  # log10 rounded up across a power of ten
        e -= 1
        m = _shift(x, 11 - e)
    mi = np.int64(np.rint(m))
    if mi >= 1000000000000:  # rounding carried into a 13th digit
        mi = np.int64(np.rint(mi / 10.0))
        e += 1
    src = pos + 8  # the 12 digits go 8 bytes ahead, then move down into place (never overlapping badly)
    for k in range(11, -1, -1):
        out[src + k] = 48 + mi % 10
        mi //= 10
    last = 11
    while last > 0 and out[src + last] == 48:
        last -= 1
    if -4 <= e < 12:  # fixed notation
        if e >= 0:
            for k in range(e + 1):
                out[pos] = out[src + k]
                pos += 1
            if last > e:
                out[pos] = 46  # '.'
                pos += 1
                for k in range(e + 1, last + 1):
                    out[pos] = out[src + k]
                    pos += 1
        else:
            out[pos] = 48
            out[pos + 1] = 46
            pos += 2
            for k in range(-e - 1):
                out[pos] = 48
                pos += 1
            for k in range(last + 1):
                out[pos] = out[src + k]
                pos += 1
        return pos
    out[pos] = out[src]
    pos += 1
    if last > 0:
        out[pos] = 46
        pos += 1
        for k in range(1, last + 1):
            out[pos] = out[src + k]
            pos += 1
    out[pos] = 101  # 'e'
    pos += 1
    if e < 0:
        out[pos] = 45
        e = -e
    else:
        out[pos] = 43  # '+'
    pos += 1
    if e < 10:
        out[pos] = 48
        pos += 1
    return _write_int(out, pos, e)


@njit(**_JIT)
def encode_records(lit, lit_start, lit_len, code, piece_start, values, channels, seq0, ts, out, offsets):
    """Framed Message records for every sample (row of ``values``/``ts``) and message template;
    returns the bytes written. ``offsets[s · m + j]`` = start of sample s's message j;
    ``channels[j]`` its channel; sequence = seq0 + s (mod 2³²); log time = publish time = ts[s]."""
    m = piece_start.shape[0] - 1
    pos = 0
    for s in range(values.shape[0]):
        vi = 0
        t = ts[s]
        seq = (seq0 + s) & 0xFFFFFFFF
        for j in range(m):
            start = pos
            offsets[s * m + j] = start
            out[pos] = 5
            pos = _write_uint(out, pos + 9, channels[j], 2)
            pos = _write_uint(out, pos, seq, 4)
            pos = _write_uint(out, pos, t, 8)
            pos = _write_uint(out, pos, t, 8)
            for k in range(piece_start[j], piece_start[j + 1]):
                a = lit_start[k]
                for b in range(lit_len[k]):
                    out[pos + b] = lit[a + b]
                pos += lit_len[k]
                c = code[k]
                if c == 0:
                    pos = format_g12(values[s, vi], out, pos)
                    vi += 1
                elif c == 1:
                    pos = _write_int(out, pos, np.int64(np.rint(values[s, vi])))
                    vi += 1
            _write_uint(out, start + 1, pos - start - 9, 8)  # record length: everything after opcode + length
    return pos


def warm_call():
    """The ``encode_records`` call of a one-sample block, for ``sms_cli.sim.compiled.warmup``
    (the argument types of ``McapRecorder.write_block``'s call)."""
    from sms_cli.sim.compiled.warmup import KernelCall

    tpl = Templates([b"%.12g %d"])
    return KernelCall("sms_cli.sim.mcap_block:encode_records",
                      (tpl.lit, tpl.lit_start, tpl.lit_len, tpl.code, tpl.piece_start, np.zeros((1, 2)),
                       np.zeros(1, dtype=np.int64), 0, np.zeros(1, dtype=np.int64), np.empty(tpl.capacity(1), np.uint8),
                       np.empty(1, dtype=np.int64)), cost=1.6)
