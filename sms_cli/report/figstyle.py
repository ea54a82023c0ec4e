"""One set-up for every figure of a results folder and of the report.

Each figure is drawn at the size and resolution the report shows it at: one image pixel is one CSS
pixel (``DPI`` image pixels per inch of matplotlib's figure size), a figure is either the width
of the report's content column (``FULL_PX``) or half of it (``HALF_PX``), and the report gives the
``<img>`` its natural size. Fonts are set here once (tick labels 9 pt = 12.5 px, axis labels 10 pt,
nothing below ``MIN_FONT_PT``).

:func:`render` draws a figure once, measures its text (smallest font in pixels, text boxes that
overlap each other or leave the canvas) and writes the PNG with those measurements in tEXt chunks
(:data:`META_KEYS`), which the report reads to size the ``<img>`` and the tests to check legibility.
:class:`Redraw` gives the same PNG for a figure drawn many times with a few artists changed,
redrawing only those.
"""

from __future__ import annotations

import functools
import io
import struct
import zlib
from pathlib import Path
from typing import Any, Callable, TypeVar

import numpy as np

F = TypeVar("F", bound=Callable[..., Any])

DPI = 100  # image px per inch; the report shows 1 image px as 1 CSS px
CONTENT_PX = 960  # width of the report's content column (CSS px); the template uses the same numbers
GAP_PX = 16
FULL_PX = CONTENT_PX
HALF_PX = (CONTENT_PX - GAP_PX) // 2
MIN_FONT_PT = 8.5  # 11.8 px at DPI

STYLE = {
    "figure.dpi": DPI, "savefig.dpi": DPI, "figure.facecolor": "white",
    "font.size": 9.5, "axes.titlesize": 10, "axes.labelsize": 9.5, "xtick.labelsize": 9, "ytick.labelsize": 9,
    "legend.fontsize": MIN_FONT_PT, "legend.title_fontsize": 9, "figure.titlesize": 10.5, "figure.labelsize": 9.5,
    "axes.titlelocation": "left", "axes.titlepad": 4, "axes.grid": True, "grid.alpha": 0.3, "grid.linewidth": 0.6,
    "axes.spines.top": False, "axes.spines.right": False, "legend.frameon": False, "lines.linewidth": 1.3,
    "axes.formatter.limits": (-3, 4), "axes.formatter.use_mathtext": False, "xtick.major.pad": 2, "ytick.major.pad": 2,
    "figure.constrained_layout.use": True, "figure.constrained_layout.h_pad": 0.04, "figure.constrained_layout.w_pad": 0.04,
    "path.simplify": True, "agg.path.chunksize": 20000, "image.cmap": "viridis",
}
META_KEYS = ("sms:width-css-px", "sms:font-px-min", "sms:text-overlaps", "sms:text-clipped")


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def warm_up() -> None:
    """Import matplotlib and PIL and draw a small figure with mathtext, so that the first real figure
    of this process does not pay for them (a figure worker does this while its caller computes)."""
    import PIL.PngImagePlugin  # noqa: F401

    with pyplot().rc_context(STYLE):
        fig = new_figure(120, 40)
        fig.text(0.05, 0.3, r"$K^m_{\omega_0}$ (m)")
        render(fig)


