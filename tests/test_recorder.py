"""MCAP recorder and ``sms inspect``: read back with the official ``mcap`` reader.

Oracles: the ``mcap`` package's reader (an independent implementation of the format, with CRC
checks) with the published protobuf decoder (``mcap-protobuf-support``: Google's runtime on the
schemas stored in the file), Foxglove's published FrameTransforms schema, Pinocchio's SE3 algebra
for the transform tree, exact integer arithmetic for the decimation times, the JSON schemas stored
in the file (validated with ``jsonschema``), sha256 of two independent runs, and a real SIGINT
delivered to a recording subprocess.
"""

from __future__ import annotations

import hashlib
import json
import math
import signal
import subprocess
import sys
import textwrap
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import NonSeekingReader, make_reader

from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

from sms_cli.recording.read import _JsonDecoderFactory, _plain
from sms_cli.recording.frames import RelativePoses
from sms_cli.recording.inspect import inspect_recording
from sms_cli.recording.recorder import McapRecorder

LINKS = ["base_link", "arm_1", "arm_2", "arm_3", "wheel_1", "wheel_2"]
PARENTS = ["world", "base_link", "arm_1", "arm_2", "base_link", "base_link"]
URDF = '<?xml version="1.0"?>\n<robot name="test_robot"><link name="base_link"/></robot>\n'
MISSION = "name: test\nrobot: robot.urdf\n"
SCALAR_TOPICS = ["/attitude", "/wheels/speed", "/joints/position"]


