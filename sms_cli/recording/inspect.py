"""``sms inspect``: summarise an MCAP recording (topics, schemas, counts, time span, rates, run
status, whether another engine can replay it: ``replay_check``), find damage, and ``--repair`` a
recording that a killed run, a full disk or flipped bytes left incomplete.

A complete file is read through its summary and message indexes, and every chunk is decompressed
once to check its CRC (fast: no message is parsed). A file without a summary (a run killed while
recording: the writer's end marker has no index), without an end (killed inside a write, or the
disk filled), or with a damaged index is read record by record from the start instead (``scan``).
Times are in seconds of simulation time (log times / 1e9).

Damage is an ``InputError`` (exit 2) naming the file, the damaged chunks (byte offset, time range,
topics) and what can still be read; ``repair_recording`` rewrites what can be read into a complete,
indexed file (atomically, in place).
"""

from __future__ import annotations

import io
import mmap
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sms_cli.errors import InputError, Location, Problem

MAGIC = b"\x89MCAP0\r\n"
_HEAD = struct.Struct("<BQ")  # record opcode, content length
_MSG = struct.Struct("<HIQ")  # message: channel, sequence, log time (publish time follows)
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX = 1, 2, 3, 4, 5, 6, 7
OP_ATTACHMENT, OP_METADATA, OP_DATA_END = 9, 12, 15


def _fail(path: Path, message: str, hint: str = "") -> InputError:
    return InputError(problems=[Problem(message, Location(path), hint=hint)])


def _s(ns: int | None) -> str:
    return "?" if ns is None else f"{ns / 1e9:.6g}"


def _stream(data: bytes):
    from mcap.data_stream import ReadDataStream

    return ReadDataStream(io.BytesIO(data))


def chunk_content(chunk) -> bytes:
    """The decompressed records of a Chunk record; ValueError when it is damaged (CRC, codec)."""
    from mcap.stream_reader import get_chunk_data_stream

    try:
        stream, n = get_chunk_data_stream(chunk, validate_crc=True)
    except Exception as exc:  # noqa: BLE001 - zstd/lz4 errors, CRC mismatch: the chunk is damaged
        raise ValueError("its CRC does not match" if "crc" in str(exc).lower() else "it does not decompress") from None
    return stream.read(n)


def _inner(data: bytes):
    """(opcode, record, channel, log time, start, end) of each record inside a chunk's content."""
    from mcap.records import Channel, Schema

    pos, n = 0, len(data)
    while pos + 9 <= n:
        op, length = _HEAD.unpack_from(data, pos)
        start, end = pos + 9, pos + 9 + length
        if end > n:
            raise ValueError("a record inside it runs past its end")
        if op == OP_MESSAGE:
            cid, _, log_time = _MSG.unpack_from(data, start)
            yield op, None, cid, log_time, start, end
        elif op in (OP_SCHEMA, OP_CHANNEL):
            yield op, (Schema if op == OP_SCHEMA else Channel).read(_stream(data[start:end])), 0, 0, start, end
        pos = end


@dataclass
class Scan:
    """What a record-by-record read of a recording found (see ``scan``)."""

    size: int
    header: Any = None
    items: list = field(default_factory=list)   # ("metadata" | "attachment" | "chunk", record, content) in file order
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    spans: dict = field(default_factory=dict)   # channel id → [messages, first, last, {log times}]
    chunks: int = 0
    messages: int = 0
    last_ns: int | None = None
    damaged: list = field(default_factory=list)  # dicts: offset, start_ns, end_ns, channels, reason
    end: str = ""                                # "index" | "marker" (no summary) | "" (no end)
    stopped_at: int | None = None                # byte offset of an unreadable record (the rest is lost)
    index_damaged: bool = False

    def note(self, cid: int, t: int) -> None:
        span = self.spans.setdefault(cid, [0, t, t, set()])
        span[0] += 1
        span[1], span[2] = min(span[1], t), max(span[2], t)
        span[3].add(t)
        self.messages += 1
        self.last_ns = t if self.last_ns is None else max(self.last_ns, t)

    def topics_of(self, cids) -> list[str]:
        return sorted(self.channels[c].topic if c in self.channels else f"channel {c}" for c in cids)


