"""Workspace plots (PNG, drawn at the size the report shows them, :mod:`sms_cli.report.figstyle`).

* :func:`cloud`: one index over the reachable workspace, as the XY, XZ and YZ projections of the
  end-effector positions in the satellite frame (R_sat: base-link frame, origin at the base-link
  origin, m); each cell shows the best value of the sampled configurations that project into it
  (the views of Kraiem 2022, Fig. 3.6-3.8);
* :func:`compare_clouds`: the same maps for every design variant on one colour scale;
* :func:`histograms`: the distribution of every index over the sampled workspace;
* :func:`slices`: how each index depends on each joint (mean over the other joints).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sms_cli.report import figstyle as S

LABELS = {
    "K_m": "K^m_ω0 (joint share of base attitude disturbance)",
    "K_r": "K^r_ω0 (wheel share)",
    "mu_fixed": "μ fixed base",
    "fixed_cond": "σmin/σmax of the fixed-base J_m",
    "mu_gjm": "μ(J*_mEE) free floating",
    "gjm_cond": "σmin/σmax of J*_mEE",
    "mu_ratio": "μ(J*_mEE) / μ fixed base",
    "mu_dyn": "dynamic manipulability μ*",
    "mu_scal_lin_norm": "μ(ṙ_EE) normalised (base free)",
    "mu_null_lin_norm": "μ^N(ṙ_EE) normalised (fixed attitude)",
    "mu_null_ang": "μ^N(ω_EE)",
    "joint_limit_margin": "joint-limit margin",
    "h_arm_max": "arm momentum at max joint speed (N m s)",
    "h_ratio": "arm momentum / wheel capacity",
}
# Panel titles (≤ 24 characters: they sit above a third of the figure width).
_R, _W = r"\dot{r}_\mathrm{EE}", r"\omega_\mathrm{EE}"
SHORT = {
    "K_m": r"$K^m_{\omega_0}$ joint share", "K_r": r"$K^r_{\omega_0}$ wheel share", "mu_fixed": r"$\mu$ fixed base",
    "fixed_cond": r"$\sigma_{min}/\sigma_{max}$ fixed base", "mu_gjm": r"$\mu(J^*)$ free floating",
    "gjm_cond": r"$\sigma_{min}/\sigma_{max}$ of $J^*$", "mu_ratio": r"$\mu(J^*)\,/\,\mu$ fixed base",
    "mu_dyn": r"dynamic $\mu^*$", "mu_scal_lin": f"$\\mu({_R})$ base free", "mu_null_lin": f"$\\mu^N({_R})$",
    "mu_null_ang": f"$\\mu^N({_W})$", "mu_scal_lin_norm": f"$\\mu({_R})$ normalised",
    "mu_null_lin_norm": f"$\\mu^N({_R})$ normalised", "joint_limit_margin": "joint-limit margin",
    "h_arm_max": "arm momentum (N m s)", "h_ratio": "arm / wheel momentum",
}
LOWER_IS_BETTER = frozenset({"K_m", "h_arm_max", "h_ratio"})
KEY_COLUMNS = ("K_m", "mu_gjm", "mu_ratio", "mu_dyn", "mu_scal_lin_norm", "mu_null_lin_norm", "h_ratio", "joint_limit_margin")
_PLANES = ((0, 1, "XY"), (0, 2, "XZ"), (1, 2, "YZ"))
_UNDEFINED = "#c9ced6"


def better(column: str) -> str:
    return "lower" if column in LOWER_IS_BETTER else "higher"


def _limits(values: np.ndarray, lo_pct: float = 1.0, hi_pct: float = 99.0) -> tuple[float, float]:
    v = values[np.isfinite(values)]
    if v.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(v, [lo_pct, hi_pct]) if v.size > 50 else (v.min(), v.max())
    return (float(lo), float(hi)) if hi > lo else (float(v.min()), float(v.max()) + 1e-12)


def _box(xyz_list: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Centre and (padded, never flat) span per axis of every cloud."""
    A = np.vstack([x[np.all(np.isfinite(x), axis=1)] for x in xyz_list] or [np.zeros((1, 3))])
    if not len(A):
        A = np.zeros((1, 3))
    lo, hi = A.min(axis=0), A.max(axis=0)
    span = hi - lo
    span = np.maximum(span, 0.05 * max(float(span.max()), 1e-3)) * 1.06
    return (lo + hi) / 2, span


def _cells(u: np.ndarray, v: np.ndarray, extent: tuple[float, float, float, float], cell: float
           ) -> tuple[np.ndarray, tuple[int, int]]:
    """Flat index of the cell of the (u, v) plane each sample projects into, and the grid shape (nv, nu)."""
    u0, u1, v0, v1 = extent
    nu, nv = max(1, int(round((u1 - u0) / cell))), max(1, int(round((v1 - v0) / cell)))
    iu = np.clip(((u - u0) / (u1 - u0) * nu).astype(int), 0, nu - 1)
    iv = np.clip(((v - v0) / (v1 - v0) * nv).astype(int), 0, nv - 1)
    return iv * nu + iu, (nv, nu)


