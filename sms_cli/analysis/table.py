"""Streamed tables of every sample: one row per sample, written block by block.

Formats (``analysis.table`` in the mission, ``sms analyze --csv``):

* Parquet, ``analysis_<variant>.parquet`` (the default): column ``sample`` (int64, 0 … n−1) first,
  then the joint coordinates and every index, float64; row groups of whole evaluated blocks
  (``analysis.sampling.chunk`` samples each), at least :data:`ROW_GROUP_ROWS` rows but the last;
  fixed writer options, so one study gives the same bytes on every run (with one pyarrow version);
* CSV, ``analysis_<variant>.csv``: the same columns, ``%.10g`` (slower to write and read: a
  2^20-sample study formats 60 million numbers).

Values in SI (rad, m, N m s); NaN where an index is undefined at that sample. Each file appears
only when complete (``sms_cli.results.atomic_path``): an interrupted run leaves the previous
table, never part of a new one.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator

import numpy as np

from sms_cli.results import atomic_path

FORMATS = ("parquet", "csv")
#: Rows per Parquet row group (at least; whole evaluated blocks): fewer, larger groups write and read faster.
ROW_GROUP_ROWS = 65536
#: Parquet writer options (part of the file's bytes: change them and the bytes change).
PARQUET_OPTIONS = {"compression": "snappy", "use_dictionary": False, "write_statistics": True}


class CsvTable:
    """Append blocks of rows; ``columns`` fixes the order (``sample`` first, an integer)."""

    def __init__(self, fh, columns: list[str]):
        self._fh = fh
        self.columns = list(columns)
        self.rows = 0
        fh.write(",".join(self.columns) + "\n")
        self._fmt = ",".join(["%d"] + ["%.10g"] * (len(self.columns) - 1))

    def write(self, block: dict[str, np.ndarray]) -> None:
        """Write one block: ``block`` maps every column (except ``sample``) to a (k,) array."""
        k = len(next(iter(block.values())))
        data = np.empty((k, len(self.columns)))
        data[:, 0] = np.arange(self.rows, self.rows + k)
        for i, c in enumerate(self.columns[1:], start=1):
            data[:, i] = block[c]
        np.savetxt(self._fh, data, fmt=self._fmt)
        self.rows += k


class ParquetTable:
    """Append blocks of rows as row groups of a Parquet file (``sample`` int64 first, float64 after).

    Row groups are encoded, compressed and written on a background thread (:func:`_writer_thread`,
    one for the process, so every file's groups are written in order: the same bytes as written
    here) while the caller evaluates the next blocks; at most one group per file is in flight. The
    written arrays are kept, not copied, until their group is written: a caller must not change
    them after :meth:`write`.
    """

    def __init__(self, path: Path, columns: list[str]):
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._pa = pa
        self.columns = list(columns)
        self.rows = 0
        self.schema = pa.schema([pa.field("sample", pa.int64(), nullable=False)]
                                + [pa.field(c, pa.float64()) for c in self.columns[1:]])
        self._writer = pq.ParquetWriter(str(path), self.schema, **PARQUET_OPTIONS)
        self._pending: list = []
        self._pending_rows = 0
        self._in_flight = None  # the future of the group being written

    def write(self, block: dict[str, np.ndarray]) -> None:
        """Append one block: ``block`` maps every column but ``sample`` to a (k,) array. Blocks are
        written as row groups of :data:`ROW_GROUP_ROWS` rows or more (whole blocks)."""
        pa = self._pa
        k = len(next(iter(block.values())))
        arrays = [pa.array(np.arange(self.rows, self.rows + k, dtype=np.int64))]
        arrays += [pa.array(np.ascontiguousarray(block[c], dtype=np.float64)) for c in self.columns[1:]]
        self._pending.append(pa.Table.from_arrays(arrays, schema=self.schema))
        self._pending_rows += k
        self.rows += k
        if self._pending_rows >= ROW_GROUP_ROWS:
            self._flush()

    def _wait(self) -> None:
        """Wait for the group in flight (its error, if any, is raised here)."""
        future, self._in_flight = self._in_flight, None
        if future is not None:
            future.result()

    def _flush(self) -> None:
        if self._pending:
            group = self._pa.concat_tables(self._pending)
            self._pending, self._pending_rows = [], 0
            self._wait()
            self._in_flight = _writer_thread().submit(self._writer.write_table, group, row_group_size=max(group.num_rows, 1))

    def close(self, complete: bool = True) -> None:
        """Write what is pending (``complete``) and close the file."""
        try:
            if complete:
                self._flush()
                self._wait()
            else:
                with contextlib.suppress(Exception):  # the error being raised is the caller's
                    self._wait()
        finally:
            self._writer.close()


_WRITER: list = []


def _writer_thread():
    """The process's Parquet writing thread (a one-thread executor: jobs run in submission order)."""
    if not _WRITER:
        from concurrent.futures import ThreadPoolExecutor

        _WRITER.append(ThreadPoolExecutor(max_workers=1, thread_name_prefix="sms-parquet"))
    return _WRITER[0]


class SampleTables:
    """One variant's tables, one per format; :meth:`write` appends a block to each."""

    def __init__(self, tables: list):
        self._tables = tables

    def write(self, block: dict[str, np.ndarray]) -> None:
        for t in self._tables:
            t.write(block)


def table_names(stem: str, formats: tuple[str, ...] | list[str]) -> list[str]:
    """The file names :func:`sample_tables` writes for ``stem`` (``analysis_<variant>``)."""
    return [f"{stem}.{f}" for f in FORMATS if f in formats]


@contextlib.contextmanager
def csv_table(path: Path | str, columns: list[str]) -> Iterator[CsvTable]:
    """Open a streamed CSV at ``path`` (renamed into place when the block exits normally)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="\n") as fh:
        yield CsvTable(fh, ["sample"] + list(columns))


@contextlib.contextmanager
def parquet_table(path: Path | str, columns: list[str]) -> Iterator[ParquetTable]:
    """Open a streamed Parquet file at ``path`` (renamed into place when the block exits normally)."""
    with atomic_path(path) as tmp:
        table = ParquetTable(tmp, ["sample"] + list(columns))
        try:
            yield table
        except BaseException:
            table.close(complete=False)  # closed before atomic_path removes it
            raise
        table.close()


@contextlib.contextmanager
def sample_tables(folder: Path, stem: str, columns: list[str], formats: tuple[str, ...] | list[str]
                  ) -> Iterator[SampleTables]:
    """The tables of ``folder/<stem>.<format>`` for each of ``formats``; each appears when the block exits
    normally, none if it raises."""
    openers = {"parquet": parquet_table, "csv": csv_table}
    with contextlib.ExitStack() as stack:
        yield SampleTables([stack.enter_context(openers[name.rsplit(".", 1)[1]](folder / name, columns))
                            for name in table_names(stem, formats)])