def scan(path: Path) -> Scan:
    """Read a recording record by record from the start: every whole, undamaged chunk counts; a
    damaged chunk is listed and skipped; reading stops at a record that cannot be parsed."""
    from mcap.records import Attachment, Channel, Chunk, Footer, Header, MessageIndex, Metadata, Schema

    path = Path(path)
    with open(path, "rb") as f:
        size = path.stat().st_size
        mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
        try:
            return _scan(mm, size, (Attachment, Channel, Chunk, Footer, Header, MessageIndex, Metadata, Schema))
        finally:
            if size:
                mm.close()


def _scan(mm, size: int, cls) -> Scan:
    Attachment, Channel, Chunk, Footer, Header, MessageIndex, Metadata, Schema = cls
    out = Scan(size)
    pos = len(MAGIC)
    after_data = False
    last_damaged = None
    while True:
        if pos == size:
            break
        if pos + 9 > size:
            out.stopped_at = pos
            break
        op, length = _HEAD.unpack_from(mm, pos)
        start, end = pos + 9, pos + 9 + length
        if end > size:
            out.stopped_at = pos
            break
        content = mm[start:end]
        try:
            if op == OP_FOOTER:
                footer = Footer.read(_stream(content))
                out.end = "marker" if footer.summary_start == 0 else "index"
                break
            if op in (OP_SCHEMA, OP_CHANNEL):  # outside chunks: a file without messages, or the summary's copies
                record = (Schema if op == OP_SCHEMA else Channel).read(_stream(content))
                (out.schemas if op == OP_SCHEMA else out.channels).setdefault(record.id, record)
            elif after_data:
                pass  # the rest of the summary: the recording itself is before DataEnd
            elif op == OP_HEADER:
                out.header = Header.read(_stream(content))
            elif op == OP_CHUNK:
                chunk = Chunk.read(_stream(content))
                last_damaged = None
                try:
                    data = chunk_content(chunk)
                    records = list(_inner(data))
                except ValueError as exc:
                    last_damaged = {"offset": pos, "start_ns": chunk.message_start_time, "end_ns": chunk.message_end_time,
                                    "channels": set(), "reason": str(exc)}
                    out.damaged.append(last_damaged)
                else:
                    for op_in, record, cid, t, _, _ in records:
                        if op_in == OP_SCHEMA:
                            out.schemas.setdefault(record.id, record)
                        elif op_in == OP_CHANNEL:
                            out.channels.setdefault(record.id, record)
                        else:
                            out.note(cid, t)
                    out.chunks += 1
                    out.items.append(("chunk", chunk, data))
            elif op == OP_MESSAGE_INDEX and last_damaged is not None:
                last_damaged["channels"].add(MessageIndex.read(_stream(content)).channel_id)
            elif op == OP_METADATA:
                out.items.append(("metadata", Metadata.read(_stream(content)), None))
            elif op == OP_ATTACHMENT:
                out.items.append(("attachment", Attachment.read(_stream(content)), None))
            elif op == OP_DATA_END:
                after_data = True
        except Exception:  # noqa: BLE001 - a record that does not parse: the rest cannot be trusted
            if after_data:
                out.index_damaged = True
            else:
                out.stopped_at = pos
            break
        pos = end
    return out


def verify_chunks(f, summary) -> list[dict]:
    """The damaged chunks of an indexed recording (each decompressed once, its CRC checked)."""
    from mcap.records import Chunk

    damaged = []
    for ci in summary.chunk_indexes:
        f.seek(ci.chunk_start_offset)
        raw = f.read(ci.chunk_length)
        try:
            op, length = _HEAD.unpack_from(raw, 0)
            if op != OP_CHUNK or length + 9 != len(raw):
                raise ValueError("its record header is damaged")
            chunk = Chunk.read(_stream(raw[9:]))
            if chunk.compression != ci.compression or chunk.uncompressed_size != ci.uncompressed_size:
                raise ValueError("its record header is damaged")
            chunk_content(chunk)
        except ValueError as exc:
            reason = str(exc)
        except Exception:  # noqa: BLE001 - an unparseable chunk record
            reason = "its record header is damaged"
        else:
            continue
        lost = 0
        for offset in ci.message_index_offsets.values():  # entries of 16 bytes after a 15-byte head
            f.seek(offset)
            head = f.read(15)
            lost += struct.unpack_from("<I", head, 11)[0] // 16 if len(head) == 15 and head[0] == OP_MESSAGE_INDEX else 0
        damaged.append({"offset": ci.chunk_start_offset, "start_ns": ci.message_start_time, "end_ns": ci.message_end_time,
                        "channels": set(ci.message_index_offsets), "reason": reason, "messages": lost})
    return damaged


