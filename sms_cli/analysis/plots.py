"""Workspace plots (PNG): the end-effector cloud coloured by an index in the satellite frame
(the views of seed 004 Fig. 3.6-3.8), index histograms, and index slices along each joint.

Positions in metres in R_sat (base-link frame, origin at the base-link origin).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sms_cli.results import atomic_path

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
KEY_COLUMNS = ("K_m", "mu_gjm", "mu_ratio", "mu_dyn", "mu_scal_lin_norm", "mu_null_lin_norm", "h_ratio", "joint_limit_margin")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    _plt().close(fig)
    return Path(path)


def _limits(values: np.ndarray) -> tuple[float, float]:
    v = values[np.isfinite(values)]
    if v.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(v, [1, 99]) if v.size > 50 else (v.min(), v.max())
    return (float(lo), float(hi)) if hi > lo else (float(v.min()), float(v.max()) + 1e-12)


def cloud(path: Path, xyz: np.ndarray, values: np.ndarray, column: str, title: str,
          vlim: tuple[float, float] | None = None) -> Path:
    """EE positions coloured by ``values``: a 3-D view and the XY, XZ, YZ projections (R_sat)."""
    plt = _plt()
    fig = plt.figure(figsize=(11, 9))
    ok = np.isfinite(values)
    vmin, vmax = vlim or _limits(values)
    size = 4 if len(values) > 5000 else 10
    ax = fig.add_subplot(2, 2, 1, projection="3d")
    sc = ax.scatter(xyz[ok, 0], xyz[ok, 1], xyz[ok, 2], c=values[ok], s=size, cmap="viridis", vmin=vmin, vmax=vmax,
                    depthshade=False)
    ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)"), ax.set_zlabel("z (m)")
    ax.view_init(elev=25, azim=-60)
    for k, (i, j, name) in enumerate(((0, 1, "XY"), (0, 2, "XZ"), (1, 2, "YZ")), start=2):
        a = fig.add_subplot(2, 2, k)
        order = np.argsort(values[ok])  # best values drawn last
        a.scatter(xyz[ok][order, i], xyz[ok][order, j], c=values[ok][order], s=size, cmap="viridis", vmin=vmin, vmax=vmax)
        if (~ok).any():
            a.scatter(xyz[~ok, i], xyz[~ok, j], s=size, c="lightgrey", label="undefined")
        a.set_xlabel("xyz"[i] + " (m)"), a.set_ylabel("xyz"[j] + " (m)"), a.set_title(f"{name} projection")
        a.set_aspect("equal", adjustable="datalim")
    fig.colorbar(sc, ax=fig.axes, shrink=0.6, label=LABELS.get(column, column))
    fig.suptitle(title)
    return _save(fig, path)


def compare_clouds(path: Path, clouds: list[tuple[str, np.ndarray, np.ndarray]], column: str, title: str) -> Path:
    """Side-by-side 3-D EE clouds of one index for several variants, one colour scale (Fig. 3.6)."""
    plt = _plt()
    n = len(clouds)
    fig = plt.figure(figsize=(6 * n, 5.5))
    allv = np.concatenate([v for _, _, v in clouds])
    vmin, vmax = _limits(allv)
    for k, (name, xyz, v) in enumerate(clouds, start=1):
        ax = fig.add_subplot(1, n, k, projection="3d")
        ok = np.isfinite(v)
        sc = ax.scatter(xyz[ok, 0], xyz[ok, 1], xyz[ok, 2], c=v[ok], s=4, cmap="viridis", vmin=vmin, vmax=vmax, depthshade=False)
        ax.set_title(f"{name}: max {np.nanmax(v):.3g}, min {np.nanmin(v):.3g}")
        ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)"), ax.set_zlabel("z (m)")
    fig.colorbar(sc, ax=fig.axes, shrink=0.7, label=LABELS.get(column, column))
    fig.suptitle(title)
    return _save(fig, path)


def histograms(path: Path, rows: np.ndarray, columns: list[str], title: str) -> Path:
    """One histogram per index column (finite values)."""
    plt = _plt()
    cols = [c for c in columns if not c.startswith("ee_") and c != "singular"]
    n = len(cols)
    ncol = 4
    nrow = max(1, -(-n // ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4 * ncol, 2.8 * nrow), squeeze=False)
    for ax in axes.flat[n:]:
        ax.axis("off")
    for ax, c in zip(axes.flat, cols):
        v = rows[:, columns.index(c)]
        v = v[np.isfinite(v)]
        if v.size:
            ax.hist(v, bins=50, color="tab:blue")
        ax.set_title(LABELS.get(c, c), fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def slices(path: Path, slice_data: list[dict], columns: list[str], title: str) -> Path:
    """Index envelopes along each sampled joint: min, mean and max over the other joints."""
    plt = _plt()
    cols = [c for c in KEY_COLUMNS if c in columns] or [c for c in columns if not c.startswith("ee_")][:6]
    nj = len(slice_data)
    fig, axes = plt.subplots(len(cols), nj, figsize=(3.2 * nj + 1, 2.2 * len(cols) + 0.8), squeeze=False)
    for r, c in enumerate(cols):
        ci = columns.index(c)
        for j, s in enumerate(slice_data):
            ax = axes[r, j]
            x = s["x"]
            ax.fill_between(x, s["min"][:, ci], s["max"][:, ci], color="tab:blue", alpha=0.25, lw=0)
            ax.plot(x, s["mean"][:, ci], color="tab:blue", lw=1.2)
            if r == len(cols) - 1:
                ax.set_xlabel(s["joint"])
            if j == 0:
                ax.set_ylabel(c, fontsize=8)
            ax.tick_params(labelsize=7)
    fig.suptitle(title + " (band: min-max over the other joints; line: mean)")
    fig.tight_layout()
    return _save(fig, path)
