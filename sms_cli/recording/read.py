"""Reading a recording's messages back as plain values, with the published decoders: the ``mcap``
reader, ``mcap-protobuf-support`` (Google's protobuf runtime on the schema stored in the file)
for the binary topics and ``json`` for the JSON ones. Nothing here shares code with the encoder.

Numeric topics come back as {recorded field name: float or list of floats}; ``/tf`` as
{"transforms": [{"parent_frame_id", "child_frame_id", "timestamp": {"sec", "nsec"},
"translation": {x, y, z}, "rotation": {x, y, z, w}}, …]}; JSON topics as their JSON.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterator

from mcap.decoder import DecoderFactory as _McapDecoderFactory


class _JsonDecoderFactory(_McapDecoderFactory):
    def decoder_for(self, message_encoding, schema):
        return json.loads if message_encoding == "json" else None


def _plain(message: Any, names: list[str] | None) -> dict[str, Any]:
    """A protobuf message as a dict (recursively; repeated fields as lists, doubles as floats)."""
    out: dict[str, Any] = {}
    for k, field in enumerate(message.DESCRIPTOR.fields):
        value = getattr(message, field.name)
        name = names[k] if names else field.name
        if field.type == field.TYPE_MESSAGE:
            if field.is_repeated:
                out[name] = [_plain(v, None) for v in value]
            else:
                out[name] = _plain(value, None)
        elif field.is_repeated:
            out[name] = list(value)
        else:
            out[name] = value
    if "seconds" in out and "nanos" in out and len(out) == 2:  # google.protobuf.Timestamp
        return {"sec": out["seconds"], "nsec": out["nanos"]}
    return out


def messages(path: str | Path, topics: list[str] | None = None, *,
             log_time_order: bool = True) -> Iterator[tuple[str, int, dict[str, Any]]]:
    """(topic, log time in ns, decoded message) of every message (of ``topics``) in the file."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory(), _JsonDecoderFactory()])
        names: dict[int, list[str] | None] = {}
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=topics, log_time_order=log_time_order):
            if isinstance(decoded, dict):
                yield channel.topic, message.log_time, decoded
                continue
            if channel.id not in names:
                meta = channel.metadata.get("sms.fields")
                names[channel.id] = json.loads(meta) if meta else None
            yield channel.topic, message.log_time, _plain(decoded, names[channel.id])


def topic_series(path: str | Path, topics: list[str]) -> dict[str, tuple[list[float], list[dict[str, Any]]]]:
    """topic → (times in s, decoded messages) for the topics asked for that have messages."""
    out: dict[str, tuple[list[float], list[dict[str, Any]]]] = {t: ([], []) for t in topics}
    for topic, log_time, data in messages(path, topics):
        ts, rows = out[topic]
        ts.append(log_time / 1e9)
        rows.append(data)
    return {t: v for t, v in out.items() if v[0]}


__all__ = ["messages", "topic_series"]
