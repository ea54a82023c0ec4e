"""The per-sample tables of ``sms analyze`` (issue #19): Parquet by default, CSV when asked for.

One row per sample with the values the study computed (read back with pyarrow and compared, to the
bit, with the indices evaluated again in memory, and with the CSV written by ``--csv``), the same
bytes on every run, and no file at all when the writing is interrupted.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml

from conftest import MISSIONS, run_cli
from sms_cli.analysis import table as T


def study(tmp_path: Path, **analysis) -> Path:
    """Demeter (symmetric half workspace) with a variant: a 5^3 grid in blocks of 32 samples, so the
    tables are written in many blocks (and several row groups: ``ROW_GROUP_ROWS`` lowered by the tests)."""
    d = yaml.safe_load((MISSIONS / "demeter_3dof.yaml").read_text())
    d["robot"]["urdf"] = str((MISSIONS / d["robot"]["urdf"]).resolve())
    d["analysis"] = {"sampling": {"method": "grid", "n": 5, "chunk": 32}, "plots": False,
                     "variants": [{"name": "doubled_wheels", "wheel_inertia_scale": 2}], **analysis}
    p = tmp_path / "demeter_tables.yaml"
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


def in_memory(mission: Path) -> tuple[list[str], np.ndarray, list[dict[str, np.ndarray]]]:
    """The study evaluated again, in one block, in this process: joint names, samples, columns per
    variant (in the kernel's column order)."""
    from sms_cli.analysis.schema import AnalysisSpec
    from sms_cli.analysis.workspace import build_variants, evaluate_block, make_sampler
    from sms_cli.mission.load import load_mission
    from sms_cli.model import compile_system

    loaded = load_mission(mission)
    sm = compile_system(loaded)
    spec = loaded.mission.analysis or AnalysisSpec()
    sampler, sampled = make_sampler(sm, spec, loaded)
    variants = build_variants(sm, spec, sampled, loaded)
    samples = np.vstack(list(sampler.chunks()))
    _, res = evaluate_block(variants, samples)
    return sampler.names, samples, [{c: r[c] for c in v.kernel.columns} for v, r in zip(variants, res)]


@pytest.fixture
def small_groups(monkeypatch):
    monkeypatch.setattr(T, "ROW_GROUP_ROWS", 70)  # blocks of 32: a row group of 96 rows, the last (pending) of 29


def test_parquet_holds_one_row_per_sample_with_the_computed_values(tmp_path, small_groups):
    mission = study(tmp_path)
    out = tmp_path / "out"
    r = run_cli("analyze", mission, "-o", out, "--no-progress", "--csv")
    assert r.exit_code == 0, r.output
    sec = json.loads((out / "results.json").read_text())["analysis"]
    names, samples, res = in_memory(mission)
    for variant, cols in zip(("nominal", "doubled_wheels"), res):
        f = pq.ParquetFile(out / f"analysis_{variant}.parquet")
        assert f.metadata.num_rows == sec["samples"] == len(samples) == 125
        assert [f.metadata.row_group(i).num_rows for i in range(f.metadata.num_row_groups)] == [96, 29]
        t = f.read()
        assert t.column_names == ["sample"] + [f"q_{n}" for n in names] + list(cols)
        assert t.schema.field("sample").type == pa.int64()
        assert all(t.schema.field(c).type == pa.float64() for c in t.column_names[1:])
        np.testing.assert_array_equal(t["sample"].to_numpy(), np.arange(len(samples)))
        for j, n in enumerate(names):
            np.testing.assert_array_equal(t[f"q_{n}"].to_numpy(), samples[:, j])
        for c, v in cols.items():  # bit for bit, NaN where the index is undefined
            np.testing.assert_array_equal(t[c].to_numpy(), np.asarray(v, float), err_msg=c)
        assert any(np.isnan(t[c].to_numpy()).any() for c in cols)  # the study has undefined values
        with open(out / f"analysis_{variant}.csv") as fh:  # the CSV (--csv): same rows, 10 digits
            rows = list(csv.reader(fh))
        assert rows[0] == t.column_names and len(rows) == len(samples) + 1
        data = np.array(rows[1:], dtype=float)
        np.testing.assert_allclose(data, np.column_stack([t[c].to_numpy() for c in t.column_names]), rtol=1e-9,
                                   atol=0, equal_nan=True)
    assert sec["artifacts"][:4] == ["analysis_nominal.parquet", "analysis_nominal.csv",
                                    "analysis_doubled_wheels.parquet", "analysis_doubled_wheels.csv"]


def test_same_study_same_parquet_bytes(tmp_path):
    mission = study(tmp_path)
    runs = [tmp_path / "a", tmp_path / "b"]
    for out in runs:
        assert run_cli("analyze", mission, "-o", out, "--no-progress").exit_code == 0
    for name in ("analysis_nominal.parquet", "analysis_doubled_wheels.parquet"):
        assert (runs[0] / name).read_bytes() == (runs[1] / name).read_bytes(), name


@pytest.mark.parametrize("table, files", [(True, ["parquet"]), (False, []), (["csv"], ["csv"]),
                                          (["csv", "parquet"], ["parquet", "csv"])])
def test_the_mission_chooses_the_formats(tmp_path, table, files):
    mission = study(tmp_path, table=table)
    out = tmp_path / "out"
    assert run_cli("analyze", mission, "-o", out, "--no-progress").exit_code == 0
    written = sorted(p.name for p in out.glob("analysis_nominal.*"))
    assert written == sorted(f"analysis_nominal.{f}" for f in files)
    arts = json.loads((out / "results.json").read_text())["analysis"]["artifacts"]
    assert [a for a in arts if a.startswith("analysis_nominal.")] == [f"analysis_nominal.{f}" for f in files]


def test_csv_option_adds_csv_to_what_the_mission_says(tmp_path):
    mission = study(tmp_path, table=False)
    out = tmp_path / "out"
    assert run_cli("analyze", mission, "-o", out, "--no-progress", "--csv").exit_code == 0
    assert sorted(p.name for p in out.glob("analysis_nominal.*")) == ["analysis_nominal.csv"]


class Boom(Exception):
    pass


@pytest.mark.parametrize("formats", [("parquet",), ("csv",), ("parquet", "csv")])
def test_an_interrupted_table_leaves_no_file_and_keeps_the_previous_one(tmp_path, formats, small_groups):
    block = {"q_a": np.linspace(0, 1, 50), "x": np.where(np.arange(50) % 7 == 0, np.nan, np.arange(50.0))}
    with T.sample_tables(tmp_path, "analysis_nominal", ["q_a", "x"], formats) as t:
        t.write(block)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert sorted(before) == sorted(f"analysis_nominal.{f}" for f in formats)
    for when in ("after a block", "before any block"):
        with pytest.raises(Boom):
            with T.sample_tables(tmp_path, "analysis_nominal", ["q_a", "x"], formats) as t:
                if when == "after a block":
                    t.write({k: v[::-1] for k, v in block.items()})  # 50 rows: pending (< 70)
                    t.write(block)  # 100 rows: a row group written
                raise Boom
        assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before, when  # no .part, old tables
    fresh = tmp_path / "fresh"
    with pytest.raises(Boom):
        with T.sample_tables(fresh, "analysis_nominal", ["q_a", "x"], formats) as t:
            t.write(block)
            raise Boom
    assert list(fresh.iterdir()) == []


def test_an_interrupted_study_writes_no_table(tmp_path, monkeypatch):
    import sms_cli as sms
    from sms_cli.analysis import summary

    mission = study(tmp_path)
    calls = []
    real = summary.StudyStats.add

    def add(self, *a, **k):  # Ctrl-C after a few blocks were written
        calls.append(1)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return real(self, *a, **k)

    monkeypatch.setattr(summary.StudyStats, "add", add)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        sms.analyze(mission, out=out, csv=True)
    assert sorted(p.name for p in out.iterdir()) == [".sms.lock"]


def test_an_evaluation_error_reaches_the_command_and_writes_no_table(tmp_path, monkeypatch):
    """Blocks are evaluated one ahead on a background thread (stage._ahead): its error is raised by the
    command, as if evaluated in line, and no table appears."""
    import sms_cli as sms
    from sms_cli.analysis import workspace

    mission = study(tmp_path)
    calls = []
    real = workspace.evaluate_block

    def evaluate(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise FloatingPointError("block 3")
        return real(*a, **k)

    monkeypatch.setattr(workspace, "evaluate_block", evaluate)
    out = tmp_path / "out"
    with pytest.raises(FloatingPointError, match="block 3"):
        sms.analyze(mission, out=out)
    assert sorted(p.name for p in out.iterdir()) == [".sms.lock"]


def test_a_parquet_write_error_reaches_the_command(tmp_path, monkeypatch):
    """Row groups are written on a background thread (table.ParquetTable): a write error is raised by
    the command, and no table appears."""
    import pyarrow.parquet as pq

    import sms_cli as sms

    mission = study(tmp_path)

    def fail(self, *a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(pq.ParquetWriter, "write_table", fail)
    out = tmp_path / "out"
    with pytest.raises(OSError, match="disk full"):
        sms.analyze(mission, out=out)
    assert sorted(p.name for p in out.iterdir()) == [".sms.lock"]