def _best_map(flat: np.ndarray, shape: tuple[int, int], values: np.ndarray, lower: bool) -> tuple[np.ndarray, np.ndarray]:
    """Best finite value per cell (``flat``: each sample's cell, :func:`_cells`), and the cells holding
    only undefined samples."""
    size = shape[0] * shape[1]
    ok = np.isfinite(values)
    best = np.full(size, np.inf if lower else -np.inf)
    (np.minimum if lower else np.maximum).at(best, flat[ok], values[ok])
    undefined = np.zeros(size, dtype=bool)
    undefined[flat[~ok]] = True
    best[~np.isfinite(best)] = np.nan
    undefined &= np.isnan(best)
    return best.reshape(shape), undefined.reshape(shape)


def _cell(spans: np.ndarray, n: int) -> float:
    """Cell size: about 4 samples per occupied cell of a projection, 12 to 90 cells across."""
    across = int(np.clip(np.sqrt(max(n, 1) / 4.0), 12, 90))
    return float(spans.max()) / across


class _Maps:
    """The XY, XZ and YZ maps of one or more point clouds (a row of three panels each, one colour bar),
    built once and redrawn for each index column: the layout, projections, extents, axes and their
    ticks do not depend on the column; only the images, the colour scale, the titles and the notes do.
    The axes are drawn once (:class:`figstyle.Redraw`); a figure drawn after others is, byte for byte,
    the figure a fresh one draws (``tests/test_analysis_plots.py``)."""

    def __init__(self, xyz_list: list[np.ndarray], n: int):
        from matplotlib.colors import Normalize

        self.centre, self.span = _box(xyz_list)
        self.fig, self.axes = _cloud_figure(self.span, len(xyz_list))
        cell = _cell(self.span, n)
        self.cells = []  # per row and plane: flat cell index of each sample, grid shape
        self.images = []  # per row and plane: [best-value image, undefined-cells image or None]
        for row, xyz in zip(self.axes, xyz_list):
            cells, images = [], []
            for ax, (i, j, name) in zip(row, _PLANES):
                c, s = self.centre, self.span
                ext = (c[i] - s[i] / 2, c[i] + s[i] / 2, c[j] - s[j] / 2, c[j] + s[j] / 2)
                flat, shape = _cells(xyz[:, i], xyz[:, j], ext, cell)
                cells.append((flat, shape))
                im = ax.imshow(np.full(shape, np.nan), origin="lower", extent=ext, norm=Normalize(0, 1),
                               interpolation="nearest", aspect="equal")
                images.append([im, None, ext])
                ax.set_xlabel(f"{'xyz'[i]} (m)")
                ax.set_ylabel(f"{'xyz'[j]} (m)", labelpad=3)
                ax.set_title(f"{name} projection")
                ax.grid(False)
                ax.locator_params(nbins=5)
            self.cells.append(cells)
            self.images.append(images)
        W, H = self.fig.canvas.get_width_height()
        m = _CLOUD
        cax = S.px_axes(self.fig, W - m["right"] + 14, m["bottom"], 14, H - m["top"] - m["bottom"])
        self.colorbar = self.fig.colorbar(self.images[-1][-1][0], cax=cax)
        # above the bar, clear of its top tick label
        self.note = self.fig.text((W - m["right"] + 4) / W, (H - m["top"] + 11) / H, "grey: undefined",
                                  fontsize=S.MIN_FONT_PT, va="bottom", visible=False)
        self.title = self.fig.suptitle("", x=0.01, y=0.99, ha="left", va="top")
        self._redraw = S.Redraw(self.fig, self._changing)

    def _changing(self) -> list:
        """What differs between two columns, in the order a full draw paints it: per panel its images
        (undefined cells under the values) and its frame over them, then the colour bar and the texts."""
        out = []
        for row, slots in zip(self.axes, self.images):
            for ax, (values, grey, _) in zip(row, slots):
                out += [a for a in (grey, values) if a is not None] + list(ax.spines.values())
        return out + [self.colorbar.ax, self.note, self.title]

    def draw(self, values_list: list[np.ndarray], column: str, title: str, row_titles: list[str] | None = None,
             vlim: tuple[float, float] | None = None) -> bytes:
        """The PNG (:func:`figstyle.render`) of ``column``: ``values_list`` holds its values per row."""
        norm = _norm(np.concatenate(values_list), vlim)
        lower = column in LOWER_IS_BETTER
        for r, (row, values) in enumerate(zip(self.axes, values_list)):
            for p, (ax, (flat, shape), slot) in enumerate(zip(row, self.cells[r], self.images[r])):
                best, undef = _best_map(flat, shape, values, lower)
                if slot[1] is not None and not undef.any():
                    slot[1].remove()
                    slot[1] = None
                elif undef.any():
                    grey = np.ma.masked_where(~undef, np.ones(undef.shape))
                    if slot[1] is None:  # under the values (zorder), as if drawn first
                        slot[1] = ax.imshow(grey, origin="lower", extent=slot[2], cmap=_grey_cmap(), vmin=0, vmax=1,
                                            interpolation="nearest", aspect="equal", zorder=-1)
                    else:
                        slot[1].set_data(grey)
                slot[0].set_data(best)
                slot[0].set_norm(norm)
            if row_titles is not None:
                row[0].set_title(f"{row_titles[r]}{_PLANES[0][2]}")
        self.colorbar.set_label(f"{SHORT.get(column, column)}\n({better(column)} is better)")
        self.note.set_visible(any(bool((~np.isfinite(v)).any()) for v in values_list))
        self.title.set_text(title)
        # panel titles that change are placed by the axes' draw (clear of a y offset text): draw it all
        return self._redraw.png() if row_titles is None else S.render(self.fig, close=False)

    def close(self) -> None:
        S.pyplot().close(self.fig)


