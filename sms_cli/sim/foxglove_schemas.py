"""JSON schemas of the recorded topics (MCAP ``jsonschema`` encoding, ``json`` messages).

``foxglove.FrameTransform`` and ``foxglove.Log`` follow Foxglove's published JSON schemas
(github.com/foxglove/foxglove-sdk, ``schemas/jsonschema``): field names and nesting must match
exactly for the 3D and Log panels to recognise them. The numeric-topic, event and robot
description schemas are ours.

Foxglove turns a JSON schema into datatypes with a strict subset of JSON Schema (see
``parseJsonSchema.ts`` in Foxglove's ``mcap-support`` package): every object needs
``"type": "object"`` and a ``properties`` map; a field's ``type`` is one string among boolean,
string, number, integer, object, array (no unions such as ``["number", "null"]``); enumerations
are ``oneOf`` of numeric ``const``. A schema outside that subset makes Foxglove reject the
channel, so the schemas below stay inside it (``tests/test_recorder.py`` checks this).
"""

from __future__ import annotations

import json
from typing import Any

_TIME = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
    },
}

FRAME_TRANSFORM: dict[str, Any] = {
    "title": "foxglove.FrameTransform",
    "description": "A transform between two reference frames in 3D space (translation in m, "
    "rotation a unit quaternion): the pose of the child frame in the parent frame.",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "Timestamp of transform"},
        "parent_frame_id": {"type": "string", "description": "Name of the parent frame"},
        "child_frame_id": {"type": "string", "description": "Name of the child frame"},
        "translation": {
            "title": "foxglove.Vector3",
            "description": "Position of the child frame's origin in the parent frame",
            "type": "object",
            "properties": {k: {"type": "number"} for k in ("x", "y", "z")},
            "required": ["x", "y", "z"],
        },
        "rotation": {
            "title": "foxglove.Quaternion",
            "description": "Orientation of the child frame in the parent frame",
            "type": "object",
            "properties": {k: {"type": "number"} for k in ("x", "y", "z", "w")},
            "required": ["x", "y", "z", "w"],
        },
    },
    "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
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

NUMBER = {"type": "number"}


def numeric_topic_schema(topic: str, fields: list[tuple[str, int]]) -> dict[str, Any]:
    """Schema of a numeric topic: ``fields`` are (name, n) with n = 0 for a number, n ≥ 1 for an array.

    JSON has no NaN: a non-finite value is written as ``null``. The schema still says
    ``number`` (Foxglove accepts no type unions); such values only appear once a run diverges.
    """
    props: dict[str, Any] = {}
    for name, n in fields:
        if n == 0:
            props[name] = dict(NUMBER)
        else:
            props[name] = {"type": "array", "items": dict(NUMBER), "minItems": n, "maxItems": n}
    return {
        "title": schema_name(topic),
        "description": "Numeric samples of simulation topic " + topic + " (SI units; null = not finite).",
        "type": "object",
        "properties": props,
        "required": [name for name, _ in fields],
        "additionalProperties": False,
    }


def schema_name(topic: str) -> str:
    """Schema name of a numeric topic: ``/wheels/speed`` → ``sms.wheels.speed``."""
    return "sms" + topic.replace("/", ".")


def schema_bytes(schema: dict[str, Any]) -> bytes:
    """Deterministic compact JSON of a schema (key order as written above)."""
    return json.dumps(schema, separators=(",", ":"), ensure_ascii=False).encode()


__all__ = [
    "FRAME_TRANSFORM",
    "LOG",
    "LOG_LEVELS",
    "EVENT",
    "ROBOT_DESCRIPTION",
    "numeric_topic_schema",
    "schema_name",
    "schema_bytes",
]
