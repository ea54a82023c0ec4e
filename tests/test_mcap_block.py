"""The recorder's block path (select + write_block, sms_cli/sim/mcap_block.py) against its
per-sample path (write_step) and C's printf: same samples picked, same messages."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_recorder import LINKS, make_recorder, read_all, scalars_of, world_poses

from sms_cli.sim.mcap_block import format_g12


def _format_all(xs: np.ndarray) -> list[str]:
    out = np.zeros(xs.size * 32, dtype=np.uint8)
    texts, pos = [], 0
    for x in xs:
        end = format_g12(float(x), out, pos)
        texts.append(out[pos:end].tobytes().decode())
        pos = end
    return texts


def test_format_g12_is_printf():
    rng = np.random.default_rng(0)
    xs = np.concatenate([
        rng.normal(size=20000) * 10.0 ** rng.integers(-30, 30, 20000),
        rng.integers(-10**7, 10**7, 2000).astype(float),
        [0.0, -0.0, 5e-324, 1e-310, 1.7976931348623157e308, 0.1, 1e-4, 1e-5, 99999999999.95, 1e11, 1e12,
         999999999999.5, 123456789012345.0, -2.5, 1.0 / 3.0, math.pi * 1e-5, 6.02214076e23],
    ])
    mine = _format_all(xs)
    ref = ["%.12g" % x for x in xs]
    differ = [i for i, (a, b) in enumerate(zip(mine, ref)) if a != b]
    # exact ties in the 13th digit can round the other way (the product x·10^k is not exact)
    assert len(differ) <= 2e-4 * xs.size
    for i in differ:
        assert float(mine[i]) == pytest.approx(float(ref[i]), rel=1e-11)
    assert _format_all(np.array([np.nan, np.inf, -np.inf])) == ["null"] * 3


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
    ma, mb = sorted(ma, key=key), sorted(mb, key=key)
    assert [m[:5] for m in ma] == [m[:5] for m in mb]
    differ = 0
    for x, y in zip(ma, mb):
        if x[5] != y[5]:
            differ += 1
            assert json.dumps(x[5], sort_keys=True) != json.dumps(y[5], sort_keys=True)
            for k in x[5]:
                assert np.allclose(np.asarray(x[5][k], float), np.asarray(y[5][k], float), rtol=1e-11, atol=0) or x[5][k] == y[5][k]
    assert differ <= 2  # the rare 12th-digit tie (test above)
    tf = [m for m in mb if m[0] == "/tf"]
    assert len(tf) == len(LINKS) * b.samples