def unit_quats(rng, shape):
    q = rng.normal(size=shape + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def world_poses(i: int, n: int = len(LINKS)) -> np.ndarray:
    """Deterministic pseudo-random world poses of step i: (n, 7) [x y z qx qy qz qw]."""
    rng = np.random.default_rng(1000 + i)
    w = np.empty((n, 7))
    w[:, :3] = rng.normal(scale=2.0, size=(n, 3))
    w[:, 3:] = unit_quats(rng, (n,))
    return w


def scalars_of(i: int) -> dict:
    t = i * 0.001
    return {
        "/attitude": {"roll": math.sin(t), "pitch": 1e-7 * math.cos(t), "yaw": -123.456789 * t},
        "/wheels/speed": {"rw1": 100.0 + t, "rw2": -3.0e5 * t, "rw3": np.float64(0.5)},
        "/joints/position": {"q": np.array([t, 2 * t, -t, 1e-12 * i])},
    }


def make_recorder(path, rate=None, **kw) -> McapRecorder:
    rec = McapRecorder(
        path,
        mission_text=MISSION,
        mission_name="test",
        model_summary={"dof": 12, "mass_kg": 1234.5, "wheels": ["rw1", "rw2", "rw3"]},
        urdf_text=URDF,
        versions={"sms": "0.1.0", "pinocchio": "4.1"},
        record_rate_hz=rate,
        **kw,
    )
    rec.add_transform_tree(LINKS, PARENTS)
    return rec


def record_run(path, n_steps, dt=0.001, rate=None, events=True, **kw) -> McapRecorder:
    rec = make_recorder(path, rate, **kw)
    with rec:
        for i in range(n_steps):
            rec.write_step(i * dt, transforms=world_poses(i), scalars=scalars_of(i))
            if events and i == n_steps // 2:
                rec.write_event(i * dt, "phase", {"name": "deploy", "index": np.int64(2), "gain": np.array([1.0, np.nan])})
            if events and i == n_steps // 2 + 1:
                rec.write_event(i * dt, "saturation", {"wheel": "rw1"}, level="warning")
    return rec


def read_all(path, flatten_tf=True):
    """[(topic, schema name, schema data, log_time, publish_time, payload dict)] via the mcap reader
    and the published protobuf decoder; each /tf message (foxglove.FrameTransforms) gives one row
    per FrameTransform it holds unless ``flatten_tf`` is False."""
    out = []
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[ProtobufDecoderFactory(), _JsonDecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            if not isinstance(decoded, dict):
                meta = channel.metadata.get("sms.fields")
                decoded = _plain(decoded, json.loads(meta) if meta else None)
            rows = decoded["transforms"] if channel.topic == "/tf" and flatten_tf else [decoded]
            for payload in rows:
                out.append((channel.topic, schema.name, schema.data, message.log_time, message.publish_time, payload))
    return out


def by_topic(messages):
    topics: dict[str, list] = {}
    for m in messages:
        topics.setdefault(m[0], []).append(m)
    return topics


def metadata(path) -> dict[str, dict[str, str]]:
    with open(path, "rb") as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}


def expected_sample_steps(n_steps: int, dt: str, rate: int) -> list[int]:
    """Exact oracle: the first step index at or after each grid time k/rate (t_i = i·dt)."""
    dt_f, period = Fraction(dt), Fraction(1, rate)
    steps, k = [], 0
    while True:
        i = math.ceil(k * period / dt_f)
        if i >= n_steps:
            return steps
        if not steps or i != steps[-1]:
            steps.append(i)
        k += 1


# --------------------------------------------------------------------------- structure
def test_every_topic_counts_and_monotonic_times(tmp_path):
    path = tmp_path / "run.mcap"
    n = 1200
    rec = record_run(path, n, rate=None)
    msgs = read_all(path)
    topics = by_topic(msgs)
    assert set(topics) == {"/tf", "/robot_description", "/events", "/log", *SCALAR_TOPICS}
    assert len(topics["/tf"]) == n * len(LINKS)
    assert len(by_topic(read_all(path, flatten_tf=False))["/tf"]) == n  # one FrameTransforms per sample
    for topic in SCALAR_TOPICS:
        assert len(topics[topic]) == n
    assert len(topics["/events"]) == len(topics["/log"]) == 2
    assert len(topics["/robot_description"]) == 1
    assert rec.samples == n and rec.steps == n
    for topic, items in topics.items():
        times = [m[3] for m in items]
        assert times == sorted(times), topic
        assert all(m[3] == m[4] for m in items)  # log time = publish time = simulation time
    assert [m[3] for m in topics["/attitude"]] == [round(i * 0.001 * 1e9) for i in range(n)]
    # every link appears once per sample, with its URDF parent
    first = [m[5] for m in topics["/tf"] if m[3] == 0]
    assert [(p["child_frame_id"], p["parent_frame_id"]) for p in first] == list(zip(LINKS, PARENTS))


@pytest.mark.parametrize("dt, rate, n_steps", [("0.001", 50, 2001), ("0.003", 100, 1500), ("0.02", 10, 301), ("0.05", 50, 40)])
def test_decimation_matches_exact_grid(tmp_path, dt, rate, n_steps):
    path = tmp_path / "dec.mcap"
    rec = record_run(path, n_steps, dt=float(dt), rate=rate, events=False)
    steps = expected_sample_steps(n_steps, dt, rate)
    topics = by_topic(read_all(path))
    got = [m[3] for m in topics["/attitude"]]
    assert got == [round(i * float(dt) * 1e9) for i in steps]
    assert len(topics["/tf"]) == len(steps) * len(LINKS)
    assert rec.samples == len(steps)
    if Fraction(dt) <= Fraction(1, rate):  # no more than one sample per step: count = ⌊T·r⌋ + 1
        t_end = (n_steps - 1) * Fraction(dt)
        assert len(steps) == math.floor(t_end * rate) + 1
    meta = metadata(path)["run"]
    assert meta["steps"] == str(n_steps) and meta["samples"] == str(len(steps))


def test_due_and_force(tmp_path):
    path = tmp_path / "force.mcap"
    rec = make_recorder(path, rate=10)
    with rec:
        assert rec.due(0.0)
        assert rec.write_step(0.0, scalars=scalars_of(0))
        assert not rec.due(0.05) and not rec.write_step(0.05, scalars=scalars_of(1))
        assert rec.due(0.1)
        assert rec.write_step(0.1, scalars=scalars_of(2))
        assert rec.write_step(0.13, scalars=scalars_of(3), force=True)  # off-grid final state
        assert not rec.write_step(0.13, scalars=scalars_of(3), force=True)  # same time: not twice
        assert rec.write_step(0.2, scalars=scalars_of(4))  # the grid is kept after a forced sample
    times = [m[3] for m in by_topic(read_all(path))["/attitude"]]
    assert times == [0, 100_000_000, 130_000_000, 200_000_000]


# --------------------------------------------------------------------------- payloads
def test_payloads_validate_against_their_schemas(tmp_path):
    path = tmp_path / "schema.mcap"
    record_run(path, 50)
    msgs = read_all(path)
    try:
        import jsonschema
    except ImportError:  # pragma: no cover - the structural checks below still run
        jsonschema = None
    for topic, name, schema_data, _, _, payload in msgs:
        if topic not in ("/events", "/log", "/robot_description"):
            continue
        schema = json.loads(schema_data)
        if jsonschema is not None:
            jsonschema.validate(payload, schema)
        for key in schema.get("required", []):
            assert key in payload, (topic, key)
    tf = by_topic(msgs)["/tf"][0]
    assert tf[1] == "foxglove.FrameTransforms"
    payload = tf[5]
    assert set(payload) == {"timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"}
    assert set(payload["timestamp"]) == {"sec", "nsec"}
    assert set(payload["translation"]) == {"x", "y", "z"} and set(payload["rotation"]) == {"x", "y", "z", "w"}
    # the schema stored is Foxglove's published FrameTransforms (foxglove-schemas-protobuf), not a copy
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    stored = {f.name: f for f in FileDescriptorSet.FromString(tf[2]).file}
    published = FileDescriptorSet()
    FrameTransforms.DESCRIPTOR.file.CopyToProto(published.file.add())
    assert stored["foxglove/FrameTransforms.proto"] == published.file[0]
    log = by_topic(msgs)["/log"]
    assert [m[5]["level"] for m in log] == [2, 3]  # foxglove.LogLevel INFO, WARNING
    assert log[1][5]["timestamp"] == {"sec": 0, "nsec": 26_000_000}


def test_numeric_topics_are_protobuf_doubles_in_field_order(tmp_path):
    """A numeric topic's stored schema is one double per number and a packed repeated double per
    array, numbered in the first sample's order; the message parses with Google's runtime alone."""
    from google.protobuf.descriptor_pb2 import FieldDescriptorProto as F, FileDescriptorSet
    from google.protobuf.descriptor_pool import DescriptorPool
    from google.protobuf.message_factory import GetMessageClass

    path = tmp_path / "pb.mcap"
    record_run(path, 3, events=False)
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        channel = next(c for c in summary.channels.values() if c.topic == "/joints/position")
        schema = summary.schemas[channel.schema_id]
        raw = [m.data for _, c, m in reader.iter_messages(topics=["/joints/position"])]
    assert (schema.encoding, channel.message_encoding, schema.name) == ("protobuf", "protobuf", "sms.topic.joints__position")
    fds = FileDescriptorSet.FromString(schema.data)
    (field,) = fds.file[0].message_type[0].field
    assert (field.name, field.number, field.type, field.label) == ("q", 1, F.TYPE_DOUBLE, F.LABEL_REPEATED)
    pool = DescriptorPool()
    pool.Add(fds.file[0])
    cls = GetMessageClass(pool.FindMessageTypeByName(schema.name))
    assert list(cls.FromString(raw[2]).q) == list(scalars_of(2)["/joints/position"]["q"])
    # packed: tag (1 << 3 | 2), length 32, then the four doubles' bytes as they are in memory
    assert raw[2] == bytes([0x0A, 32]) + np.asarray(scalars_of(2)["/joints/position"]["q"], "<f8").tobytes()


FOXGLOVE_FIELD_TYPES = {"boolean", "string", "number", "integer", "object", "array"}


def assert_foxglove_parseable(schema: dict, where: str) -> None:
    """The subset of JSON Schema that Foxglove's parseJsonSchema (mcap-support) accepts."""
    assert schema.get("type") == "object", where
    assert isinstance(schema.get("properties"), dict), f"{where}: an object needs a properties map"
    for name, field in schema["properties"].items():
        path = f"{where}.{name}"
        if "oneOf" in field:
            assert all(isinstance(alt.get("const"), (int, float)) for alt in field["oneOf"]), path
            continue
        assert isinstance(field.get("type"), str) and field["type"] in FOXGLOVE_FIELD_TYPES, f"{path}: type {field.get('type')!r}"
        assert field.get("contentEncoding") in (None, "base64"), path
        if field["type"] == "object":
            assert_foxglove_parseable(field, path)
        elif field["type"] == "array":
            item_type = field["items"].get("type")
            assert isinstance(item_type, str) and item_type in FOXGLOVE_FIELD_TYPES - {"array"}, f"{path}[]"
            if item_type == "object":
                assert_foxglove_parseable(field["items"], path + "[]")


def test_schemas_are_in_the_subset_foxglove_parses(tmp_path):
    path = tmp_path / "fox.mcap"
    record_run(path, 5)
    with open(path, "rb") as f:
        schemas = make_reader(f).get_summary().schemas.values()
    assert {s.encoding for s in schemas} == {"jsonschema", "protobuf"}
    for schema in schemas:
        if schema.encoding == "jsonschema":
            assert_foxglove_parseable(json.loads(schema.data), schema.name)
    assert {s.name for s in schemas} >= {"foxglove.FrameTransforms", "foxglove.Log", "sms.Event", "sms.topic.attitude"}


def test_tf_reconstructs_world_poses_with_pinocchio(tmp_path):
    """Composing the recorded parent→child transforms along the tree gives back the world poses."""
    pin = pytest.importorskip("pinocchio")
    path = tmp_path / "tf.mcap"
    record_run(path, 20, events=False)
    tf = by_topic(read_all(path))["/tf"]
    for i in range(20):
        msgs = {m[5]["child_frame_id"]: m[5] for m in tf if m[3] == round(i * 0.001 * 1e9)}
        world = {"world": pin.SE3.Identity()}
        for link in LINKS:  # parents come before children in LINKS
            p = msgs[link]
            tr, ro = p["translation"], p["rotation"]
            rel = pin.XYZQUATToSE3(np.array([tr["x"], tr["y"], tr["z"], ro["x"], ro["y"], ro["z"], ro["w"]]))
            world[link] = world[p["parent_frame_id"]] * rel
        expected = world_poses(i)
        for row, link in enumerate(LINKS):
            ref = pin.XYZQUATToSE3(expected[row])
            got = world[link]
            assert np.allclose(got.translation, ref.translation, atol=1e-12)  # doubles recorded exactly
            assert np.allclose(got.rotation, ref.rotation, atol=1e-12)


@pytest.mark.parametrize("n, python_below", [(15, 0), (15, 100), (4, 8)])
def test_relative_poses_match_pinocchio(n, python_below):
    """Both implementations (vectorised, plain Python) against Pinocchio's SE3 algebra."""
    pin = pytest.importorskip("pinocchio")
    rng = np.random.default_rng(7 + n)
    placements = [pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3)) for _ in range(n)]
    world = np.array([pin.SE3ToXYZQUAT(m) for m in placements])
    parents = [-1] + [int(rng.integers(0, i)) for i in range(1, n)]
    rel = RelativePoses(parents, python_below=python_below)(world)
    for i, p in enumerate(parents):
        ref = (pin.SE3.Identity() if p < 0 else placements[p]).actInv(placements[i])
        got = pin.XYZQUATToSE3(rel[i])
        assert np.allclose(got.homogeneous, ref.homogeneous, atol=1e-12)
        assert abs(np.linalg.norm(rel[i, 3:]) - 1) < 1e-14


