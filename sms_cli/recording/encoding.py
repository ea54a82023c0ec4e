"""Protobuf wire encoding of MCAP Message records in bulk (numba): n samples × m messages framed
in one compiled pass, the recorder's only encoding path (``McapRecorder.write_block``; a single
``write_step`` is a block of one).

Every recorded message has a fixed layout, so it is described once as a template: literal bytes
(tags, length prefixes, frame names) with slots between them. A slot is

* ``DOUBLE``: the next value of the sample's row, 8 bytes little-endian (protobuf ``double``,
  wire type I64; NaN and infinities are representable, nothing is dropped);
* ``STAMP``: the sample's time as a nested ``google.protobuf.Timestamp`` (length varint, then
  ``seconds`` and ``nanos`` as varints: the only variable-length part);
* ``LENGTH``: the varint length prefix of an enclosing sub-message that holds one ``STAMP``:
  ``param`` (its fixed bytes) plus the stamp's size, which is the same for every message of a sample.

The output of each message is an MCAP Message record (opcode, record length, channel, sequence,
log time = publish time) followed by the payload; ``offsets`` says where each starts. Protobuf
decoders read the payloads (``tests/test_recording_encoding.py`` decodes them with Google's
runtime and with ``@mcap/core`` + protobufjs in Node when available).
"""

from __future__ import annotations

import sys

import numpy as np
from numba import njit

from sms_cli.sim.compiled import JIT as _JIT

NONE, DOUBLE, STAMP, LENGTH = -1, 0, 1, 2
HEADER_BYTES = 31  # opcode u8, record length u64, channel u16, sequence u32, log time u64, publish time u64
STAMP_MAX_BYTES = 18  # length varint (1) + tag, int64 varint (≤ 10) + tag, int32 varint (≤ 5)
LENGTH_MAX_BYTES = 5

if sys.byteorder != "little":  # the DOUBLE slots copy the machine's bytes
    raise ImportError("sms recording needs a little-endian machine (protobuf doubles are little-endian)")


def varint(value: int) -> bytes:
    """Protobuf base-128 varint of a non-negative integer."""
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def tag(field: int, wire_type: int) -> bytes:
    """A field's key: (number << 3) | wire type (0 varint, 1 I64, 2 LEN)."""
    return varint((field << 3) | wire_type)


class Template:
    """One message kind: ``pieces`` is a list of (literal bytes, slot code, param) in order."""

    def __init__(self) -> None:
        self.pieces: list[tuple[bytes, int, int]] = []
        self._lit = b""

    def literal(self, data: bytes) -> "Template":
        self._lit += data
        return self

    def slot(self, code: int, param: int = 0) -> "Template":
        self.pieces.append((self._lit, code, param))
        self._lit = b""
        return self

    def double_field(self, field: int) -> "Template":
        return self.literal(tag(field, 1)).slot(DOUBLE)

    def packed_doubles(self, field: int, n: int) -> "Template":
        self.literal(tag(field, 2) + varint(8 * n))
        for _ in range(n):
            self.slot(DOUBLE)
        return self

    def done(self) -> "Template":
        self.pieces.append((self._lit, NONE, 0))
        self._lit = b""
        return self

    @property
    def n_values(self) -> int:
        return sum(1 for _, code, _ in self.pieces if code == DOUBLE)


def vector_body(n: int) -> Template:
    """The body of foxglove.Vector3 (n = 3: x, y, z) or foxglove.Quaternion (n = 4: x, y, z, w)."""
    t = Template()
    for k in range(1, n + 1):
        t.double_field(k)
    return t


def frame_transform(t: Template, field: int, parent: str, child: str) -> Template:
    """Append one foxglove.FrameTransform as field ``field`` of the message being built:
    timestamp (the sample's), parent and child frame ids, translation (3 values), rotation (4)."""
    names = tag(2, 2) + varint(len(parent.encode())) + parent.encode() + tag(3, 2) + varint(len(child.encode())) + child.encode()
    translation = tag(4, 2) + varint(27)  # 3 × (key + 8 bytes)
    rotation = tag(5, 2) + varint(36)
    fixed = len(tag(1, 2)) + len(names) + len(translation) + 27 + len(rotation) + 36  # all but the stamp
    t.literal(tag(field, 2)).slot(LENGTH, fixed)
    t.literal(tag(1, 2)).slot(STAMP)
    t.literal(names + translation)
    for k in range(1, 4):
        t.double_field(k)
    t.literal(rotation)
    for k in range(1, 5):
        t.double_field(k)
    return t


