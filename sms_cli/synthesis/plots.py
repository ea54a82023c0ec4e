"""Pole map of the synthesised loops with the requested region drawn (PNG, rad/s)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sms_cli.results import atomic_path
from sms_cli.synthesis.regions import PoleRegion


def _region_patch(ax, reg: PoleRegion, color: str, label: str) -> None:
    """Shade the region {Re s ≤ −α} ∩ {ζ ≥ ζ_min} ∩ {|s| ≤ r} (upper and lower half)."""
    r, a = reg.radius, reg.alpha
    theta_max = math.acos(reg.zeta_min) if reg.zeta_min > 0 else math.pi / 2
    th = np.linspace(-theta_max, theta_max, 200)
    arc = -r * np.cos(th) + 1j * r * np.sin(th)  # |s| = r, angle from the negative real axis
    keep = arc.real <= -a
    pts = list(arc[keep])
    if reg.zeta_min > 0:
        # cone edges from the half plane line to the arc
        t = math.tan(theta_max)
        pts = [complex(-a, -a * t)] + pts + [complex(-a, a * t)]
    else:
        h = math.sqrt(max(r * r - a * a, 0.0))
        pts = [complex(-a, -h)] + pts + [complex(-a, h)]
    xs = [p.real for p in pts]
    ys = [p.imag for p in pts]
    ax.fill(xs, ys, color=color, alpha=0.12, label=label)
    ax.plot(xs + [xs[0]], ys + [ys[0]], color=color, lw=0.8)


def plot_pole_map(poles: list[dict], regions: dict[str, PoleRegion], target: Path, title: str) -> Path:
    """``poles``: per linearisation {label, controller: [...], observer: [...], ndo: [...]};
    ``regions``: {'controller': region, 'observer': region} (observer optional)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    colors = {"controller": "tab:blue", "observer": "tab:orange", "ndo": "tab:green"}
    for ax, zoom in zip(axes, (False, True)):
        for name, reg in regions.items():
            _region_patch(ax, reg, colors[name], f"{name} region")
        for key, marker in (("controller", "x"), ("observer", "+"), ("ndo", "^")):
            vals = np.concatenate([np.asarray(p.get(key, []), dtype=complex) for p in poles]) if poles else []
            if len(vals):
                ax.scatter(np.real(vals), np.imag(vals), marker=marker, s=28, color=colors[key],
                           label=f"{key} poles ({len(poles)} linearisation(s))")
        ax.axvline(0, color="0.5", lw=0.6)
        ax.axhline(0, color="0.5", lw=0.6)
        ax.set_xlabel("Re s (1/s)")
        ax.set_ylabel("Im s (rad/s)")
        if zoom and "controller" in regions:
            r = regions["controller"].radius * 1.3
            ax.set_xlim(-r, 0.15 * r)
            ax.set_ylim(-r, r)
            ax.set_title("zoom on the controller region")
        else:
            ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper left")
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return target