def test_odd_link_names_and_numpy_time(tmp_path):
    """Names with characters that mean something to the encoder (%, N, quotes) survive verbatim."""
    path = tmp_path / "names.mcap"
    links = ["BASE N%d", 'arm "1"', "ärm_2"]
    rec = McapRecorder(path, mission_text="", mission_name="m", model_summary={}, urdf_text=None, versions={})
    rec.add_transform_tree(links, ["world", "BASE N%d", 'arm "1"'])
    with rec:
        rec.write_step(np.float64(0.25), transforms=world_poses(0, 3), scalars={"/n": {"N": np.float32(1.5), "joint-1 %d": 2.0}})
    msgs = by_topic(read_all(path))
    assert [(m[5]["parent_frame_id"], m[5]["child_frame_id"]) for m in msgs["/tf"]] == list(zip(["world", *links[:2]], links))
    assert msgs["/tf"][0][3] == 250_000_000 and msgs["/n"][0][5] == {"N": 1.5, "joint-1 %d": 2.0}


def test_scalar_values_round_trip(tmp_path):
    path = tmp_path / "values.mcap"
    record_run(path, 30, events=False)
    topics = by_topic(read_all(path))
    for k, m in enumerate(topics["/attitude"]):
        assert m[5] == scalars_of(k)["/attitude"]  # exact: binary doubles, no decimal rounding
    q = [m[5]["q"] for m in topics["/joints/position"]]
    assert q[29] == list(scalars_of(29)["/joints/position"]["q"])