def _damage_text(path: Path, damaged: list[dict], topics_of, readable: str) -> InputError:
    parts = [f"chunk at byte {d['offset']} (t = {_s(d['start_ns'])} – {_s(d['end_ns'])} s; "
             f"{', '.join(topics_of(d['channels'])) or 'topics unknown'}): {d['reason']}" for d in damaged[:5]]
    more = f"; and {len(damaged) - 5} more" if len(damaged) > 5 else ""
    return _fail(path, f"damaged recording: {len(damaged)} chunk(s) cannot be read, their messages are lost: "
                       + "; ".join(parts) + more + f". Still readable: {readable}",
                 f"run `sms inspect --repair {path}` to rewrite the readable part into a complete file")


def _channel_spans(f, summary) -> dict[int, list[int]] | None:
    """channel id → [messages, first log time, last log time, {distinct log times}] from the
    message indexes, or None when the file has none."""
    from mcap.data_stream import ReadDataStream
    from mcap.records import MessageIndex

    spans: dict[int, list[int]] = {}
    for chunk_index in summary.chunk_indexes:
        if not chunk_index.message_index_offsets:
            return None
        for cid, offset in chunk_index.message_index_offsets.items():
            f.seek(offset)
            head = f.read(9)
            if len(head) != 9 or head[0] != OP_MESSAGE_INDEX:
                return None
            index = MessageIndex.read(ReadDataStream(io.BytesIO(f.read(struct.unpack("<Q", head[1:])[0]))))
            if not index.records:
                continue
            times = [t for t, _ in index.records]
            span = spans.setdefault(cid, [0, min(times), max(times), set()])
            span[0] += len(times)
            span[1] = min(span[1], min(times))
            span[2] = max(span[2], max(times))
            span[3].update(times)
    return spans


def _readable(sc: Scan) -> str:
    return (f"{sc.messages} messages ({sc.chunks} whole chunks"
            + (f", up to t = {_s(sc.last_ns)} s)" if sc.last_ns is not None else ")"))


def _scan_problem(path: Path, sc: Scan, ends_with_magic: bool) -> InputError | None:
    """The InputError for what a scan found wrong (None: readable, at most without an index)."""
    fix = f"run `sms inspect --repair {path}` to rewrite the readable part into a complete file"
    if sc.damaged:
        return _damage_text(path, sc.damaged, sc.topics_of, _readable(sc) + (
            f" (nothing after byte {sc.stopped_at} can be read)" if sc.stopped_at is not None else ""))
    if sc.index_damaged:
        return _fail(path, f"damaged recording: its index (the summary at the end) cannot be read; {_readable(sc)} "
                           "are readable", fix)
    if sc.stopped_at is not None and ends_with_magic:
        return _fail(path, f"damaged recording: the record at byte {sc.stopped_at} cannot be read, nor anything after "
                           f"it; {_readable(sc)} are readable before it", fix)
    if not sc.end:
        return _fail(path, f"unfinished recording: it has no end, so the run was killed (or its disk filled) at about "
                           f"t = {_s(sc.last_ns)} s; {_readable(sc)} are readable", fix)
    return None


