"""``workspace.png``: the facility workspace an absolute and a relative replay need, over time, against
the envelope (one figure, the report's full width; ``sms_cli.report.figstyle`` fonts and size).

Panels: the displacement from the start along facility x, y and z (m), or its length with a radius
envelope, and the rotation angle from the start (deg). Absolute replay solid, relative replay dashed, the
envelope as dotted red lines, the time each replay leaves it as a vertical mark.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sms_cli.hil.workspace import AXES, Envelope, Excursion
from sms_cli.report import figstyle

ABS, REL, LIMIT = "#1f5fa8", "#d9730d", "#b3261e"


def _leave_mark(ax, t: float | None, color: str) -> None:
    if t is not None:
        ax.axvline(t, color=color, lw=0.9, ls="-.", zorder=1)


@figstyle.styled
def workspace_figure(absolute: Excursion, relative: Excursion, env: Envelope, metrics: dict, moving: str):
    """The figure (not yet rendered)."""
    box = env.half_ranges is not None
    fig, axes = figstyle.new(figstyle.FULL_PX, 520, 2, 2 if box else 1, squeeze=False, sharex=True)
    axes = axes.ravel()
    t = absolute.t
    leave_a, leave_r = metrics["absolute"]["leaves_envelope_s"], metrics["relative"]["leaves_envelope_s"]
    series = ([(absolute.displacement[:, i], relative.displacement[:, i], f"{a} from start (m)", env.half_ranges[i], True)
               for i, a in enumerate(AXES)] if box else
              [(np.linalg.norm(absolute.displacement, axis=1), np.linalg.norm(relative.displacement, axis=1),
                "distance from start (m)", env.radius, False)])
    series.append((np.degrees(absolute.angle), np.degrees(relative.angle), "rotation from start (deg)",
                   float(np.degrees(env.rotation)), False))
    for ax, (a, r, label, limit, both_signs) in zip(axes, series):
        ax.plot(t, a, color=ABS, label="absolute replay")
        ax.plot(t, r, color=REL, ls="--", label="relative replay")
        for sgn in ((1, -1) if both_signs else (1,)):
            ax.axhline(sgn * limit, color=LIMIT, lw=1.0, ls=":", label="envelope" if sgn > 0 else None, zorder=1)
        _leave_mark(ax, leave_a, ABS)
        _leave_mark(ax, leave_r, REL)
        ax.set_ylabel(label)
    for ax in axes[-2 if box else -1:]:
        ax.set_xlabel("time (s)")
    axes[0].legend(loc="best")
    left = ("absolute leaves the envelope at " + (f"{leave_a:.4g} s" if leave_a is not None else "never: stays inside")
            + " · relative " + (f"at {leave_r:.4g} s" if leave_r is not None else "stays inside"))
    fig.suptitle(f"Facility workspace of the {moving} mock-up: {left}", x=0.01, ha="left")
    return fig


def write_workspace_png(path: Path, absolute: Excursion, relative: Excursion, env: Envelope, metrics: dict,
                        moving: str) -> Path:
    return figstyle.save(workspace_figure(absolute, relative, env, metrics, moving), path)


__all__ = ["workspace_figure", "write_workspace_png"]
