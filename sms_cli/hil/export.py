"""Writers of ``sms export hil``: ``commands.csv`` and ``commands.mcap`` (Foxglove), each written atomically
(a temporary in the same folder, renamed when complete: an interrupted export leaves no half file).

``commands.csv``: one row per sample of the moving mock-up, then one row (t = first time) of the held one.
Columns: ``mockup`` (spacecraft name), ``role`` (moving | held), ``t`` (s), the mock-up pose in the facility
world ``x y z`` (m) and ``qx qy qz qw``, its commanded body twist ``vx vy vz`` (m/s) ``wx wy wz`` (rad/s)
in the mock-up frame, and with a robot URDF ``reachable`` (1/0), ``position_error_m``,
``rotation_error_deg`` and the joint angles ``q1_rad …`` (the robot's joints in URDF order: names in
workspace.json); empty where a mock-up has no robot. Floats in repr precision.

``commands.mcap``: ``/tf`` (``foxglove.FrameTransforms``, protobuf) per sample with the facility world
frame as root: each mock-up frame (``<name>_mockup``), each robot base (``<name>_robot_base``) and the
tool frame its inverse kinematics reaches (``<name>_tool``, child of its base); ``/hil/twist`` (the moving
mock-up's commanded body twist, fields ``v``, ``w``), ``/hil/<role>/joints`` (field ``q``, rad, per robot).
Metadata ``facility`` (name, file, text, sha256), ``formation`` and ``versions``. Encoded with the
recording package (``sms_cli.recording``: its MCAP writer, Foxglove's descriptor, its protobuf templates).
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sms_cli.results import atomic_path, write_text_atomic

ROLES = ("moving", "held")


@dataclass
class MockupTrack:
    """One mock-up's commanded poses for the writers: ``poses`` (n, 7) facility world (n = 1 when held),
    ``twist`` (n, 6) or None (held), ``joints`` (n, nq) rad and residuals when it has a robot."""

    name: str
    role: str
    poses: np.ndarray
    twist: np.ndarray | None
    robot_base: np.ndarray | None = None
    tool: np.ndarray | None = None  # (n, 7) FK tool pose in the robot base frame
    joints: np.ndarray | None = None
    reachable: np.ndarray | None = None
    position_error: np.ndarray | None = None
    rotation_error: np.ndarray | None = None


def _f(x: float) -> str:
    return repr(float(x))


def commands_csv(t: np.ndarray, tracks: list[MockupTrack]) -> str:
    """The text of commands.csv (see the module docstring)."""
    nq = max([tr.joints.shape[1] for tr in tracks if tr.joints is not None], default=0)
    head = ["mockup", "role", "t", "x", "y", "z", "qx", "qy", "qz", "qw", "vx", "vy", "vz", "wx", "wy", "wz"]
    if nq:
        head += ["reachable", "position_error_m", "rotation_error_deg"] + [f"q{j + 1}_rad" for j in range(nq)]
    buf = io.StringIO()
    buf.write(",".join(head) + "\n")
    for tr in tracks:
        n = tr.poses.shape[0]
        twist = tr.twist if tr.twist is not None else np.zeros((n, 6))
        for k in range(n):
            row = [tr.name, tr.role, _f(t[k])] + [_f(x) for x in tr.poses[k]] + [_f(x) for x in twist[k]]
            if nq:
                if tr.joints is None:
                    row += [""] * (3 + nq)
                else:
                    q = [_f(x) for x in tr.joints[k]] + [""] * (nq - tr.joints.shape[1])
                    row += [str(int(tr.reachable[k])), _f(tr.position_error[k]), _f(np.degrees(tr.rotation_error[k]))] + q
            buf.write(",".join(row) + "\n")
    return buf.getvalue()


def write_commands_csv(path: Path, t: np.ndarray, tracks: list[MockupTrack]) -> Path:
    return write_text_atomic(path, commands_csv(t, tracks))


def _frames(world: str, t: np.ndarray, tracks: list[MockupTrack]) -> tuple[list[tuple[str, str]], np.ndarray]:
    """(parent, child) of every /tf transform and their pose rows (n, 7 · m), parent-relative."""
    n = t.size
    names, cols = [], []
    for tr in tracks:
        names.append((world, f"{tr.name}_mockup"))
        cols.append(np.broadcast_to(tr.poses, (n, 7)))
    for tr in tracks:
        if tr.robot_base is not None:
            names.append((world, f"{tr.name}_robot_base"))
            cols.append(np.broadcast_to(tr.robot_base, (n, 7)))
            names.append((f"{tr.name}_robot_base", f"{tr.name}_tool"))
            cols.append(np.broadcast_to(tr.tool, (n, 7)))
    return names, np.hstack(cols)


def write_commands_mcap(path: Path, t: np.ndarray, tracks: list[MockupTrack], *, world: str,
                        metadata: dict[str, dict[str, str]]) -> Path:
    """commands.mcap (see the module docstring); ``metadata``: record name → {key: text}."""
    from sms_cli import __version__
    from sms_cli.recording import schemas as fs
    from sms_cli.recording.encoding import HEADER_BYTES, Template, Templates, frame_transform
    from sms_cli.recording.writer import ChunkedMcapWriter, available_compression

    n = t.size
    ts = np.rint(np.asarray(t, float) * 1e9).astype(np.int64)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        w = ChunkedMcapWriter(fh, compression=available_compression(), library=f"sms {__version__} export hil",
                              live_end=False)
        for name, record in metadata.items():
            w.add_metadata(name, record)
        w.add_metadata("versions", {"sms": __version__})
        templates, channels, values = [], [], []
        # /tf
        names, poses = _frames(world, t, tracks)
        tf = Template()
        for parent, child in names:
            frame_transform(tf, 1, parent, child)
        sid = w.register_schema(fs.FRAME_TRANSFORMS_NAME, "protobuf", fs.frame_transforms_descriptor())
        templates.append(tf.done())
        channels.append(w.register_channel("/tf", "protobuf", sid))
        values.append(poses)
        # numeric topics
        topics: list[tuple[str, list[tuple[str, int]], np.ndarray]] = []
        mover = next(tr for tr in tracks if tr.role == "moving")
        topics.append(("/hil/twist", [("v", 3), ("w", 3)], mover.twist))
        for tr in tracks:
            if tr.joints is not None:
                topics.append((f"/hil/{tr.role}/joints", [("q", tr.joints.shape[1])],
                               np.broadcast_to(tr.joints, (n, tr.joints.shape[1]))))
        for topic, spec, data in topics:
            schema_name, descriptor, meta = fs.numeric_topic_descriptor(topic, spec)
            sid = w.register_schema(schema_name, "protobuf", descriptor)
            channels.append(w.register_channel(topic, "protobuf", sid, meta or None))
            tpl = Template()
            for number, (_, k) in enumerate(spec, start=1):
                tpl.packed_doubles(number, k)
            templates.append(tpl.done())
            values.append(data)
        compiled = Templates(templates)
        out, end, offsets = compiled.encode(np.hstack(values), np.array(channels, dtype=np.int64), 0, ts)
        stops = np.append(offsets[1:], end)
        m = len(channels)
        for k in range(offsets.size):
            s, j = divmod(k, m)
            w.add_message(channels[j], int(ts[s]), bytes(out[offsets[k] + HEADER_BYTES:stops[k]]), s)
            if j == m - 1:
                w.maybe_flush()
        w.finish()
    return Path(path)


def facility_metadata(name: str, file: Path, text: str) -> dict[str, str]:
    return {"name": name, "file": str(file), "text": text, "sha256": hashlib.sha256(text.encode()).hexdigest()}


__all__ = ["MockupTrack", "commands_csv", "write_commands_csv", "write_commands_mcap", "facility_metadata"]
