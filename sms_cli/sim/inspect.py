"""``sms inspect``: summarise an MCAP recording (topics, schemas, counts, time span, rates, run status).

Reads only the summary section, the message indexes and the metadata records, so it is fast on
large files. Times are printed in seconds of simulation time (log times / 1e9). A file that is
not MCAP, or that was never finalised (the writer was killed), is an ``InputError`` naming the
file; for an unfinished file the message says how much of it is still readable.
"""

from __future__ import annotations

import io
import struct
from pathlib import Path
from typing import Any

from sms_cli.errors import InputError, Location, Problem

MAGIC = b"\x89MCAP0\r\n"


def _fail(path: Path, message: str, hint: str = "") -> InputError:
    return InputError(problems=[Problem(message, Location(path), hint=hint)])


def _recoverable(path: Path) -> tuple[int, int, float | None]:
    """(messages, complete chunks, last log time in s) readable from the start of a broken file."""
    from mcap.records import Chunk, Message
    from mcap.stream_reader import StreamReader, breakup_chunk

    messages = chunks = 0
    last = None
    try:
        with open(path, "rb") as f:
            for record in StreamReader(f, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    inner = [r for r in breakup_chunk(record, validate_crc=True) if isinstance(r, Message)]
                    chunks += 1
                    messages += len(inner)
                    if inner:
                        t = max(m.log_time for m in inner)
                        last = t if last is None else max(last, t)
                elif isinstance(record, Message):
                    messages += 1
                    last = record.log_time if last is None else max(last, record.log_time)
    except Exception:  # noqa: BLE001 - reading stops at the first damaged record
        pass
    return messages, chunks, (None if last is None else last / 1e9)


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
            if len(head) != 9 or head[0] != 0x07:
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


def _spans_by_scan(f) -> tuple[dict[int, list[int]], dict, dict]:
    from mcap.reader import make_reader

    f.seek(0)
    spans: dict[int, list[int]] = {}
    channels: dict = {}
    schemas: dict = {}
    for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
        channels[channel.id] = channel
        if schema is not None:
            schemas[schema.id] = schema
        span = spans.setdefault(channel.id, [0, message.log_time, message.log_time, set()])
        span[0] += 1
        span[1] = min(span[1], message.log_time)
        span[2] = max(span[2], message.log_time)
        span[3].add(message.log_time)
    return spans, channels, schemas


def inspect_recording(path: str | Path) -> dict[str, Any]:
    """Summary of an MCAP file as a JSON-able dict (see ``format_inspection``)."""
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
        except Exception:  # noqa: BLE001 - any parse failure means a damaged/unfinished file
            messages, chunks, last = _recoverable(path)
            readable = f"{messages} messages in {chunks} complete chunks" + (f", up to t = {last:.6g} s" if last is not None else "")
            raise _fail(
                path,
                "truncated or unfinished MCAP file: it has no valid footer and summary (the process that wrote it "
                f"stopped before finalising it); {readable} can still be read in order",
                "re-run the simulation (an interrupted `sms simulate` finalises its file; only a killed one leaves it like this)",
            ) from None

        if summary is None or summary.statistics is None:
            spans, channels, schemas = _spans_by_scan(f)
            stats_chunks = None
            compression: list[str] = []
        else:
            channels, schemas = summary.channels, summary.schemas
            spans = _channel_spans(f, summary)
            if spans is None:
                spans, _, _ = _spans_by_scan(f)
            stats_chunks = summary.statistics.chunk_count
            compression = sorted({ci.compression or "none" for ci in summary.chunk_indexes})
        f.seek(0)
        metadata = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
        f.seek(0)
        attachments = [a.name for a in summary.attachment_indexes] if summary is not None else []

    topics = []
    for cid, channel in sorted(channels.items(), key=lambda kv: kv[1].topic):
        count, t0, t1, stamps = spans.get(cid, [0, None, None, set()])
        schema = schemas.get(channel.schema_id)
        first = t0 / 1e9 if t0 is not None else None
        last = t1 / 1e9 if t1 is not None else None
        # rate of distinct times (samples per second): /tf carries one message per link per sample
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
        "library": header.library,
        "status": run.get("status"),
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
    }


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
    if info["attachments"]:
        lines.append(f"  attachments: {', '.join(info['attachments'])}")
    return "\n".join(lines)


__all__ = ["inspect_recording", "format_inspection"]