def inspect_recording(path: str | Path) -> dict[str, Any]:
    """Summary of an MCAP file as a JSON-able dict (see ``format_inspection``); InputError when
    it is not a recording, has no end, or is damaged (the message says what is still readable)."""
    from mcap.reader import make_reader

    path = Path(path)
    if not path.is_file():
        raise _fail(path, "no such recording file", "give the path of an .mcap file written by `sms simulate`")
    size = path.stat().st_size
    with open(path, "rb") as f:
        if f.read(8) != MAGIC:
            raise _fail(path, "not an MCAP file (its first bytes are not the MCAP magic)", "give the .mcap file written by `sms simulate`")
        f.seek(0)
        try:
            reader = make_reader(f)
            header = reader.get_header()
            summary = reader.get_summary()
            spans = None if summary is None or summary.statistics is None else _channel_spans(f, summary)
        except Exception:  # noqa: BLE001 - any parse failure: no end, or a damaged index
            summary, spans = None, None
        note = ""
        if spans is not None:
            channels, schemas = summary.channels, summary.schemas
            damaged = verify_chunks(f, summary)
            if damaged:
                n, lost = len(summary.chunk_indexes), sum(d["messages"] for d in damaged)
                raise _damage_text(path, damaged, lambda cids: sorted(channels[c].topic for c in cids if c in channels),
                                   f"{summary.statistics.message_count - lost} messages in the other {n - len(damaged)} "
                                   f"of {n} chunks")
            stats_chunks = summary.statistics.chunk_count
            compression = sorted({ci.compression or "none" for ci in summary.chunk_indexes})
            f.seek(0)
            metadata = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
            attachments = [a.name for a in summary.attachment_indexes]
            f.seek(0)
            events = [m.data for _, _, m in make_reader(f).iter_messages(topics=["/events"])]
            if "repair" in metadata:
                r = metadata["repair"]
                note = (f"repaired by `sms inspect --repair`: {r.get('damaged_chunks_dropped', '0')} damaged chunk(s) "
                        "dropped" + (f", unreadable from byte {r['unreadable_from_byte']} on" if r.get("unreadable_from_byte") else ""))
        else:
            f.seek(max(size - 8, 0))
            sc = scan(path)
            problem = _scan_problem(path, sc, f.read(8) == MAGIC)
            if problem is not None:
                raise problem
            header, channels, schemas, spans = sc.header, sc.channels, sc.schemas, sc.spans
            stats_chunks = sc.chunks
            compression = sorted({c.compression or "none" for k, c, _ in sc.items if k == "chunk"})
            metadata = {r.name: dict(r.metadata) for k, r, _ in sc.items if k == "metadata"}
            attachments = [r.name for k, r, _ in sc.items if k == "attachment"]
            events_cid = [c for c, ch in channels.items() if ch.topic == "/events"]
            events = [data[start + 22:end] for k, _, data in sc.items if k == "chunk" and events_cid
                      for op, _, cid, _, start, end in _inner(data) if op == OP_MESSAGE and cid == events_cid[0]]
            if sc.end == "marker":  # the writer's end marker: it is still writing, or stopped before finishing
                from sms_cli.results import lock_holder, pid_alive

                writer = lock_holder(path.parent).get("pid")
                if "run" not in metadata and pid_alive(writer):
                    note = f"still being written (PID {writer}): {_readable(sc)} so far"
                else:
                    note = (("" if "run" in metadata else f"the run was killed at about t = {_s(sc.last_ns)} s; ")
                            + f"{_readable(sc)} are readable; the file has no index: run `sms inspect --repair {path}` "
                            "to add one")

    topics = []
    for cid, channel in sorted(channels.items(), key=lambda kv: kv[1].topic):
        count, t0, t1, stamps = spans.get(cid, [0, None, None, set()])
        schema = schemas.get(channel.schema_id)
        first = t0 / 1e9 if t0 is not None else None
        last = t1 / 1e9 if t1 is not None else None
        # rate of distinct times (samples per second)
        rate = (len(stamps) - 1) / (last - first) if len(stamps) > 1 and last > first else None
        topics.append(
            {
                "topic": channel.topic,
                "schema": schema.name if schema is not None else "",
                "encoding": channel.message_encoding,
                "messages": count,
                "samples": len(stamps),
                "first_s": first,
                "last_s": last,
                "rate_hz": rate,
            }
        )
    starts = [t["first_s"] for t in topics if t["first_s"] is not None]
    ends = [t["last_s"] for t in topics if t["last_s"] is not None]
    run = metadata.get("run", {})
    return {
        "file": str(path),
        "size_bytes": size,
        "library": header.library if header is not None else "",
        "status": run.get("status") or ("recording" if note.startswith("still being written")
                                         else "killed" if note.startswith("the run was killed") else None),
        "mission": metadata.get("mission", {}).get("name"),
        "start_s": min(starts) if starts else None,
        "end_s": max(ends) if ends else None,
        "duration_s": (max(ends) - min(starts)) if starts else None,
        "messages": sum(t["messages"] for t in topics),
        "chunks": stats_chunks,
        "compression": compression,
        "topics": topics,
        "metadata": sorted(metadata),
        "run": run,
        "attachments": attachments,
        "note": note,
        "replay": replay_check(metadata, channels, spans, events),
    }