def test_non_finite_values(tmp_path):
    path = tmp_path / "nan.mcap"
    rec = make_recorder(path)
    w = world_poses(0)
    w_bad = w.copy()
    w_bad[2, 0] = np.nan  # arm_2 (and so its child arm_3, relative to it) become unknown
    with rec:
        rec.write_step(0.0, transforms=w, scalars={"/x": {"a": 1.0, "v": np.array([1.0, 2.0])}})
        rec.write_step(0.1, transforms=w_bad, scalars={"/x": {"a": np.inf, "v": np.array([np.nan, 2.0])}})
        rec.write_step(0.2, transforms=w, scalars={"/x": {"a": 3.0, "v": np.array([1.0, 2.0])}})
        rec.finish("diverged", {"reason": "NaN in state", "t": 0.1})
    topics = by_topic(read_all(path))
    x = [m[5] for m in topics["/x"]]
    assert x[0] == {"a": 1.0, "v": [1.0, 2.0]} and x[2] == {"a": 3.0, "v": [1.0, 2.0]}
    assert x[1]["a"] == math.inf and math.isnan(x[1]["v"][0]) and x[1]["v"][1] == 2.0  # kept as they are
    bad = {m[5]["child_frame_id"]: m[5] for m in topics["/tf"] if m[3] == 100_000_000}
    assert sorted(bad) == sorted(LINKS)
    assert math.isnan(bad["arm_2"]["translation"]["x"]) and math.isnan(bad["arm_3"]["translation"]["x"])
    assert all(math.isfinite(v) for v in bad["arm_1"]["translation"].values())
    run = metadata(path)["run"]
    assert run["status"] == "diverged" and run["reason"] == "NaN in state" and run["t"] == "0.1"


