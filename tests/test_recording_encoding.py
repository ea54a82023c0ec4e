"""The recorder's encoding (sms_cli/recording/encoding.py) against independent implementations:
Google's protobuf runtime serialising Foxglove's published FrameTransforms and the topic messages
(byte for byte where proto3 writes every field, i.e. no zero values), and the block path
(select + write_block) against the per-sample path (write_step): same samples, same bytes."""

from __future__ import annotations

import numpy as np
import pytest
from google.protobuf.descriptor_pool import DescriptorPool
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from google.protobuf.message_factory import GetMessageClass
from test_recorder import LINKS, make_recorder, read_all, scalars_of, world_poses

from sms_cli.recording import schemas
from sms_cli.recording.encoding import HEADER_BYTES, Template, Templates, frame_transform, varint
from sms_cli.recording.recorder import _topic_template


def _payloads(templates: list[Template], values: np.ndarray, ts: np.ndarray) -> list[list[bytes]]:
    """The payload of every message of every sample (record framing stripped and checked)."""
    compiled = Templates(templates)
    channels = np.arange(1, len(templates) + 1, dtype=np.int64)
    out, end, offsets = compiled.encode(values, channels, 7, ts)
    ends = np.append(offsets[1:], end)
    data = out[:end].tobytes()
    rows = []
    for s in range(len(ts)):
        row = []
        for j in range(len(templates)):
            a, b = int(offsets[s * len(templates) + j]), int(ends[s * len(templates) + j])
            rec = data[a:b]
            assert rec[0] == 5 and int.from_bytes(rec[1:9], "little") == len(rec) - 9  # opcode, record length
            assert int.from_bytes(rec[9:11], "little") == channels[j] and int.from_bytes(rec[11:15], "little") == 7 + s
            assert int.from_bytes(rec[15:23], "little") == int.from_bytes(rec[23:31], "little") == ts[s]
            row.append(rec[HEADER_BYTES:])
        rows.append(row)
    return rows


@pytest.mark.parametrize("seconds", [0.123456789, 3.0e3 + 0.5, 7.2e5 + 1e-9, 4.2e9 + 0.25])
def test_frame_transforms_bytes_equal_googles_serialisation(seconds):
    """Every link's FrameTransform, with the varint timestamp at sizes from 1 to 5 bytes of seconds."""
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

    rng = np.random.default_rng(3)
    links = ["base", "arm_1", "a" * 200]  # a 200-byte name: two-byte length varints
    parents = ["world", "base", "arm_1"]
    tpl = Template()
    for link, parent in zip(links, parents):
        frame_transform(tpl, 1, parent, link)
    values = rng.normal(size=(3, 7 * len(links)))
    ts = np.rint((seconds + np.arange(3) * 1e-3) * 1e9).astype(np.int64)
    for s, (payload,) in enumerate(_payloads([tpl.done()], values, ts)):
        ref = FrameTransforms()
        for k, (link, parent) in enumerate(zip(links, parents)):
            t = ref.transforms.add(parent_frame_id=parent, child_frame_id=link)
            t.timestamp.seconds, t.timestamp.nanos = divmod(int(ts[s]), 1_000_000_000)
            v = values[s, 7 * k:7 * k + 7]
            t.translation.x, t.translation.y, t.translation.z = v[:3]
            t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = v[3:]
        if ts[s] % 1_000_000_000 and ts[s] >= 1_000_000_000:
            assert payload == ref.SerializeToString()
        assert FrameTransforms.FromString(payload) == ref  # zero seconds or nanos: omitted by Google's writer


def test_topic_messages_bytes_equal_googles_serialisation():
    """A topic of numbers and arrays (a field number past 15: two-byte keys) through its stored schema."""
    spec = [(f"f{k}", 0) for k in range(17)] + [("arr", 5), ("one", 1)]
    name, data, meta = schemas.numeric_topic_descriptor("/group/topic", spec)
    pool = DescriptorPool()
    pool.Add(FileDescriptorSet.FromString(data).file[0])
    cls = GetMessageClass(pool.FindMessageTypeByName(name))
    rng = np.random.default_rng(5)
    values = rng.normal(size=(4, 17 + 5 + 1)) * 10.0 ** rng.integers(-300, 300, size=(4, 23))
    values[3, 2] = np.nan
    values[3, 18] = -np.inf
    ts = np.arange(1, 5, dtype=np.int64) * 1_000_000_007
    for s, (payload,) in enumerate(_payloads([_topic_template(spec)], values, ts)):
        ref = cls(**{f"f{k}": values[s, k] for k in range(17)}, arr=values[s, 17:22], one=values[s, 22:23])
        assert payload == ref.SerializeToString()
        back = cls.FromString(payload)
        np.testing.assert_array_equal([getattr(back, f"f{k}") for k in range(17)] + list(back.arr) + list(back.one), values[s])
    assert meta == {}  # identifiers: no name map


def test_field_identifiers_keep_names_and_make_others_unique():
    names = ["rw1", "joint-1", "joint_1", "2nd", "a b", "a_b"]
    assert schemas.field_identifiers(names) == ["rw1", "joint_1_2", "joint_1", "_2nd", "a_b_2", "a_b"]
    assert varint(300) == b"\xac\x02" and varint(0) == b"\x00"