def replay_check(metadata: dict, channels: dict, spans: dict, events=()) -> dict[str, Any]:
    """Whether another engine can replay the recording from its own topics: what its ``sms.timing``
    metadata says (``sms_cli.sim.timing``), checked against the sample times (every control tick
    sampled) and the /events payloads ``events`` (a joint stop's impulse is not a recorded input).
    ``replayable`` None: the recording has no ``sms.timing`` (an older one)."""
    import json

    from sms_cli.sim.timing import TIMING_METADATA, missing_ticks

    timing = metadata.get(TIMING_METADATA)
    if not timing:
        return {"replayable": None, "reasons": [f"the recording has no {TIMING_METADATA} metadata (it predates it): "
                                                "its timing is unknown"]}
    reasons = [r for r in timing.get("not_replayable_because", "").split("; ") if r]
    out = {"control_rate_hz": float(timing["control_rate_hz"]), "plant_dt_s": float(timing["plant_dt_s"]),
           "record_rate_hz": timing.get("record_rate_hz"), "command_stamp": timing.get("command_stamp", "")}
    cids = [c for c, ch in channels.items() if ch.topic == "/attitude"]
    stamps = spans.get(cids[0], [0, None, None, set()])[3] if cids else set()
    n, missing, first = missing_ticks(stamps, float(timing["control_period_s"]), out["plant_dt_s"])
    if missing:
        reasons.append(f"{missing} of the {n} control ticks up to the last sample have no sample (the first at "
                       f"t = {first:.6g} s), so the commands of those control periods are not in the recording")
    stops = []
    for raw in events:
        try:
            event = json.loads(bytes(raw))
        except ValueError:
            continue
        if event.get("name") == "joint_stop":
            stops.append(event)
    if stops:
        reasons.append(f"a joint reached its stop {len(stops)} time(s) (first {stops[0].get('detail', {}).get('joint', '?')} "
                       f"at t = {float(stops[0].get('t') or 0):.6g} s): the stop's impulse and holding force are not "
                       "recorded inputs")
    return {"replayable": not reasons, "reasons": reasons, **out}


def repair_recording(path: str | Path) -> dict[str, Any]:
    """Rewrite the readable part of a recording (every undamaged chunk up to the first unreadable
    record, the metadata and attachments) into a complete, indexed MCAP, atomically in place.
    A recording without ``run`` metadata (killed) gets ``run.status = killed``. Returns what was
    kept: messages, chunks, damaged chunks dropped, last time (s)."""
    from sms_cli.results import atomic_path
    from sms_cli.recording.writer import ChunkedMcapWriter

    path = Path(path)
    if not path.is_file():
        raise _fail(path, "no such recording file", "give the path of an .mcap file written by `sms simulate`")
    with open(path, "rb") as f:
        if f.read(8) != MAGIC:
            raise _fail(path, "not an MCAP file (its first bytes are not the MCAP magic)", "nothing to repair")
    sc = scan(path)
    chunks = [c for k, c, _ in sc.items if k == "chunk"]
    compression = chunks[0].compression if chunks else ""
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    kept = lost = 0
    last = None
    with atomic_path(path) as tmp, open(tmp, "wb") as out:
        w = ChunkedMcapWriter(out, compression=compression, chunk_size=1 << 62, live_end=False,
                              library=sc.header.library if sc.header is not None else "sms inspect --repair",
                              profile=sc.header.profile if sc.header is not None else "")

        def channel(cid: int) -> int | None:
            """The new id of channel ``cid`` (registered at first use; None: it was only in a damaged chunk)."""
            if cid not in channel_ids and cid in sc.channels:
                ch = sc.channels[cid]
                schema = sc.schemas.get(ch.schema_id)
                if schema is not None and schema.id not in schema_ids:
                    schema_ids[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
                channel_ids[cid] = w.register_channel(ch.topic, ch.message_encoding, schema_ids.get(ch.schema_id, 0),
                                                      dict(ch.metadata))
            return channel_ids.get(cid)

        has_run = False
        for kind, record, data in sc.items:
            if kind == "metadata":
                has_run = has_run or record.name == "run"
                w.add_metadata(record.name, dict(record.metadata))
            elif kind == "attachment":
                w.add_attachment(record.name, record.media_type, record.data, record.log_time)
            else:
                for op, rec, cid, t, start, end in _inner(data):
                    if op == OP_CHANNEL:
                        channel(rec.id)
                    elif op == OP_MESSAGE:
                        new_id = channel(cid)
                        if new_id is None:
                            lost += 1
                            continue
                        seq = struct.unpack_from("<I", data, start + 2)[0]
                        w.add_message(new_id, t, data[start + 22:end], seq)
                        kept += 1
                        last = t if last is None else max(last, t)
                w.flush_chunk()
        if not has_run:
            w.add_metadata("run", {"status": "killed", "last_sample_s": repr(last / 1e9) if last is not None else ""})
        w.add_metadata("repair", {"messages": str(kept), "chunks": str(len(chunks)), "damaged_chunks_dropped": str(len(sc.damaged)),
                                  "unreadable_from_byte": "" if sc.stopped_at is None else str(sc.stopped_at)})
        w.finish()
    return {"file": str(path), "messages": kept, "chunks": len(chunks), "damaged_chunks": len(sc.damaged),
            "lost_messages": lost, "until_s": None if last is None else last / 1e9, "unreadable_from_byte": sc.stopped_at}


def format_repair(r: dict[str, Any]) -> str:
    until = "" if r["until_s"] is None else f", up to t = {r['until_s']:.6g} s"
    dropped = f"; {r['damaged_chunks']} damaged chunk(s) dropped" if r["damaged_chunks"] else ""
    cut = "" if r["unreadable_from_byte"] is None else f"; unreadable from byte {r['unreadable_from_byte']} on"
    return f"repaired {r['file']}: {r['messages']} messages in {r['chunks']} chunks recovered{until}{dropped}{cut}"


def _size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n} B"


