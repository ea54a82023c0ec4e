"""Plain data the report template renders: tables, figures, sections (no HTML here)."""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass
class Table:
    """A table: numeric columns are right-aligned and carry their unit in the header (``[unit]``),
    in a ``unit`` column or in every cell; ``status_col`` is the column coloured by pass/fail."""

    caption: str
    headers: list[str]
    rows: list[list[str]]
    numeric: list[bool] = field(default_factory=list)  # right-align these columns
    row_classes: list[str] = field(default_factory=list)
    status_col: int | None = None

    def __post_init__(self) -> None:
        if not self.numeric:
            self.numeric = [False] * len(self.headers)
        if not self.row_classes:
            self.row_classes = [""] * len(self.rows)


@dataclass
class Figure:
    """An embedded PNG shown at its natural size (1 image px = 1 CSS px) when it fits the column;
    ``wide`` figures span the content column, the others share a row with a neighbour."""

    caption: str
    src: str  # data: URI
    alt: str = ""
    wide: bool = False
    width: int = 0  # natural size in px (0: unknown)
    height: int = 0
    font_px: float | None = None  # smallest text in the image (px, from its sms:font-px-min chunk)
    id: str = ""  # set by the report builder (the anchor of click-to-enlarge)

    @classmethod
    def of_png(cls, caption: str, data: bytes, alt: str = "") -> "Figure":
        """A figure of PNG bytes, sized and laid out from the PNG header (compacted when large)."""
        from sms_cli.report.figstyle import HALF_PX, png_info

        info = png_info(data)
        w, h = int(info["width"] or 0), int(info["height"] or 0)
        font = info["text"].get("sms:font-px-min")
        try:
            font_px = float(font) if font is not None else None
        except ValueError:
            font_px = None
        return cls(caption, png_uri(compact_png(data)), alt=alt or caption, wide=w > HALF_PX + 8, width=w, height=h,
                   font_px=font_px)


@dataclass
class Section:
    id: str
    title: str
    intro: str = ""
    tables: list[Table] = field(default_factory=list)
    figures: list[Figure] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    blocks: list[Any] = field(default_factory=list)  # ordered Tables and Figures (if set, used instead)

    def add(self, item: Table | Figure | None) -> None:
        if item is None:
            return
        (self.tables if isinstance(item, Table) else self.figures).append(item)
        self.blocks.append(item)


def png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


COMPACT_ABOVE = 150_000  # bytes: larger PNGs are re-encoded with a 256-colour palette


def compact_png(data: bytes) -> bytes:
    """A large plot re-encoded with an adaptive 256-colour palette (3-4x smaller, visually the
    same for line and scatter plots); small or unreadable images are returned unchanged."""
    if len(data) <= COMPACT_ABOVE:
        return data
    import io

    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as im:
            q = im.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE)
            buf = io.BytesIO()
            q.save(buf, format="PNG", optimize=True)
    except OSError:
        return data
    out = buf.getvalue()
    return out if len(out) < len(data) else data


def figure_from_file(folder: Path, name: str, caption: str, wide: bool = False) -> Figure | None:
    """A figure from a PNG of the results folder (None when absent or not a PNG)."""
    p = Path(name)
    if p.is_absolute() or ".." in p.parts:
        p = Path(p.name)
    f = folder / p
    if not f.is_file():
        return None
    data = f.read_bytes()
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        return None
    fig = Figure.of_png(caption, data)
    fig.wide = fig.wide or wide
    return fig


THIN = "\u202f"  # narrow no-break space: groups thousands without a line break inside the number


def fmt(x: Any, nd: int = 4) -> str:
    """A number for a table: ``nd`` significant digits, thousands grouped by a narrow no-break space,
    None → —."""
    if x is None:
        return "—"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x:,}".replace(",", THIN)
    if isinstance(x, float):
        if not math.isfinite(x):
            return "—"
        if x != 0 and (abs(x) >= 1e6 or abs(x) < 1e-3):
            return f"{x:.{nd - 1}e}"
        if abs(x) >= 10 ** nd:
            return f"{x:,.0f}".replace(",", THIN)
        return f"{x:.{nd}g}"
    return str(x)


def qty(x: Any, unit: str, nd: int = 4) -> str:
    """A number and its unit kept on one line (no-break space); a missing value has no unit."""
    v = fmt(x, nd)
    return v if v == "—" or not unit or unit == "–" else f"{v}\u00a0{unit}"