def _grey_cmap():
    from matplotlib.colors import ListedColormap

    return ListedColormap([_UNDEFINED])


_CLOUD = {"left": 56, "right": 118, "top": 52, "bottom": 44, "wgap": 64, "hgap": 62}


def _cloud_figure(spans: np.ndarray, rows: int):
    """Figure and axes (rows × XY, XZ, YZ) whose widths follow the horizontal spans, so the cells are
    square and every panel is as tall as the figure allows."""
    m = _CLOUD
    ratios = [float(spans[0]), float(spans[0]), float(spans[1])]
    usable = S.FULL_PX - m["left"] - m["right"] - 2 * m["wgap"]
    panel_h = float(np.clip(usable * float(max(spans[1], spans[2])) / sum(ratios), 170, 330))
    height = int(m["top"] + rows * panel_h + (rows - 1) * m["hgap"] + m["bottom"])
    return S.panels(S.FULL_PX, height, rows, 3, width_ratios=ratios, **m)


def _norm(values: np.ndarray, vlim: tuple[float, float] | None):
    from matplotlib.colors import Normalize

    vmin, vmax = vlim or _limits(values)
    return Normalize(vmin=vmin, vmax=vmax, clip=True)


@S.styled
def clouds(xyz: np.ndarray, items: list[tuple[Path, np.ndarray, str, str]],
           vlim: tuple[float, float] | None = None) -> list[tuple[Path, bytes]]:
    """:func:`cloud` of several index columns over the same end-effector positions, as (path, PNG bytes)
    to write (nothing is written here): ``items`` holds (path, values, column, title) per figure.
    The figure is built once and redrawn per column."""
    maps = _Maps([xyz], min((len(v) for _, v, _, _ in items), default=len(xyz)))
    try:
        return [(Path(path), maps.draw([values], column, title, vlim=vlim)) for path, values, column, title in items]
    finally:
        maps.close()


def cloud(path: Path, xyz: np.ndarray, values: np.ndarray, column: str, title: str,
          vlim: tuple[float, float] | None = None) -> Path:
    """One index over the workspace: XY, XZ and YZ maps of the best value per cell (R_sat, m)."""
    from sms_cli.results import write_bytes_atomic

    [(p, png)] = clouds(xyz, [(path, values, column, title)], vlim)
    return write_bytes_atomic(p, png)


@S.styled
def compare_figures(clouds_: list[tuple[str, np.ndarray]], items: list[tuple[Path, list[np.ndarray], str, str]]
                    ) -> list[tuple[Path, bytes]]:
    """:func:`compare_clouds` of several index columns over the same variants (names and end-effector
    positions in ``clouds_``), as (path, PNG bytes); ``items`` holds (path, values per variant, column,
    title). The figure is built once and redrawn per column."""
    maps = _Maps([xyz for _, xyz in clouds_], min(len(v) for _, vals, _, _ in items for v in vals))
    out = []
    try:
        for path, values, column, title in items:
            rows = []
            for (name, _), v in zip(clouds_, values):
                fin = v[np.isfinite(v)]
                best = f" (best {(fin.min() if column in LOWER_IS_BETTER else fin.max()):.3g})" if fin.size else ""
                rows.append(f"{name}{best}: ")
            out.append((Path(path), maps.draw(list(values), column, title, row_titles=rows)))
        return out
    finally:
        maps.close()


