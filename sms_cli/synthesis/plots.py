"""Pole map of the synthesised loops with the requested region drawn (PNG at the report's width, rad/s)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sms_cli.report import figstyle as S
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


@S.styled
def plot_pole_map(poles: list[dict], regions: dict[str, PoleRegion], target: Path, title: str) -> Path:
    """``poles``: per linearisation {label, controller: [...], observer: [...], ndo: [...]};
    ``regions``: {'controller': region, 'observer': region} (observer optional). Left: every pole and
    region; right: zoom on the controller region (the poles a reviewer checks against it)."""
    fig, axes = S.new(S.FULL_PX, 380, 1, 2)
    colors = {"controller": "tab:blue", "observer": "tab:orange", "ndo": "tab:green"}
    for ax, zoom in zip(axes, (False, True)):
        for name, reg in regions.items():
            _region_patch(ax, reg, colors[name], f"{name} region")
        for key, marker in (("controller", "x"), ("observer", "+"), ("ndo", "^")):
            vals = np.concatenate([np.asarray(p.get(key, []), dtype=complex) for p in poles]) if poles else []
            if len(vals):
                ax.scatter(np.real(vals), np.imag(vals), marker=marker, s=30, color=colors[key], rasterized=True,
                           label=f"{key} poles ({len(poles)} linearisation{'s' * (len(poles) != 1)})")
        ax.axvline(0, color="0.5", lw=0.6)
        ax.axhline(0, color="0.5", lw=0.6)
        ax.set_xlabel("Re s (1/s)")
        ax.set_ylabel("Im s (rad/s)")
        ax.locator_params(nbins=5)
        if zoom and "controller" in regions:
            r = regions["controller"].radius * 1.3
            ax.set_xlim(-r, 0.15 * r)
            ax.set_ylim(-r, r)
            ax.set_title("zoom on the controller region")
        else:
            ax.set_title(title)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=3)
    return S.save(fig, target)
