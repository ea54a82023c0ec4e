"""A recording whose writer dies in the middle of a write (Linux cuts a large write() short, page by page, when
the process is killed) is still an MCAP file the ``mcap`` reader opens (its seeking reader: the footer read from
the end, then a linear scan) and holds the chunks written before that write.

The oracle is the ``mcap`` package's own reader on the bytes a stream holds when one of the writer's write calls
stops after a prefix of its data, for every write call of a small recording and several prefix lengths."""

from __future__ import annotations

import io

import pytest
from mcap.reader import make_reader

from sms_cli.recording.writer import LIVE_END, ChunkedMcapWriter


PAGE = 512  # finer than Linux's 4096-byte pages: more cut points, a stronger check


class Killed(Exception):
    """The process died."""


class DyingStream(io.BytesIO):
    """A BytesIO whose ``die_at``-th write stops after its ``cut``-th page boundary (0: writes nothing), as Linux's
    write() does when the process is killed (the file offset's PAGE-byte pages, one at a time), then the process
    'dies'. ``cuts`` records each write call's possible cut lengths."""

    def __init__(self, die_at: int = 0, cut: int = 0):
        super().__init__()
        self.calls, self.die_at, self.cut, self.cuts, self.lengths = 0, die_at, cut, [], []

    def write(self, data) -> int:
        self.calls += 1
        data = bytes(data)
        o = self.tell()
        first = PAGE - o % PAGE
        self.cuts.append([0] + list(range(first, len(data), PAGE)))
        self.lengths.append(len(data))
        if self.calls == self.die_at:
            super().write(data[:self.cuts[-1][self.cut]])
            raise Killed
        return super().write(data)


def _record(stream) -> int:
    """Write a recording of 3 chunks of 40 messages (about 5 KB each, uncompressed) into ``stream``."""
    w = ChunkedMcapWriter(stream, chunk_size=4500, compression="")
    ch = w.register_channel("/x", "json", w.register_schema("x", "jsonschema", b"{}"))
    chunks = 0
    for c in range(3):
        for i in range(40):
            w.add_message(ch, (c * 40 + i) * 1_000_000, b'{"value": %d, "pad": "0123456789012345678901234"}' % i, i)
        w.flush_chunk()
        chunks += 1
    w.finish()
    return chunks


def _messages(data: bytes) -> int:
    reader = make_reader(io.BytesIO(data))
    return sum(1 for _ in reader.iter_messages(log_time_order=False))


def test_every_write_cut_short_leaves_a_readable_file():
    """Every cut of every write call but one: a write of the 46-byte end marker (new, or over the old one) that
    straddles a page boundary, cut between its two pages (a window of a few hundred nanoseconds around a write
    that comes every chunk; the writer's module docstring says so). Before, any cut inside a chunk's write (tens
    of microseconds each) left a file the reader refused."""
    whole = DyingStream()
    _record(whole)
    assert whole.calls > 5 and _messages(whole.getvalue()) == 120
    checked = 0
    for die_at in range(3, whole.calls + 1):  # after the magic and the header
        for cut in range(len(whole.cuts[die_at - 1])):
            if cut and whole.lengths[die_at - 1] <= len(LIVE_END):
                continue  # the end marker's write straddling a page, cut between its pages
            s = DyingStream(die_at, cut)
            with pytest.raises(Killed):
                _record(s)
            assert _messages(s.getvalue()) in (0, 40, 80, 120)  # raises when the file cannot be read
            checked += 1
    assert checked > 2 * whole.calls
