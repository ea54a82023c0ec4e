"""The workspace figures of ``sms analyze``, drawn fast (issue #19), are the figures a plain draw gives.

The index maps of one point cloud are built once and redrawn per index column, only the changing
artists repainted over the kept axes (``figstyle.Redraw``); the figures are drawn on worker
processes (``figpool.FigurePool``) while the caller draws too. Each shortcut is checked against
the plain way, byte for byte (pixels and the legibility chunks): a full draw of a fresh figure,
one process.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import MISSIONS, run_cli
from sms_cli.analysis import plots as P
from sms_cli.report import figstyle as S
from sms_cli.report.figpool import FigurePool


def point_cloud(n: int = 3000, seed: int = 1) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """End-effector positions and index columns that exercise every changing part of a map:
    undefined cells (grey) present, absent, present again; a column with no finite value; colour
    scales of other magnitudes (other tick labels)."""
    rng = np.random.default_rng(seed)
    xyz = rng.normal(size=(n, 3)) * [0.8, 0.5, 0.3] + [0.2, 0.0, 1.0]
    r = np.linalg.norm(xyz - [0.2, 0.0, 1.0], axis=1)
    return xyz, {
        "mu_gjm": np.where(xyz[:, 2] > 1.25, np.nan, xyz[:, 0] ** 2),
        "K_m": r / r.max(),
        "h_ratio": 1e4 * (xyz[:, 1] + 3.0),
        "joint_limit_margin": np.full(n, np.nan),
        "mu_null_lin_norm": np.where(xyz[:, 0] < 0, np.nan, 1e-4 * np.exp(-r)),
    }


def items_of(tmp_path: Path, columns: dict[str, np.ndarray]) -> list[tuple]:
    return [(tmp_path / f"{c}.png", v, c, f"test ({c}): {P.LABELS.get(c, c)}, EE positions") for c, v in columns.items()]


@S.styled
def plain_cloud(xyz: np.ndarray, values: np.ndarray, column: str, title: str) -> bytes:
    """A fresh figure of one column, drawn whole by ``figstyle.render`` (no kept background)."""
    maps = P._Maps([xyz], len(values))
    maps.draw([values], column, title)  # fills the figure (and draws it once the fast way)
    return S.render(maps.fig)


def test_maps_redrawn_per_column_are_the_fresh_figures_byte_for_byte(tmp_path):
    xyz, columns = point_cloud()
    items = items_of(tmp_path, columns)
    items.append(items[0])  # after every other column: nothing of them is left on the figure
    batch = P.clouds(xyz, items)
    assert [p for p, _ in batch] == [p for p, *_ in items]
    for (path, png), (_, values, column, title) in zip(batch, items):
        assert png == plain_cloud(xyz, values, column, title), path.name
    # and each drawing shows its column: values per cell, colour bar label, title, the undefined note
    maps = P._Maps([xyz], len(xyz))
    for _, values, column, title in items:
        maps.draw([values], column, title)
        for (flat, shape), (image, grey, _) in zip(maps.cells[0], maps.images[0]):
            best, undef = P._best_map(flat, shape, values, column in P.LOWER_IS_BETTER)
            np.testing.assert_array_equal(np.asarray(image.get_array().filled(np.nan)), best)
            assert (grey is not None) == bool(undef.any())
        assert maps.colorbar.ax.get_ylabel() == f"{P.SHORT[column]}\n({P.better(column)} is better)"
        assert maps.title.get_text() == title and maps.note.get_visible() == bool(np.isnan(values).any())
    maps.close()
    meta = [S.png_info(png)["text"] for _, png in batch]
    assert all(set(m) == set(S.META_KEYS) for m in meta)
    # the redrawn parts are measured: the "grey: undefined" note (8.5 pt = 11.8 px) only where a column has NaN
    assert [m["sms:font-px-min"] for m in meta] == ["11.8056", "12.5", "12.5", "11.8056", "11.8056", "11.8056"]


def test_comparison_maps_redrawn_per_column_are_the_fresh_figures(tmp_path):
    xyz, columns = point_cloud()
    xyz2 = xyz * 0.9
    clouds_ = [("nominal", xyz), ("doubled_wheels", xyz2)]
    items = [(tmp_path / f"compare_{c}.png", [v, v * 0.5], c, f"test: {c} per variant") for c, v in columns.items()]
    batch = P.compare_figures(clouds_, items)
    for (path, png), item in zip(batch, items):
        assert png == P.compare_figures(clouds_, [item])[0][1], path.name


def test_cloud_writes_the_png_clouds_gives(tmp_path):
    xyz, columns = point_cloud(500)
    [(path, png)] = P.clouds(xyz, items_of(tmp_path, {"K_m": columns["K_m"]}))
    written = P.cloud(tmp_path / "one.png", xyz, columns["K_m"], "K_m", items_of(tmp_path, columns)[1][3])
    assert written.read_bytes() == png


def _interrupt() -> None:
    raise KeyboardInterrupt


def test_pool_gives_the_results_in_job_order_from_both_processes():
    jobs = [(sum, ([1, 2, 3],))] + [(os.getpid, ())] * 6 + [(time.sleep, (3,))]
    with FigurePool(1) as pool:
        assert pool.workers == 1
        worker = pool._procs[0].pid
        out = pool.run(jobs)
    assert out[0] == 6 and out[-1] is None
    assert worker in out[1:-1]  # the worker ran the front jobs while the caller ran the last one


def test_pool_error_raises_in_the_caller_and_a_dead_worker_costs_nothing():
    with FigurePool(1) as pool:
        with pytest.raises(ValueError, match="invalid literal"):
            pool.run([(int, ("not a number",)), (time.sleep, (0.2,))])
    with FigurePool(1) as pool:
        pool._procs[0].kill()
        assert pool.run([(abs, (-2,)), (abs, (-3,))]) == [2, 3]


def test_pool_interrupted_stops_at_once_and_leaves_no_worker():
    pool = FigurePool(1)
    procs = list(pool._procs)
    t = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        pool.run([(time.sleep, (30,)), (time.sleep, (0.5,)), (_interrupt, ())])
    assert time.perf_counter() - t < 10
    assert all(p.poll() is not None for p in procs)  # stopped by run itself, before any close
    pool.close()


def small_study(tmp_path: Path) -> Path:
    d = yaml.safe_load((MISSIONS / "demeter_3dof.yaml").read_text())
    d["robot"]["urdf"] = str((MISSIONS / d["robot"]["urdf"]).resolve())
    d["analysis"] = {"sampling": {"method": "grid", "n": 6}, "variants": [{"name": "doubled_wheels", "wheel_inertia_scale": 2}]}
    p = tmp_path / "demeter_small.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


def test_figures_drawn_by_workers_are_the_ones_drawn_in_one_process(tmp_path, monkeypatch):
    mission = small_study(tmp_path)
    outs = {}
    for workers in ("0", "1"):
        monkeypatch.setenv("SMS_FIGURE_WORKERS", workers)
        outs[workers] = tmp_path / f"w{workers}"
        r = run_cli("analyze", mission, "-o", outs[workers], "--no-progress")
        assert r.exit_code == 0, r.output
    arts = json.loads((outs["1"] / "results.json").read_text())["analysis"]["artifacts"]
    assert arts == json.loads((outs["0"] / "results.json").read_text())["analysis"]["artifacts"]
    pngs = [a for a in arts if a.endswith(".png")]
    assert len(pngs) == 22
    for a in pngs:
        assert (outs["1"] / a).read_bytes() == (outs["0"] / a).read_bytes(), a
        meta = S.png_info((outs["1"] / a).read_bytes())["text"]
        assert float(meta["sms:font-px-min"]) >= 11.8 and meta["sms:text-clipped"] == "0", (a, meta)


def test_interrupted_plots_leave_no_partial_file_and_no_worker(tmp_path, monkeypatch):
    import sms_cli as sms

    mission = small_study(tmp_path)
    monkeypatch.setattr(P, "slices_png", lambda *a: _interrupt())
    started = []
    real = FigurePool.__init__

    def spy(self, *a, **k):
        real(self, *a, **k)
        started.extend(self._procs)

    monkeypatch.setattr(FigurePool, "__init__", spy)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        sms.analyze(mission, out=out)
    assert started and all(p.poll() is not None for p in started)
    from PIL import Image

    left = sorted(p.name for p in out.iterdir())
    assert not [n for n in left if n.endswith(".part")], left
    for n in left:
        if n.endswith(".png"):
            Image.open(out / n).load()  # a figure that is there is whole
