"""Streamed CSV table of every sample: one row per sample, written block by block.

The file appears only when complete (``sms_cli.results.atomic_path``): an interrupted run
leaves the previous table, never half of a new one. Values in SI (rad, m, N m s); NaN where an
index is undefined at that sample.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator

import numpy as np

from sms_cli.results import atomic_path


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


@contextlib.contextmanager
def csv_table(path: Path | str, columns: list[str]) -> Iterator[CsvTable]:
    """Open a streamed CSV at ``path`` (renamed into place when the block exits normally)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="\n") as fh:
        yield CsvTable(fh, ["sample"] + list(columns))