def test_metadata_attachment_and_robot_description(tmp_path):
    path = tmp_path / "meta.mcap"
    record_run(path, 100, rate=100)
    meta = metadata(path)
    assert set(meta) == {"mission", "model", "versions", "run"}
    assert meta["mission"]["text"] == MISSION and meta["mission"]["name"] == "test"
    assert meta["mission"]["sha256"] == hashlib.sha256(MISSION.encode()).hexdigest()
    assert json.loads(meta["model"]["mass_kg"]) == 1234.5 and json.loads(meta["model"]["wheels"]) == ["rw1", "rw2", "rw3"]
    assert meta["versions"] == {"sms": "0.1.0", "pinocchio": "4.1"}
    run = meta["run"]
    assert run["status"] == "completed" and run["steps"] == "100" and run["samples"] == "10" and run["events"] == "2"
    assert float(run["sim_time_s"]) == pytest.approx(0.099) and float(run["last_sample_s"]) == pytest.approx(0.09)
    with open(path, "rb") as f:
        attachments = list(make_reader(f).iter_attachments())
    assert [(a.name, a.media_type, a.data.decode()) for a in attachments] == [("robot.urdf", "application/xml", URDF)]
    desc = by_topic(read_all(path))["/robot_description"]
    assert desc[0][5] == {"data": URDF} and desc[0][3] == 0