class Templates:
    """Several templates flattened for ``encode_records``: message j's pieces are
    ``piece_start[j]:piece_start[j + 1]``; piece k is ``lit[lit_start[k]:lit_start[k] + lit_len[k]]``
    then slot ``code[k]`` with ``param[k]``. Values are read in order from one row per sample."""

    def __init__(self, templates: list[Template]):
        lits, codes, params, starts = [], [], [], [0]
        for tpl in templates:
            if not tpl.pieces or tpl.pieces[-1][1] != NONE:
                raise ValueError("encoding: a template must end with done()")
            for lit, code, param in tpl.pieces:
                lits.append(lit)
                codes.append(code)
                params.append(param)
            starts.append(len(lits))
        joined = b"".join(lits)
        # A template without STAMP/LENGTH has the same bytes at the same places in every sample:
        # its payload is a gather from [literals | the sample's value bytes] (one index per byte).
        n_lit = len(joined)
        gidx: list[int] = []
        gstart, glen, vstart = [], [], []
        lit_at, value_byte = 0, 0
        for tpl in templates:
            vstart.append(value_byte)
            fixed = all(code in (NONE, DOUBLE) for _, code, _ in tpl.pieces)
            gstart.append(len(gidx) if fixed else -1)
            first = len(gidx)
            for lit, code, _ in tpl.pieces:
                if fixed:
                    gidx.extend(range(lit_at, lit_at + len(lit)))
                    if code == DOUBLE:
                        gidx.extend(range(n_lit + value_byte, n_lit + value_byte + 8))
                lit_at += len(lit)
                value_byte += 8 if code == DOUBLE else 0
            glen.append(len(gidx) - first)
        self.gidx = np.array(gidx, dtype=np.int64)
        self.gstart = np.array(gstart, dtype=np.int64)
        self.glen = np.array(glen, dtype=np.int64)
        self.vstart = np.array(vstart, dtype=np.int64)
        self.lit = np.frombuffer(joined, dtype=np.uint8).copy() if joined else np.zeros(1, np.uint8)
        self.lit_len = np.array([len(x) for x in lits], dtype=np.int64)
        self.lit_start = np.concatenate([[0], np.cumsum(self.lit_len)[:-1]]).astype(np.int64)
        self.code = np.array(codes, dtype=np.int64)
        self.param = np.array(params, dtype=np.int64)
        self.piece_start = np.array(starts, dtype=np.int64)
        self.n_messages = len(templates)
        self.n_values = int(np.count_nonzero(self.code == DOUBLE))
        self._per_sample = (len(joined) + 8 * self.n_values + STAMP_MAX_BYTES * int(np.count_nonzero(self.code == STAMP))
                            + LENGTH_MAX_BYTES * int(np.count_nonzero(self.code == LENGTH)) + HEADER_BYTES * self.n_messages)

    def capacity(self, n_samples: int) -> int:
        """Bytes enough for n samples of every message."""
        return n_samples * self._per_sample

    def encode(self, values: np.ndarray, channels: np.ndarray, seq0: int, ts: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
        """(buffer, bytes used, record offsets) of the framed records of every sample (rows of
        ``values`` (n, n_values) float64 and ``ts`` (n,) int64 ns) and message."""
        values = np.ascontiguousarray(values, dtype=np.float64)
        n = values.shape[0]
        if values.shape[1] != self.n_values:
            raise ValueError(f"encoding: {values.shape[1]} values per sample, the templates take {self.n_values}")
        out = np.empty(self.capacity(n), dtype=np.uint8)
        offsets = np.empty(n * self.n_messages, dtype=np.int64)
        raw = values.view(np.uint8).reshape(n, 8 * self.n_values)
        end = encode_records(self.lit, self.lit_start, self.lit_len, self.code, self.param, self.piece_start,
                             self.gidx, self.gstart, self.glen, self.vstart, raw, channels, seq0, ts, out, offsets)
        return out, end, offsets


@njit(**_JIT)
def _write_uint(out, pos, value, nbytes):
    for b in range(nbytes):
        out[pos + b] = (value >> (8 * b)) & 0xFF
    return pos + nbytes


@njit(**_JIT)
def _write_varint(out, pos, value):
    while value >= 0x80:
        out[pos] = (value & 0x7F) | 0x80
        value >>= 7
        pos += 1
    out[pos] = value
    return pos + 1


@njit(**_JIT)
def _varint_size(value):
    size = 1
    while value >= 0x80:
        value >>= 7
        size += 1
    return size


@njit(**_JIT)
def encode_records(lit, lit_start, lit_len, code, param, piece_start, gidx, gstart, glen, vstart, raw, channels, seq0,
                   ts, out, offsets):
    """Framed Message records for every sample (row of ``raw``, the values' bytes, and of ``ts``)
    and template; returns the bytes written. ``offsets[s · m + j]`` = start of sample s's message j;
    ``channels[j]`` its channel; sequence = seq0 + s (mod 2³²); log time = publish time = ts[s].
    Template j is a gather ``gidx[gstart[j]:gstart[j] + glen[j]]`` from [lit | row bytes] when
    ``gstart[j] ≥ 0``, else its pieces, whose values start at byte ``vstart[j]`` of the row."""
    m = piece_start.shape[0] - 1
    n_lit = lit.shape[0]
    row = raw.shape[1]
    src = np.empty(n_lit + row, dtype=np.uint8)
    for b in range(n_lit):
        src[b] = lit[b]
    pos = 0
    for s in range(raw.shape[0]):
        for b in range(row):
            src[n_lit + b] = raw[s, b]
        t = ts[s]
        sec = t // 1000000000
        nsec = t - sec * 1000000000
        stamp_body = 2 + _varint_size(sec) + _varint_size(nsec)  # keys 0x08, 0x10 and the two varints
        stamp_size = 1 + stamp_body  # with its length varint (< 128)
        seq = (seq0 + s) & 0xFFFFFFFF
        for j in range(m):
            start = pos
            offsets[s * m + j] = start
            out[pos] = 5
            pos = _write_uint(out, pos + 9, channels[j], 2)
            pos = _write_uint(out, pos, seq, 4)
            pos = _write_uint(out, pos, t, 8)
            pos = _write_uint(out, pos, t, 8)
            g0 = gstart[j]
            if g0 >= 0:
                for b in range(glen[j]):
                    out[pos + b] = src[gidx[g0 + b]]
                pos += glen[j]
                _write_uint(out, start + 1, pos - start - 9, 8)
                continue
            vb = vstart[j]
            for k in range(piece_start[j], piece_start[j + 1]):
                a = lit_start[k]
                for b in range(lit_len[k]):
                    out[pos + b] = lit[a + b]
                pos += lit_len[k]
                c = code[k]
                if c == 0:
                    for b in range(8):
                        out[pos + b] = raw[s, vb + b]
                    pos += 8
                    vb += 8
                elif c == 1:
                    out[pos] = stamp_body
                    out[pos + 1] = 0x08
                    pos = _write_varint(out, pos + 2, sec)
                    out[pos] = 0x10
                    pos = _write_varint(out, pos + 1, nsec)
                elif c == 2:
                    pos = _write_varint(out, pos, param[k] + stamp_size)
            _write_uint(out, start + 1, pos - start - 9, 8)  # record length: everything after opcode + length
    return pos


def warm_call():
    """The ``encode_records`` call of a one-sample block, for ``sms_cli.sim.compiled.warmup``
    (the argument types of ``Templates.encode``'s call)."""
    from sms_cli.sim.compiled.warmup import KernelCall

    tpl = Templates([frame_transform(Template(), 1, "world", "base").done()])
    raw = np.zeros((1, tpl.n_values)).view(np.uint8).reshape(1, -1)
    return KernelCall("sms_cli.recording.encoding:encode_records",
                      (tpl.lit, tpl.lit_start, tpl.lit_len, tpl.code, tpl.param, tpl.piece_start, tpl.gidx, tpl.gstart,
                       tpl.glen, tpl.vstart, raw,
                       np.zeros(1, dtype=np.int64), 0, np.zeros(1, dtype=np.int64), np.empty(tpl.capacity(1), np.uint8),
                       np.empty(1, dtype=np.int64)), cost=1.0)
