"""Cost of MCAP recording: µs per recorded sample, µs per skipped call, bytes per 1000 samples.

Scenario: 15 links (a chain under a free-flying base: parent-relative /tf) + 8 numeric topics
(attitude, attitude error, base rate, wheel speeds and torques as named fields, joint positions
and torques as 7-arrays, 10 modal amplitudes): 1 /tf (foxglove.FrameTransforms) + 8 = 9 messages per
sample, 57 numbers besides the 105 pose numbers. States change every sample (a random walk), as in a simulation.

    /tmp/venv/bin/python benches/bench_recorder.py [--samples 5000] [--repeats 5]

Also the block path (``select`` + ``write_block``, one compiled encoding pass per block), which
both simulation engines use. Times are CPU time of this process (``time.process_time``), best of several runs. For
comparison it also times the same messages through ``mcap.writer.Writer`` (the package's
writer, zstd chunks), which is what the recorder would cost without its own message packing.
"""

from __future__ import annotations

import argparse
import io
import os
import tempfile
import time

import numpy as np

from sms_cli.recording.recorder import McapRecorder

N_LINKS = 15
# CPU time of this process: less disturbed than wall time when other jobs share the machine
CLOCK = time.process_time


def scenario(n_samples: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    poses = np.zeros((n_samples, N_LINKS, 7))
    poses[:, :, :3] = np.cumsum(rng.normal(scale=1e-3, size=(n_samples, N_LINKS, 3)), axis=0) + rng.normal(size=(N_LINKS, 3))
    q = rng.normal(size=(n_samples, N_LINKS, 4))
    poses[:, :, 3:] = q / np.linalg.norm(q, axis=2, keepdims=True)
    x = np.cumsum(rng.normal(scale=1e-3, size=(n_samples, 57)), axis=0)
    scalars = []
    for row in x:
        r = row.tolist()
        scalars.append(
            {
                "/attitude": {"roll": r[0], "pitch": r[1], "yaw": r[2]},
                "/attitude/error": {"roll": r[3], "pitch": r[4], "yaw": r[5]},
                "/base/rate": {"wx": r[6], "wy": r[7], "wz": r[8]},
                "/wheels/speed": {"rw1": r[9], "rw2": r[10], "rw3": r[11], "rw4": r[12]},
                "/wheels/torque": {"rw1": r[13], "rw2": r[14], "rw3": r[15], "rw4": r[16]},
                "/joints/position": {"q": row[17:24]},
                "/joints/torque": {"tau": row[24:31]},
                "/modes": {"eta": row[31:41]},
            }
        )
    links = ["base_link"] + [f"link_{i}" for i in range(1, N_LINKS)]
    parents = ["world"] + links[:-1]
    return links, parents, poses, scalars


def recorder(path: str, rate: float | None, links, parents) -> McapRecorder:
    rec = McapRecorder(
        path,
        mission_text="name: bench\n",
        mission_name="bench",
        model_summary={"dof": 21},
        urdf_text="<robot name='bench'/>",
        versions={"sms": "bench"},
        record_rate_hz=rate,
    )
    rec.add_transform_tree(links, parents)
    return rec


def bench_recorded(n: int, links, parents, poses, scalars, tmp: str) -> tuple[float, float, float]:
    path = os.path.join(tmp, "recorded.mcap")
    rec = recorder(path, None, links, parents)
    with rec:
        t0 = CLOCK()
        for i in range(n):
            rec.write_step(i * 0.01, transforms=poses[i], scalars=scalars[i])
        t1 = CLOCK()
        rec.finish("completed")
        t2 = CLOCK()
    size = os.path.getsize(path)
    return (t1 - t0) / n * 1e6, (t2 - t0) / n * 1e6, size / n * 1000


def bench_block(n: int, links, parents, poses, scalars, tmp: str, block: int = 512) -> tuple[float, float]:
    """The same samples through select + write_block (the engines' path), blocks of ``block``;
    the per-field arrays are built outside the timed region, as the engines hold them."""
    path = os.path.join(tmp, "block.mcap")
    rec = recorder(path, None, links, parents)
    times = np.arange(n) * 0.01
    cols = {topic: {name: np.array([sc[topic][name] for sc in scalars]) for name in scalars[0][topic]} for topic in scalars[0]}
    with rec:
        t0 = CLOCK()
        for lo in range(0, n, block):
            hi = min(lo + block, n)
            idx = rec.select(times[lo:hi])
            rec.write_block(times[lo:hi][idx], transforms=poses[lo:hi][idx],
                            scalars={t: {f: a[lo:hi][idx] for f, a in fields.items()} for t, fields in cols.items()})
        t1 = CLOCK()
    return (t1 - t0) / n * 1e6, os.path.getsize(path) / n * 1000


def bench_foxglove_sdk(n: int, links, parents, poses, scalars, tmp: str) -> tuple[float, float]:
    """The same samples through Foxglove's maintained SDK writer (``foxglove-sdk``, Rust core), in
    µs per sample: (a) used as documented, /tf as ``foxglove.messages.FrameTransforms`` objects on a
    ``FrameTransformsChannel`` and the numeric topics as JSON dicts; (b) its writer alone, logging
    the recorder's own protobuf payloads (read from a recording beforehand). The parent-relative
    poses are computed outside the timed region (the recorder's figure includes them)."""
    import foxglove
    from foxglove.channels import FrameTransformsChannel
    from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3

    from sms_cli.recording.frames import RelativePoses

    pidx = [-1 if p == "world" else links.index(p) for p in parents]
    rel = np.array([RelativePoses(pidx)(poses[i]) for i in range(n)])
    rows = [[{k: (v.tolist() if isinstance(v, np.ndarray) else float(v)) for k, v in fields.items()}
             for fields in sc.values()] for sc in scalars]
    topics = list(scalars[0])

    ctx = foxglove.Context()
    path = os.path.join(tmp, "sdk_native.mcap")
    with foxglove.open_mcap(path, allow_overwrite=True, context=ctx):
        tf = FrameTransformsChannel("/tf", context=ctx)
        chans = [foxglove.Channel(t, context=ctx) for t in topics]
        t0 = CLOCK()
        for i in range(n):
            ts = int(i * 10_000_000)
            sec, nsec = divmod(ts, 1_000_000_000)
            r = rel[i]
            tf.log(FrameTransforms(transforms=[
                FrameTransform(timestamp=Timestamp(sec=sec, nsec=nsec), parent_frame_id=p, child_frame_id=c,
                               translation=Vector3(x=r[k, 0], y=r[k, 1], z=r[k, 2]),
                               rotation=Quaternion(x=r[k, 3], y=r[k, 4], z=r[k, 5], w=r[k, 6]))
                for k, (c, p) in enumerate(zip(links, parents))]), log_time=ts)
            for ch, row in zip(chans, rows[i]):
                ch.log(row, log_time=ts)
        t1 = CLOCK()
    native = (t1 - t0) / n * 1e6

    from mcap.reader import make_reader

    src = os.path.join(tmp, "sdk_payloads.mcap")
    rec = recorder(src, None, links, parents)
    with rec:
        for i in range(n):
            rec.write_step(i * 0.01, transforms=poses[i], scalars=scalars[i])
    with open(src, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        msgs = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages()]
    ctx = foxglove.Context()
    path = os.path.join(tmp, "sdk_bytes.mcap")
    with foxglove.open_mcap(path, allow_overwrite=True, context=ctx):
        chans = {}
        for c in summary.channels.values():
            sch = summary.schemas[c.schema_id]
            chans[c.topic] = foxglove.Channel(c.topic, schema=foxglove.Schema(name=sch.name, encoding=sch.encoding, data=sch.data),
                                              message_encoding=c.message_encoding, context=ctx)
        items = [(chans[topic], t, data) for topic, t, data in msgs if topic in chans]
        t0 = CLOCK()
        for ch, t, data in items:
            ch.log(data, log_time=t)
        t1 = CLOCK()
    return native, (t1 - t0) / n * 1e6


def bench_world_only(n: int, links, poses, scalars, tmp: str) -> float:
    path = os.path.join(tmp, "world.mcap")
    rec = recorder(path, None, links, ["world"] * len(links))
    with rec:
        t0 = CLOCK()
        for i in range(n):
            rec.write_step(i * 0.01, transforms=poses[i], scalars=scalars[i])
        t1 = CLOCK()
    return (t1 - t0) / n * 1e6


def bench_small(n: int, tmp: str) -> float:
    """A rigid spacecraft with three wheels (base + 3 wheel links, 5 topics of 3 numbers)."""
    rng = np.random.default_rng(1)
    links = ["base_link", "rw1", "rw2", "rw3"]
    rec = recorder(os.path.join(tmp, "small.mcap"), None, links, ["world", "base_link", "base_link", "base_link"])
    poses = np.zeros((n, 4, 7))
    q = rng.normal(size=(n, 4, 4))
    poses[:, :, 3:] = q / np.linalg.norm(q, axis=2, keepdims=True)
    x = rng.normal(size=(n, 15)).tolist()
    names = ["/attitude/mrp", "/attitude/error", "/base/rate", "/wheels/speed", "/wheels/torque"]
    scalars = [{name: {"x": r[3 * k], "y": r[3 * k + 1], "z": r[3 * k + 2]} for k, name in enumerate(names)} for r in x]
    with rec:
        t0 = CLOCK()
        for i in range(n):
            rec.write_step(i * 0.1, transforms=poses[i], scalars=scalars[i])
        t1 = CLOCK()
    return (t1 - t0) / n * 1e6


def bench_skipped(n: int, links, parents, poses, scalars, tmp: str) -> tuple[float, float, float]:
    path = os.path.join(tmp, "skipped.mcap")
    rec = recorder(path, 1e-3, links, parents)  # one sample per 1000 s: every later call is skipped
    w, s = poses[0], scalars[0]
    with rec:
        rec.write_step(0.0, transforms=w, scalars=s)
        ts = [1e-4 * (i + 1) for i in range(n)]
        t0 = CLOCK()
        for t in ts:
            rec.write_step(t, transforms=w, scalars=s)
        t1 = CLOCK()
        for t in ts:
            rec.due(t)
        t2 = CLOCK()
        for t in ts:
            pass
        t3 = CLOCK()
        assert rec.samples == 1
    loop = (t3 - t2) / n * 1e6
    return (t1 - t0) / n * 1e6, (t2 - t1) / n * 1e6, loop


def bench_mcap_package(n: int, tmp: str, links, parents, poses, scalars) -> float:
    """The same messages through mcap.writer.Writer (payloads pre-encoded by the recorder)."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    path = os.path.join(tmp, "payloads.mcap")
    rec = recorder(path, None, links, parents)
    with rec:
        for i in range(min(n, 2000)):
            rec.write_step(i * 0.01, transforms=poses[i], scalars=scalars[i])
    with open(path, "rb") as f:
        msgs = [(ch.topic, m.log_time, m.data) for _, ch, m in make_reader(f).iter_messages()]
    buf = io.BytesIO()
    writer = Writer(buf, compression=CompressionType.ZSTD)
    writer.start()
    sid = writer.register_schema("x", "protobuf", b"")
    ids = {topic: writer.register_channel(topic, "protobuf", sid) for topic in sorted({m[0] for m in msgs})}
    items = [(ids[topic], t, data) for topic, t, data in msgs]
    t0 = CLOCK()
    for cid, t, data in items:
        writer.add_message(cid, t, data, t)
    t1 = CLOCK()
    writer.finish()
    return (t1 - t0) / len(items) * 1e6


def best(fn, repeats: int):
    """(min, median) over repeats of fn()'s first result; min is the least disturbed by other load."""
    runs = sorted(fn() for _ in range(repeats))
    first = [r[0] if isinstance(r, tuple) else r for r in runs]
    return min(first), float(np.median(first)), runs[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=5000)
    parser.add_argument("--repeats", type=int, default=5, help="runs per figure; the minimum is reported (and the median)")
    args = parser.parse_args()
    n, reps = args.samples, args.repeats
    links, parents, poses, scalars = scenario(n)
    with tempfile.TemporaryDirectory() as tmp:
        tree, tree_med, (_, with_finish, per_1000) = best(lambda: bench_recorded(n, links, parents, poses, scalars, tmp), reps)
        world, world_med, _ = best(lambda: bench_world_only(n, links, poses, scalars, tmp), reps)
        bulk, bulk_med, (_, bulk_per_1000) = best(lambda: bench_block(n, links, parents, poses, scalars, tmp), reps)
        small, small_med, _ = best(lambda: bench_small(n, tmp), reps)
        skipped, skipped_med, (_, due, loop) = best(lambda: bench_skipped(200_000, links, parents, poses, scalars, tmp), reps)
        pkg, pkg_med, _ = best(lambda: bench_mcap_package(n, tmp, links, parents, poses, scalars), reps)
        try:
            import foxglove  # noqa: F401
        except ImportError:
            sdk = None
        else:
            sdk_native, sdk_native_med, (_, sdk_bytes) = best(lambda: bench_foxglove_sdk(n, links, parents, poses, scalars, tmp), reps)
            sdk = (sdk_native, sdk_native_med, sdk_bytes)
    print(f"recorder benchmark: {N_LINKS} links + 8 numeric topics (9 messages/sample), {n} samples, best of {reps} (median)")
    print(f"  recorded sample, /tf relative to URDF parents : {tree:6.1f} µs ({tree_med:.1f}); incl. finish {with_finish:.1f} µs")
    print(f"  recorded sample, /tf all relative to world    : {world:6.1f} µs ({world_med:.1f})")
    print(f"  recorded sample, blocks of 512 (write_block)  : {bulk:6.1f} µs ({bulk_med:.1f}); "
          f"{bulk_per_1000 / 1e6:.3f} MB per 1000 samples")
    print(f"  recorded sample, small (4 links, 5 topics × 3): {small:6.1f} µs ({small_med:.1f})")
    print(f"  skipped write_step call                       : {skipped:6.3f} µs ({skipped_med:.3f}); due(t) {due:.3f} µs; bare loop {loop:.3f} µs")
    print(f"  file size                                     : {per_1000 / 1e6:6.3f} MB per 1000 samples (zstd level -1)")
    print(f"  for comparison, mcap.writer.Writer.add_message: {pkg:6.2f} µs per message ({pkg_med:.2f}), ×9 = {9 * pkg:.0f} µs per sample before any encoding")
    if sdk is None:
        print("  foxglove-sdk not installed (pip install foxglove-sdk): its writer not measured")
    else:
        sdk_native, sdk_native_med, sdk_bytes = sdk
        print(f"  foxglove-sdk, FrameTransforms objects + JSON  : {sdk_native:6.1f} µs per sample ({sdk_native_med:.1f}); "
              f"ratio to write_block {sdk_native / bulk:.1f}x")
        print(f"  foxglove-sdk writer alone, sms's payloads     : {sdk_bytes:6.1f} µs per sample; ratio to write_block "
              f"{sdk_bytes / bulk:.1f}x (its writer within 20 % of ours: {'yes' if sdk_bytes <= 1.2 * bulk else 'no'})")


if __name__ == "__main__":
    main()