def test_streaming_reader_and_data_crc(tmp_path):
    """The non-seeking reader (which checks the data-section CRC) reads the same messages."""
    path = tmp_path / "stream.mcap"
    record_run(path, 300, chunk_size=8192)
    with open(path, "rb") as f:
        streamed = [(c.topic, m.log_time, m.data) for _, c, m in NonSeekingReader(f, validate_crcs=True).iter_messages()]
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        indexed = [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f, validate_crcs=True).iter_messages(log_time_order=False)]
    assert summary.statistics.chunk_count > 10
    assert sorted(streamed) == sorted(indexed) and len(indexed) == summary.statistics.message_count


@pytest.mark.parametrize("compression", ["lz4", ""])
def test_other_chunk_compressions(tmp_path, compression):
    path = tmp_path / f"c{compression}.mcap"
    record_run(path, 200, chunk_size=8192, compression=compression)
    info = inspect_recording(path)
    assert info["compression"] == [compression or "none"]
    assert len(by_topic(read_all(path))["/tf"]) == 200 * len(LINKS)


# --------------------------------------------------------------------------- determinism
def test_same_inputs_same_bytes(tmp_path):
    a, b = tmp_path / "a.mcap", tmp_path / "sub" / "b.mcap"
    record_run(a, 700, rate=200, chunk_size=16384)
    time.sleep(0.01)  # a different wall-clock time must not matter
    record_run(b, 700, rate=200, chunk_size=16384)
    digest = lambda p: hashlib.sha256(Path(p).read_bytes()).hexdigest()  # noqa: E731
    assert digest(a) == digest(b)
    c = tmp_path / "c.mcap"
    rec = make_recorder(c, rate=200, chunk_size=16384)
    with rec:
        for i in range(700):
            rec.write_step(i * 0.001, transforms=world_poses(i), scalars=scalars_of(i + (i == 650)))
    assert digest(c) != digest(a)


# --------------------------------------------------------------------------- ending
def test_exception_in_body_finalises(tmp_path):
    path = tmp_path / "exc.mcap"
    rec = make_recorder(path)
    with pytest.raises(ZeroDivisionError):
        with rec:
            for i in range(10):
                rec.write_step(i * 0.01, transforms=world_poses(i), scalars=scalars_of(i))
            1 / 0
    assert len(by_topic(read_all(path))["/attitude"]) == 10
    run = metadata(path)["run"]
    assert run["status"] == "failed" and run["exception"] == "ZeroDivisionError"


def test_keyboard_interrupt_in_body_finalises(tmp_path):
    path = tmp_path / "kbi.mcap"
    rec = make_recorder(path)
    with pytest.raises(KeyboardInterrupt):
        with rec:
            for i in range(10):
                rec.write_step(i * 0.01, transforms=world_poses(i), scalars=scalars_of(i))
            raise KeyboardInterrupt
    assert metadata(path)["run"]["status"] == "interrupted"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # handler restored


def test_sigint_is_deferred_while_writing(tmp_path):
    """A SIGINT landing inside a write is held until the write is complete, then raised."""
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("SIGINT handler is not Python's default here")
    path = tmp_path / "defer.mcap"
    rec = make_recorder(path)
    with pytest.raises(KeyboardInterrupt):
        with rec:
            rec.write_step(0.0, transforms=world_poses(0), scalars=scalars_of(0))
            rec._busy = True  # as inside a write
            signal.raise_signal(signal.SIGINT)  # held, not raised
            assert rec._pending_interrupt
            rec._end_busy()  # the write completes: now it is raised
    assert metadata(path)["run"]["status"] == "interrupted"
    with pytest.raises(KeyboardInterrupt):
        with make_recorder(tmp_path / "direct.mcap"):
            signal.raise_signal(signal.SIGINT)  # outside a write: raised at once
    assert metadata(tmp_path / "direct.mcap")["run"]["status"] == "interrupted"