def _t(x: float | None) -> str:
    return "-" if x is None else f"{x:.3f}"


def format_inspection(info: dict[str, Any]) -> str:
    """Human-readable table of ``inspect_recording``'s result."""
    lines = [
        f"{info['file']}: {_size(info['size_bytes'])}, {info['messages']} messages"
        + (f" in {info['chunks']} chunks ({', '.join(info['compression'])})" if info["chunks"] else "")
        + f", written by {info['library'] or 'unknown'}"
    ]
    run = info["run"]
    status = info["status"] or "unknown (no run metadata)"
    parts = [f"status: {status}"]
    if info["mission"]:
        parts.append(f"mission: {info['mission']}")
    if run.get("steps"):
        parts.append(f"{run['steps']} steps, {run.get('samples', '?')} samples, {run.get('events', '?')} events")
    lines.append("  " + " · ".join(parts))
    if info.get("note"):
        lines.append(f"  note: {info['note']}")
    lines.append(f"  time span: {_t(info['start_s'])} – {_t(info['end_s'])} s (duration {_t(info['duration_s'])} s)")
    if info["topics"]:
        wt = max(len("topic"), *(len(t["topic"]) for t in info["topics"]))
        ws = max(len("schema"), *(len(t["schema"]) for t in info["topics"]))
        lines.append(f"  {'topic':<{wt}}  {'schema':<{ws}}  {'messages':>9}  {'samples':>9}  {'rate (Hz)':>9}  span (s)")
        for t in info["topics"]:
            rate = "-" if t["rate_hz"] is None else f"{t['rate_hz']:.4g}"
            lines.append(
                f"  {t['topic']:<{wt}}  {t['schema']:<{ws}}  {t['messages']:>9}  {t['samples']:>9}  {rate:>9}  "
                f"{_t(t['first_s'])} – {_t(t['last_s'])}"
            )
    else:
        lines.append("  no topics")
    lines.append(f"  metadata: {', '.join(info['metadata']) or '-'}")
    replay = info.get("replay") or {}
    if replay.get("replayable") is None:
        lines.append("  replay: unknown: " + "; ".join(replay.get("reasons", ["no sms.timing metadata"])))
    elif replay["replayable"]:
        period = 1e3 / replay["control_rate_hz"]
        lines.append(f"  replay: yes: every control tick is sampled; a torque stamped at a control tick t_k acted over "
                     f"[t_k - {period:.6g} ms, t_k] (control {replay['control_rate_hz']:.6g} Hz, plant step "
                     f"{1e3 * replay['plant_dt_s']:.6g} ms, RKMK4; metadata sms.timing)")
    else:
        lines.append("  replay: NO, this recording cannot be replayed by another engine: " + "; ".join(replay["reasons"]))
    if info["attachments"]:
        lines.append(f"  attachments: {', '.join(info['attachments'])}")
    return "\n".join(lines)


__all__ = ["inspect_recording", "format_inspection", "repair_recording", "format_repair", "scan", "verify_chunks"]
