"""Schemas of the recorded topics.

Binary (protobuf, MCAP ``protobuf`` schema and message encoding) for everything recorded per sample:

* ``/tf``: ``foxglove.FrameTransforms`` of Foxglove's published schemas (the
  ``foxglove-schemas-protobuf`` package), one message per sample with every link's
  ``foxglove.FrameTransform``: what Foxglove's 3D panel reads;
* each numeric topic: a message of its own, ``sms.topic.<path>`` (``/wheels/speed`` →
  ``sms.topic.wheels__speed``), one ``double`` field per number and one packed ``repeated double``
  per array, numbered 1, 2, … in the order of the first sample. Field names are the recorded names
  when they are protobuf identifiers, else a sanitised form; the channel's metadata ``sms.fields``
  (JSON list) then gives the recorded names in field order (``sms_cli.recording.read`` maps back).

JSON (``jsonschema`` / ``json``) for the rare, free-form topics: ``/events`` (``sms.Event``, with a
JSON ``detail`` object), ``/log`` (``foxglove.Log`` in Foxglove's published JSON schema) and
``/robot_description``. Foxglove turns a JSON schema into datatypes with a strict subset of JSON
Schema (``parseJsonSchema.ts`` in Foxglove's ``mcap-support``): every object needs
``"type": "object"`` and a ``properties`` map, a field's ``type`` is one string, enumerations are
``oneOf`` of numeric ``const``; ``tests/test_recorder.py`` keeps the schemas inside it.
"""

from __future__ import annotations

import json
import re
from typing import Any

_TIME = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
    },
}

LOG_LEVELS = {"unknown": 0, "debug": 1, "info": 2, "warning": 3, "error": 4, "fatal": 5}

LOG: dict[str, Any] = {
    "title": "foxglove.Log",
    "description": "A log message",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "Timestamp of log message"},
        "level": {
            "title": "foxglove.LogLevel",
            "description": "Log level",
            "oneOf": [{"title": k.upper(), "const": v} for k, v in LOG_LEVELS.items()],
        },
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"},
    },
    "required": ["timestamp", "level", "message", "name", "file", "line"],
}

EVENT: dict[str, Any] = {
    "title": "sms.Event",
    "description": "A simulation event: phase change, saturation start/end, divergence. t in s (simulation time).",
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "simulation time, s"},
        "name": {"type": "string"},
        "level": {"type": "string", "enum": list(LOG_LEVELS)},
        "detail": {"type": "object", "properties": {}, "additionalProperties": True},
    },
    "required": ["t", "name", "level", "detail"],
}

ROBOT_DESCRIPTION: dict[str, Any] = {
    "title": "sms.RobotDescription",
    "description": "URDF text of the simulated robot, in the {data: string} shape of std_msgs/String "
    "that Foxglove's 3D panel loads from the /robot_description topic.",
    "type": "object",
    "properties": {"data": {"type": "string", "description": "URDF XML"}},
    "required": ["data"],
}

def schema_bytes(schema: dict[str, Any]) -> bytes:
    """Deterministic compact JSON of a schema (key order as written above)."""
    return json.dumps(schema, separators=(",", ":"), ensure_ascii=False).encode()


_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
FRAME_TRANSFORMS_NAME = "foxglove.FrameTransforms"


def frame_transforms_descriptor() -> bytes:
    """Serialized FileDescriptorSet of ``foxglove.FrameTransforms`` and its dependencies, from
    Foxglove's published protobuf schemas."""
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
    from mcap_protobuf.schema import build_file_descriptor_set

    return build_file_descriptor_set(FrameTransforms).SerializeToString(deterministic=True)


def topic_message_name(topic: str) -> str:
    """Protobuf message name of a numeric topic: ``/wheels/speed`` → ``sms.topic.wheels__speed``
    (one package for all, so no topic's message is another's package)."""
    return "sms.topic." + topic[1:].replace("/", "__")


def field_identifiers(names: list[str]) -> list[str]:
    """Protobuf field names for recorded field names: each name itself when it is an identifier,
    else with every other character replaced by ``_`` (and ``_`` before a leading digit), made
    unique with a numeric suffix."""
    out: list[str] = []
    taken = {n for n in names if _IDENT.match(n)}
    for name in names:
        if _IDENT.match(name):
            out.append(name)
            continue
        base = re.sub(r"[^A-Za-z0-9_]", "_", name)
        if not base or base[0].isdigit():
            base = "_" + base
        ident, k = base, 2
        while ident in taken:
            ident, k = f"{base}_{k}", k + 1
        taken.add(ident)
        out.append(ident)
    return out


def numeric_topic_descriptor(topic: str, fields: list[tuple[str, int]]) -> tuple[str, bytes, dict[str, str]]:
    """(schema name, serialized FileDescriptorSet, channel metadata) of a numeric topic whose
    ``fields`` are (name, n): n = 0 a ``double``, n ≥ 1 a packed ``repeated double`` of n values."""
    from google.protobuf import descriptor_pb2 as d

    full = topic_message_name(topic)
    package, _, message = full.rpartition(".")
    names = [name for name, _ in fields]
    idents = field_identifiers(names)
    proto = d.FileDescriptorProto(name=full.replace(".", "/") + ".proto", package=package, syntax="proto3")
    msg = proto.message_type.add(name=message)
    for number, (ident, (_, n)) in enumerate(zip(idents, fields), start=1):
        label = d.FieldDescriptorProto.LABEL_REPEATED if n else d.FieldDescriptorProto.LABEL_OPTIONAL
        msg.field.add(name=ident, number=number, type=d.FieldDescriptorProto.TYPE_DOUBLE, label=label, json_name=ident)
    data = d.FileDescriptorSet(file=[proto]).SerializeToString(deterministic=True)
    meta = {"sms.fields": json.dumps(names, ensure_ascii=False)} if idents != names else {}
    return full, data, meta


__all__ = [
    "LOG",
    "LOG_LEVELS",
    "EVENT",
    "ROBOT_DESCRIPTION",
    "FRAME_TRANSFORMS_NAME",
    "frame_transforms_descriptor",
    "field_identifiers",
    "numeric_topic_descriptor",
    "topic_message_name",
    "schema_bytes",
]