CHILD = textwrap.dedent(
    """
    import sys
    import numpy as np
    from sms_cli.recording.recorder import McapRecorder

    links = ["base_link", "a", "b", "c"]
    rec = McapRecorder(sys.argv[1], mission_text="m", mission_name="m", model_summary={}, urdf_text="<robot/>",
                       versions={}, record_rate_hz=None, chunk_size=4096)
    rec.add_transform_tree(links, ["world", "base_link", "a", "b"])
    w = np.zeros((4, 7)); w[:, 6] = 1.0
    try:
        with rec:
            i = 0
            while True:
                w[:, 0] = i * 1e-3
                rec.write_step(i * 0.01, transforms=w, scalars={"/s": {"i": float(i), "v": w[:, 0]}})
                if i == 200:
                    print("ready", flush=True)
                i += 1
                if i > 10_000_000:
                    break
    except KeyboardInterrupt:
        sys.exit(130)
    sys.exit(0)
    """
)


@pytest.mark.parametrize("delay", [0.0, 0.05, 0.3])
def test_sigint_subprocess_leaves_readable_file(tmp_path, delay):
    path = tmp_path / "int.mcap"
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.Popen([sys.executable, str(script), str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 130
    finally:
        if proc.poll() is None:
            proc.kill()
    msgs = read_all(path)
    topics = by_topic(msgs)
    run = metadata(path)["run"]
    assert run["status"] == "interrupted"
    samples = int(run["samples"])
    assert samples > 200
    assert len(topics["/s"]) == samples and len(topics["/tf"]) == 4 * samples
    assert [m[5]["i"] for m in topics["/s"]] == [float(i) for i in range(samples)]
    info = inspect_recording(path)
    assert info["status"] == "interrupted"


def test_killed_process_leaves_complete_chunks(tmp_path):
    """SIGKILL: no summary, but every complete chunk is on disk behind the writer's end marker, so
    the file opens in the mcap reader as it is; inspect says the run was killed."""
    path = tmp_path / "killed.mcap"
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.Popen([sys.executable, str(script), str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        proc.kill()
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    topics = by_topic(read_all(path))
    assert len(topics["/s"]) >= 200 and len(topics["/tf"]) == 4 * len(topics["/s"])
    info = inspect_recording(path)
    assert info["status"] == "killed" and "sms inspect --repair" in info["note"]
    assert info["messages"] >= 2 * 200  # ≥ 200 samples × (1 /tf + 1 /s) were in complete chunks


def test_finish_is_idempotent_and_closes(tmp_path):
    path = tmp_path / "idem.mcap"
    rec = make_recorder(path)
    with rec:
        rec.write_step(0.0, transforms=world_poses(0), scalars=scalars_of(0))
        rec.finish("completed")
        before = path.read_bytes()
        rec.finish("diverged")  # no effect
    assert path.read_bytes() == before and rec.status == "completed"
    with pytest.raises(RuntimeError):
        rec.write_step(1.0, transforms=world_poses(0), scalars=scalars_of(0))
    with pytest.raises(RuntimeError):
        rec.write_event(1.0, "late")


def test_empty_recording_is_valid(tmp_path):
    path = tmp_path / "empty.mcap"
    with make_recorder(path):
        pass
    info = inspect_recording(path)
    assert info["status"] == "completed"
    assert {t["topic"]: t["messages"] for t in info["topics"]}["/robot_description"] == 1


# --------------------------------------------------------------------------- misuse
def test_bad_arguments(tmp_path):
    kw = dict(mission_text="", mission_name="m", model_summary={}, urdf_text=None, versions={})
    with pytest.raises(ValueError, match="record_rate_hz"):
        McapRecorder(tmp_path / "x.mcap", record_rate_hz=0, **kw)
    rec = McapRecorder(tmp_path / "x.mcap", **kw)
    with pytest.raises(ValueError, match="neither"):
        rec.add_transform_tree(["a", "b"], ["world", "c"])
    with pytest.raises(ValueError, match="cycle"):
        rec.add_transform_tree(["a", "b"], ["b", "a"])
    with pytest.raises(ValueError, match="duplicate"):
        rec.add_transform_tree(["a", "a"], ["world", "world"])
    rec.add_transform_tree(["a", "b"], ["world", "a"])
    with rec:
        with pytest.raises(ValueError, match="shape"):
            rec.write_step(0.0, transforms=np.zeros((3, 7)))
        with pytest.raises(ValueError, match="topic"):
            rec.write_step(0.0, scalars={"no_slash": {"a": 1.0}})
        with pytest.raises(ValueError, match="reserved"):
            rec.write_step(0.0, scalars={"/tf": {"a": 1.0}})
        with pytest.raises(ValueError, match="non-empty"):
            rec.write_step(0.0, scalars={"/ok": {"": 1.0}})
        rec.write_step(0.0, scalars={"/ok": {"a": 1.0, "v": np.zeros(3)}})
        with pytest.raises(ValueError, match="changed"):
            rec.write_step(0.1, scalars={"/ok": {"a": 1.0, "v": np.zeros(4)}})
        with pytest.raises(ValueError, match="changed"):
            rec.write_step(0.1, scalars={"/ok": {"a": 1.0}})
        ok = {"/ok": {"a": 1.0, "v": np.zeros(3)}}
        assert rec.write_step(0.2, scalars=ok)
        with pytest.raises(ValueError, match="backwards"):
            rec.write_step(0.1, scalars=ok, force=True)
        with pytest.raises(ValueError, match="finite"):
            rec.write_step(float("nan"), scalars=ok, force=True)
        rec.write_event(1.0, "a")
        with pytest.raises(ValueError, match="backwards"):
            rec.write_event(0.5, "b")
        with pytest.raises(ValueError, match="level"):
            rec.write_event(2.0, "c", level="loud")
    # the failed calls left the file consistent
    topics = by_topic(read_all(tmp_path / "x.mcap"))
    assert len(topics["/ok"]) == 2 and len(topics["/events"]) == 1


# --------------------------------------------------------------------------- sms inspect
def test_inspect_summary(tmp_path):
    path = tmp_path / "insp.mcap"
    record_run(path, 1001, rate=100)
    info = inspect_recording(path)
    topics = {t["topic"]: t for t in info["topics"]}
    assert topics["/tf"]["messages"] == 101 and topics["/tf"]["samples"] == 101  # one FrameTransforms per sample
    assert topics["/attitude"]["messages"] == 101 and topics["/attitude"]["schema"] == "sms.topic.attitude"
    assert topics["/attitude"]["rate_hz"] == pytest.approx(100.0)
    assert topics["/tf"]["schema"] == "foxglove.FrameTransforms"
    assert info["start_s"] == 0.0 and info["end_s"] == pytest.approx(1.0) and info["status"] == "completed"
    assert info["metadata"] == ["mission", "model", "run", "versions"] and info["attachments"] == ["robot.urdf"]
    with open(path, "rb") as f:
        stats = make_reader(f).get_summary().statistics
    assert info["messages"] == stats.message_count


def test_cli_inspect(tmp_path):
    from typer.testing import CliRunner

    from sms_cli.cli import app

    path = tmp_path / "cli.mcap"
    record_run(path, 200, rate=50)
    runner = CliRunner()
    result = runner.invoke(app, ["inspect", str(path)])
    assert result.exit_code == 0, result.output
    assert "/wheels/speed" in result.output and "foxglove.FrameTransform" in result.output and "completed" in result.output
    result = runner.invoke(app, ["inspect", str(path), "--json"])
    assert result.exit_code == 0
    data = json.loads(result.output)
    assert {t["topic"]: t["messages"] for t in data["topics"]}["/attitude"] == 10

    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"this is not an mcap file\n" * 10)
    result = runner.invoke(app, ["inspect", str(garbage)])
    assert result.exit_code == 2
    assert str(garbage) in result.output and "not an MCAP file" in result.output
    assert "Traceback" not in result.output

    truncated = tmp_path / "truncated.mcap"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    result = runner.invoke(app, ["inspect", str(truncated)])
    assert result.exit_code == 2 and str(truncated) in result.output and "unfinished" in result.output

    result = runner.invoke(app, ["inspect", str(tmp_path / "missing.mcap")])
    assert result.exit_code == 2 and "missing.mcap" in result.output
