"""Every topic of a recording decodes with an independent implementation in another language:
Node's ``@mcap/core`` stream reader (CRCs checked) and protobufjs on the schemas stored in the
file, which is how Foxglove decodes protobuf channels (``tests/node/decode.mjs``). The values must
equal those the Python reader gives (``sms_cli.recording.read``: the ``mcap`` reader with Google's
protobuf runtime) exactly, NaN and infinities included.

Needs Node.js and npm (the npm registry on first use: ``npm ci`` into ``tests/node/node_modules``,
pinned by ``tests/node/package-lock.json``); without them the test says why it is skipped.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from test_recorder import LINKS, record_run

from sms_cli.recording.read import messages
from sms_cli.recording.schemas import field_identifiers

NODE_DIR = Path(__file__).parent / "node"


@pytest.fixture(scope="module")
def node_decoder() -> list[str]:
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        pytest.skip("Node.js and npm are not installed: the JavaScript decoder check needs them")
    if not (NODE_DIR / "node_modules" / "@mcap" / "core").is_dir():
        try:
            done = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--ignore-scripts"], cwd=NODE_DIR,
                                  capture_output=True, text=True, timeout=300)
        except subprocess.TimeoutExpired:
            pytest.skip("npm ci did not finish in 300 s (is the npm registry reachable?)")
        if done.returncode != 0:
            pytest.skip(f"npm ci failed (is the npm registry reachable?): {done.stderr[-500:]}")
    return [node, str(NODE_DIR / "decode.mjs")]


def _same(a, b, where: str) -> None:
    """Node's JSON (non-finite numbers as strings, int64 as strings) against the Python values."""
    if isinstance(b, dict):
        assert isinstance(a, dict) and len(a) == len(b), where
        for kb, ident in zip(b, field_identifiers(list(b))):  # Node has the protobuf field names
            _same(a[ident], b[kb], f"{where}.{kb}")
    elif isinstance(b, list):
        assert isinstance(a, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(b, float) and not math.isfinite(b):
        assert a == ("NaN" if math.isnan(b) else ("Infinity" if b > 0 else "-Infinity")), where
    elif isinstance(b, (int, float)) and not isinstance(b, bool):
        assert float(a) == b, where
    else:
        assert a == b, where


def test_every_topic_decodes_the_same_in_node_with_protobufjs(tmp_path, node_decoder):
    path = tmp_path / "run.mcap"
    rec = record_run(path, 300)
    rec2 = tmp_path / "nan.mcap"
    from test_recorder import make_recorder, world_poses

    bad = make_recorder(rec2)
    with bad:
        w = world_poses(1)
        w[2, 0] = np.nan
        bad.write_step(0.5, transforms=w, scalars={"/x": {"a": np.inf, "joint-1": -np.inf, "v": np.array([np.nan, 2.0])}})
    for p in (path, rec2):
        done = subprocess.run(node_decoder + [str(p)], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        js = json.loads(done.stdout)
        py: dict[str, list] = {}
        for topic, log_time, data in messages(p, log_time_order=False):
            py.setdefault(topic, []).append((log_time, data))
        assert set(js) == set(py)
        for topic, rows in py.items():
            assert [int(t) for t, _ in js[topic]] == [t for t, _ in rows], topic
            for (_, a), (_, b) in zip(js[topic], rows):
                if topic == "/tf":  # google.protobuf.Timestamp: Node keeps its field names
                    for tr in b["transforms"]:
                        tr["timestamp"] = {"seconds": tr["timestamp"]["sec"], "nanos": tr["timestamp"]["nsec"]}
                _same(a, b, topic)
    assert rec.samples == 300 and len(js) > 0
    assert len(py["/x"]) == 1 and len(LINKS) == 6