def styled(fn: F) -> F:
    """Run a plotting function under :data:`STYLE` (the caller's rcParams are left as they were)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with pyplot().rc_context(STYLE):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def new(width_px: int = FULL_PX, height_px: int = 300, nrows: int = 1, ncols: int = 1, **kw):
    """``plt.subplots`` of exactly ``width_px`` × ``height_px`` image pixels (constrained layout)."""
    return pyplot().subplots(nrows, ncols, figsize=(width_px / DPI, height_px / DPI), dpi=DPI, **kw)


def panels(width_px: int, height_px: int, nrows: int = 1, ncols: int = 1, *, left: float = 58, right: float = 14,
           top: float = 30, bottom: float = 44, wgap: float = 60, hgap: float = 48, width_ratios=None, height_ratios=None,
           **subplot_kw):
    """A grid of axes placed by pixel margins and gaps (no layout engine: figures drawn many times per
    run, such as the workspace maps, skip constrained layout's text measurement passes)."""
    fig = new_figure(width_px, height_px, layout="none")
    aw = max((width_px - left - right - (ncols - 1) * wgap) / ncols, 1.0)
    ah = max((height_px - top - bottom - (nrows - 1) * hgap) / nrows, 1.0)
    gs = fig.add_gridspec(nrows, ncols, left=left / width_px, right=1 - right / width_px, bottom=bottom / height_px,
                          top=1 - top / height_px, wspace=wgap / aw, hspace=hgap / ah, width_ratios=width_ratios,
                          height_ratios=height_ratios)
    return fig, gs.subplots(squeeze=False, **subplot_kw)


def px_axes(fig, left: float, bottom: float, width: float, height: float, **kw):
    """Axes at a rectangle given in image pixels from the bottom-left corner."""
    W, H = fig.canvas.get_width_height()
    return fig.add_axes((left / W, bottom / H, width / W, height / H), **kw)


def new_figure(width_px: int = FULL_PX, height_px: int = 300, **kw):
    """An empty figure of exactly ``width_px`` × ``height_px`` image pixels (for 3-D axes)."""
    return pyplot().figure(figsize=(width_px / DPI, height_px / DPI), dpi=DPI, **kw)


# ----------------------------------------------------------------- text measurement


def _drawn_texts(fig) -> list:
    """The text artists the last draw put on the canvas: tick labels inside the view, axis labels of
    axes that show their axes, every other visible text."""
    from matplotlib.text import Text

    axis_texts: set[int] = set()
    shown = []
    for ax in fig.axes:
        on = ax.get_visible() and ax.axison
        for axis in [getattr(ax, a) for a in ("xaxis", "yaxis", "zaxis") if hasattr(ax, a)]:
            lo, hi = sorted(axis.get_view_interval())
            eps = 1e-9 * max(abs(lo), abs(hi), 1e-300)
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                axis_texts.update((id(tick.label1), id(tick.label2)))
                if on and lo - eps <= tick.get_loc() <= hi + eps:
                    shown.extend(t for t in (tick.label1, tick.label2) if t.get_visible())
            axis_texts.update((id(axis.label), id(axis.offsetText)))
            if on:
                shown.extend(t for t in (axis.label, axis.offsetText) if t.get_visible())
    others = [t for t in fig.findobj(Text) if id(t) not in axis_texts and t.get_visible()
              and (t.axes is None or t.axes.get_visible())]
    return [t for t in shown + others if t.get_text().strip()]


_RENDERERS: dict[tuple, Any] = {}  # (width px, height px, dpi) → the Agg renderer figures of that size share
_MAX_RENDERERS = 8


def _shared_renderer(canvas) -> None:
    """Give an Agg canvas this process's renderer for its size (as ``FigureCanvasAgg.get_renderer``
    would make one): text metrics and parsed mathtext are cached per renderer, so the figures of one
    size (the index maps, the histograms of each variant) measure and parse their labels once, not
    once per figure. A figure's pixels are read (:func:`encode`) before another is drawn."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg

    if type(canvas) is not FigureCanvasAgg:
        return
    w, h = canvas.get_width_height(physical=True)
    key = (w, h, canvas.figure.dpi)
    r = _RENDERERS.pop(key, None) or RendererAgg(w, h, canvas.figure.dpi)
    _RENDERERS[key] = r  # most recent last
    while len(_RENDERERS) > _MAX_RENDERERS:
        _RENDERERS.pop(next(iter(_RENDERERS)))
    canvas.renderer, canvas._lastKey = r, key


def text_boxes(fig) -> tuple[list, np.ndarray]:
    """Draw ``fig``; its drawn texts and their boxes (x0, y0, x1, y1 in image px)."""
    _shared_renderer(fig.canvas)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts, boxes = [], []
    for t in _drawn_texts(fig):
        b = t.get_window_extent(renderer)
        if b.width > 0 and b.height > 0 and np.all(np.isfinite(b.extents)):
            texts.append(t)
            boxes.append(b.extents)
    return texts, np.array(boxes, dtype=float).reshape(-1, 4)


def overlapping(B: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of boxes closer than 2 px (they read as one word or collide); a box drawn twice counts once."""
    if len(B) < 2:
        return []
    inner = B + np.array([-1.0, -1.0, 1.0, 1.0])
    ix = np.minimum(inner[:, None, 2], inner[None, :, 2]) - np.maximum(inner[:, None, 0], inner[None, :, 0])
    iy = np.minimum(inner[:, None, 3], inner[None, :, 3]) - np.maximum(inner[:, None, 1], inner[None, :, 1])
    same = np.all(np.abs(B[:, None, :] - B[None, :, :]) < 0.5, axis=2)  # one label drawn twice (3-D panes)
    i, j = np.nonzero(np.triu((ix > 0) & (iy > 0) & ~same, 1))
    return list(zip(i.tolist(), j.tolist()))


def measure(fig) -> dict[str, float]:
    """Draw ``fig`` and measure its text: smallest font (px), overlapping pairs, boxes off the canvas."""
    texts, B = text_boxes(fig)
    return text_metrics(fig, texts, B)


def text_metrics(fig, texts: list, B: np.ndarray) -> dict[str, float]:
    """:data:`META_KEYS` of ``fig`` from its drawn ``texts`` and their boxes ``B`` (:func:`text_boxes`)."""
    w, h = fig.canvas.get_width_height()
    sizes = [t.get_fontsize() * fig.dpi / 72.0 for t in texts]
    clipped = int(np.sum((B[:, 0] < -1) | (B[:, 1] < -1) | (B[:, 2] > w + 1) | (B[:, 3] > h + 1))) if len(B) else 0
    return {"sms:width-css-px": float(w), "sms:font-px-min": float(min(sizes)) if sizes else 0.0,
            "sms:text-overlaps": float(len(overlapping(B))), "sms:text-clipped": float(clipped)}


class Redraw:
    """A figure drawn many times where only some artists change between the drawings (the maps of
    one point cloud for each index column): the rest is drawn once, with the changing artists
    hidden, and kept as a background; :meth:`png` restores it, draws the changing artists over it
    and measures their text (the text of the rest is measured once).

    ``changing()`` lists the changing artists in the order a full draw paints them (the caller's
    duty; hidden ones are skipped). Where they overlap no static artist but in that order, the PNG
    is :func:`render`'s byte for byte (``tests/test_analysis_plots.py`` checks it)."""

    def __init__(self, fig, changing):
        self.fig = fig
        self._changing = changing
        self._background = None
        self._static: list = []

    def _draw_static(self) -> None:
        shown = [(a, a.get_visible()) for a in self._changing()]
        for a, _ in shown:
            a.set_visible(False)
        try:
            texts, B = text_boxes(self.fig)
            self._static = list(zip(texts, B))
            self._background = self.fig.canvas.copy_from_bbox(self.fig.bbox)
        finally:
            for a, visible in shown:
                a.set_visible(visible)

    def png(self) -> bytes:
        """The PNG of the figure as it is now (:func:`render`'s output; the figure stays open)."""
        if self._background is None:
            self._draw_static()
        canvas = self.fig.canvas
        canvas.restore_region(self._background)
        renderer = canvas.get_renderer()
        for a in self._changing():
            if a.get_visible():
                a.draw(renderer)
        static = {id(t): b for t, b in self._static}
        texts, boxes = [], []
        for t in _drawn_texts(self.fig):
            b = static.get(id(t))
            if b is None:
                e = t.get_window_extent(renderer)
                if not (e.width > 0 and e.height > 0 and np.all(np.isfinite(e.extents))):
                    continue
                b = e.extents
            texts.append(t)
            boxes.append(b)
        return encode(self.fig, text_metrics(self.fig, texts, np.array(boxes, dtype=float).reshape(-1, 4)))


# ----------------------------------------------------------------- PNG output


def render(fig, close: bool = True) -> bytes:
    """The PNG of ``fig`` (drawn once, 256-colour palette, text measurements in tEXt); closes it
    unless ``close`` is false."""
    meta = measure(fig)
    png = encode(fig, meta)
    if close:
        pyplot().close(fig)
    return png


def encode(fig, meta: dict[str, float]) -> bytes:
    """The PNG of ``fig``'s canvas as last drawn, with ``meta`` (:data:`META_KEYS`) in tEXt chunks."""
    from PIL import Image, PngImagePlugin

    w, h = fig.canvas.get_width_height()
    im = Image.frombuffer("RGBA", (w, h), bytes(fig.canvas.buffer_rgba()), "raw", "RGBA", 0, 1).convert("RGB")
    info = PngImagePlugin.PngInfo()
    for k in META_KEYS:
        info.add_text(k, f"{meta[k]:g}")
    q = im.quantize(colors=256, method=Image.Quantize.FASTOCTREE)  # half the bytes of RGB for these plots
    pal = np.array(q.getpalette(), dtype=np.uint8).reshape(-1, 3)
    pal[np.all(pal >= 246, axis=1)] = 255  # the octree averages white with its neighbours: keep the page white
    q.putpalette(pal.ravel().tolist())
    buf = io.BytesIO()
    q.save(buf, format="PNG", pnginfo=info, dpi=(DPI, DPI), compress_level=6)
    return buf.getvalue()


def save(fig, target: Path) -> Path:
    """Write :func:`render` of ``fig`` to ``target`` atomically."""
    from sms_cli.results import write_bytes_atomic

    write_bytes_atomic(Path(target), render(fig))
    return Path(target)


def png_info(data: bytes) -> dict[str, Any]:
    """Width, height, DPI (None when not stored) and the tEXt chunks of PNG bytes (without decoding pixels)."""
    out: dict[str, Any] = {"width": None, "height": None, "dpi": None, "text": {}}
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        return out
    pos = 8
    while pos + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR" and len(body) >= 8:
            out["width"], out["height"] = struct.unpack(">II", body[:8])
        elif kind == b"pHYs" and len(body) == 9 and body[8] == 1:
            out["dpi"] = round(struct.unpack(">I", body[:4])[0] * 0.0254)
        elif kind == b"tEXt" and b"\0" in body:
            k, v = body.split(b"\0", 1)
            out["text"][k.decode("latin-1")] = v.decode("latin-1")
        elif kind == b"zTXt" and b"\0" in body:
            k, v = body.split(b"\0", 1)
            try:
                out["text"][k.decode("latin-1")] = zlib.decompress(v[1:]).decode("latin-1")
            except zlib.error:
                pass
        elif kind in (b"IDAT", b"IEND"):
            break
        pos += 12 + n
    return out


# ----------------------------------------------------------------- shared helpers


def phase_marks(ax, starts: list[float], names: list[str] | None = None) -> None:
    """Dashed lines at phase starts (after the first) and, where there is room, the phase names
    along the top inside the axes."""
    for s in starts[1:]:
        ax.axvline(s, color="0.55", lw=0.8, ls="--", zorder=1)
    if not names or len(names) != len(starts):
        return
    lo, hi = ax.get_xlim()
    span = hi - lo if hi > lo else 1.0
    width_px = ax.get_position().width * ax.figure.get_figwidth() * ax.figure.dpi
    for s, e, n in zip(starts, starts[1:] + [hi], names):
        room_px = (min(e, hi) - max(s, lo)) / span * width_px
        if room_px > 7.0 * len(n) + 12:
            ax.text(max(s, lo) + 4 / width_px * span, 0.97, n, transform=ax.get_xaxis_transform(), va="top", ha="left",
                    fontsize=MIN_FONT_PT, color="0.3", bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none",
                                                             "alpha": 0.75})