def _record(path, rate, block: bool, n=400, dt=0.001):
    rec = make_recorder(path, rate)
    with rec:
        if not block:
            for i in range(n):
                rec.write_step(i * dt, transforms=world_poses(i), scalars=scalars_of(i))
            return rec
        for lo, hi in ((0, 150), (150, 151), (151, n)):  # several blocks, one of a single step
            times = np.arange(lo, hi) * dt
            idx = rec.select(times)
            rows = [lo + int(k) for k in idx]
            if not rows:
                continue
            per = [scalars_of(i) for i in rows]
            scalars = {topic: {name: np.array([p[topic][name] for p in per]) for name in per[0][topic]} for topic in per[0]}
            rec.write_block(times[idx], transforms=np.array([world_poses(i) for i in rows]), scalars=scalars)
    return rec


@pytest.mark.parametrize("rate", [None, 7])
def test_block_writes_the_same_messages_as_steps(tmp_path, rate):
    a = _record(tmp_path / "step.mcap", rate, block=False)
    b = _record(tmp_path / "block.mcap", rate, block=True)
    assert a.samples == b.samples and a.steps == b.steps
    ma, mb = read_all(tmp_path / "step.mcap"), read_all(tmp_path / "block.mcap")
    key = lambda m: (m[3], m[0])  # noqa: E731 (time, topic): chunking may order same-time messages differently
    assert sorted(ma, key=key) == sorted(mb, key=key)  # exact: one encoder, binary doubles
    tf = [m for m in mb if m[0] == "/tf"]
    assert len(tf) == len(LINKS) * b.samples


@pytest.mark.parametrize("block", [False, True])
def test_message_indexes_point_at_their_messages(tmp_path, block):
    """Every MessageIndex entry (the mcap library's reader parses them) points, in its chunk's decompressed
    records, at a Message record of that channel and log time, and each chunk's messages are indexed once: the
    block path's index arrays (``McapWriter.add_index_blocks``) and the per-step path's lists alike."""
    import struct

    import zstandard
    from mcap.records import Chunk, MessageIndex
    from mcap.stream_reader import StreamReader

    _record(tmp_path / "r.mcap", None, block=block, n=3000)
    chunk, seen, n_chunks = None, {}, 0
    with open(tmp_path / "r.mcap", "rb") as f:
        for r in StreamReader(f, emit_chunks=True).records:
            if isinstance(r, Chunk):
                assert r.compression == "zstd"
                chunk = zstandard.ZstdDecompressor().decompress(r.data, max_output_size=r.uncompressed_size)
                n_messages = 0
                pos = 0
                while pos < len(chunk):  # count the chunk's Message records (opcode 5)
                    op, length = chunk[pos], struct.unpack_from("<Q", chunk, pos + 1)[0]
                    n_messages += op == 5
                    pos += 9 + length
                seen[id(chunk)] = [n_messages, 0]
                n_chunks += 1
            elif isinstance(r, MessageIndex):
                for log_time, offset in r.records:
                    op, _, channel, _, t_log = struct.unpack_from("<BQHIQ", chunk, offset)
                    assert (op, channel, t_log) == (5, r.channel_id, log_time)
                seen[id(chunk)][1] += len(r.records)
    assert n_chunks > 1 and all(total == indexed for total, indexed in seen.values())


@pytest.mark.parametrize("rate", [None, 7, 10, 333])
def test_select_picks_the_offers_take_picks(tmp_path, rate):
    """``select`` on blocks (random sizes, one-offer and empty blocks; times on a grid of dt = 0.01 s as the loops
    make them by repeated addition, then irregular steps and gaps longer than the period, then offers exactly at
    due times) picks exactly the
    offers that ``take`` at each offer reserves, and leaves the same next due time."""
    rng = np.random.default_rng(11)
    t_grid = np.cumsum(np.full(3000, 0.01))
    t_irr = t_grid[-1] + np.cumsum(rng.choice([1e-4, 0.003, 0.05, 0.31], size=3000))
    times = np.concatenate([t_grid, t_irr])
    if rate:  # offers exactly at due times (``_next_due``'s: the first sample is at times[0]), each just after another
        k = np.arange(int((times[-1] - times[0]) * rate) + 2, int((times[-1] - times[0]) * rate) + 200)
        due = times[0] + (k - 1e-6) * (1.0 / rate)
        times = np.concatenate([times, np.sort(np.concatenate([due, due - 1e-9]))])
    a, b = make_recorder(tmp_path / "a.mcap", rate), make_recorder(tmp_path / "b.mcap", rate)
    with a, b:
        want = [i for i, t in enumerate(times) if a.take(float(t))]
        got, lo = [], 0
        while lo < times.size:
            hi = min(times.size, lo + int(rng.choice([0, 1, 2, 37, 500])))
            got += [lo + int(k) for k in b.select(times[lo:hi])]
            lo = hi
        assert got == want and a._next_t == b._next_t
    assert len(want) > 100