def compare_clouds(path: Path, clouds_: list[tuple[str, np.ndarray, np.ndarray]], column: str, title: str) -> Path:
    """One index for several variants, a row of XY, XZ, YZ maps per variant, one colour scale."""
    from sms_cli.results import write_bytes_atomic

    [(p, png)] = compare_figures([(n, xyz) for n, xyz, _ in clouds_], [(path, [v for _, _, v in clouds_], column, title)])
    return write_bytes_atomic(p, png)


def histograms(path: Path, rows: np.ndarray, columns: list[str], title: str) -> Path:
    """One histogram per index column (finite values between the 0.5 and 99.5 percentiles; median dashed)."""
    from sms_cli.results import write_bytes_atomic

    return write_bytes_atomic(path, histograms_png(rows, columns, title))


@S.styled
def histograms_png(rows: np.ndarray, columns: list[str], title: str) -> bytes:
    """The PNG of :func:`histograms`."""
    from matplotlib.ticker import MaxNLocator

    cols = [c for c in columns if not c.startswith("ee_") and c != "singular"]
    ncol = 3
    nrow = max(1, -(-len(cols) // ncol))
    fig, axes = S.panels(S.FULL_PX, 44 + 140 * nrow + 58 * (nrow - 1) + 36, nrow, ncol, top=44, bottom=36, left=60,
                         wgap=62, hgap=58)
    for ax in axes.flat[len(cols):]:
        ax.set_visible(False)
    for k, (ax, c) in enumerate(zip(axes.flat, cols)):
        v = rows[:, columns.index(c)]
        v = v[np.isfinite(v)]
        if v.size:
            lo, hi = _limits(v, 0.5, 99.5)
            ax.hist(v, bins=40, range=(lo, hi), histtype="stepfilled", color="#4c78a8", alpha=0.85)
            ax.axvline(float(np.median(v)), color="k", lw=1, ls="--")
            ax.set_title(SHORT.get(c, c))
        else:
            ax.set_title(f"{SHORT.get(c, c)}: no finite value")
        ax.locator_params(axis="x", nbins=4)
        ax.yaxis.set_major_locator(MaxNLocator(3, prune="lower"))  # the 0 count would sit on the first x label
        if k % ncol == 0:
            ax.set_ylabel("samples")
    fig.suptitle(title + ": distribution of each index over the sampled workspace", x=0.01, y=0.995, ha="left",
                 va="top")
    return S.render(fig)


def slices(path: Path, slice_data: list[dict], columns: list[str], title: str) -> Path:
    """Per index, its mean along each joint (the other joints sampled), joints on a common 0-1 axis."""
    from sms_cli.results import write_bytes_atomic

    return write_bytes_atomic(path, slices_png(slice_data, columns, title))


@S.styled
def slices_png(slice_data: list[dict], columns: list[str], title: str) -> bytes:
    """The PNG of :func:`slices`."""
    cols = [c for c in KEY_COLUMNS if c in columns] or [c for c in columns if not c.startswith("ee_")][:8]
    ncol = 4 if len(cols) > 4 else max(len(cols), 1)
    nrow = max(1, -(-len(cols) // ncol))
    height = 44 + 170 * nrow + 46 * (nrow - 1) + 78
    fig, axes = S.panels(S.FULL_PX, height, nrow, ncol, top=44, bottom=78, left=60, wgap=58, hgap=46, sharex=True)
    for ax in axes.flat[len(cols):]:
        ax.set_visible(False)
    handles = []
    for k, (ax, c) in enumerate(zip(axes.flat, cols)):
        ci = columns.index(c)
        for j, s in enumerate(slice_data):
            x = np.asarray(s["x"], dtype=float)
            span = (x.max() - x.min()) if x.size > 1 else 1.0
            u = (x - x.min()) / span if span > 0 else np.zeros_like(x)
            (h,) = ax.plot(u, s["mean"][:, ci], color=f"C{j % 10}", lw=1.4, marker="o" if x.size < 8 else None, ms=3)
            if k == 0:
                handles.append((h, s["joint"]))
        ax.set_title(SHORT.get(c, c))
        ax.locator_params(axis="y", nbins=4)
        ax.set_xticks([0, 0.5, 1])
        ax.set_xticklabels(["lower", "mid", "upper"])
    fig.supxlabel("joint position within its sampled range (mean of the index over the other joints)", y=30 / height,
                  va="bottom")
    if handles:
        fig.legend([h for h, _ in handles], [t for _, t in handles], loc="lower center", bbox_to_anchor=(0.5, 0),
                   ncols=min(len(handles), 6), borderaxespad=0.2, handlelength=1.6)
    fig.suptitle(title + ": index against each joint", x=0.01, y=0.995, ha="left", va="top")
    return S.render(fig)