def save_time_figure(fig, axes, t, starts: list[float], names: list[str] | None, target: Path) -> Path:
    """Finish a figure of time histories and save it: every axis spans the run (when it has a time span), the
    phase (or event) starts are marked, named on the top axis, and the bottom axis says "time (s)"."""
    for a in axes:
        if t[-1] > t[0]:  # a run that stopped at its first sample has no time span to show
            a.set_xlim(float(t[0]), float(t[-1]))
    phase_marks(axes[0], starts, names)
    for a in axes[1:]:
        phase_marks(a, starts)
    axes[-1].set_xlabel("time (s)")
    return save(fig, target)


def limit_lines(ax, limit: float | None, data: np.ndarray | None = None, label: str = "limit", unit: str = ""):
    """± a limit as dotted red lines; the upper line (None when the limit is absent, infinite, or more
    than 3× the largest |data|: then a note names it, so the data keep the axis)."""
    if limit is None or not np.isfinite(limit) or limit <= 0:
        return None
    peak = float(np.nanmax(np.abs(data))) if data is not None and np.size(data) and np.any(np.isfinite(data)) else 0.0
    if peak > 0 and limit > 3 * peak:
        ax.text(0.995, 0.04, f"{label} ±{limit:.4g} {unit}: off scale ({peak / limit:.1%} used)".replace("  ", " "),
                transform=ax.transAxes, ha="right", va="bottom", fontsize=MIN_FONT_PT, color="#b3261e",
                bbox={"boxstyle": "square,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8})  # phase names sit on top
        return None
    lines = [ax.axhline(sgn * limit, color="#b3261e", lw=1.0, ls=":", label=label if sgn > 0 else None, zorder=1)
             for sgn in (1, -1)]
    return lines[0]


def box3d(ax, elev: float = 22, azim: float = -55) -> None:
    """The 3-D axes set-up of the robot drawing and the end-effector path: equal box, metres, four ticks
    per axis (more collide at half width)."""
    from matplotlib.ticker import MaxNLocator

    ax.set_box_aspect((1, 1, 1), zoom=1.12)
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):
        axis.set_major_locator(MaxNLocator(4))
        axis.set_label_text(f"{name} (m)")
        axis.labelpad = 0
    ax.tick_params(pad=0)
    ax.view_init(elev=elev, azim=azim)
