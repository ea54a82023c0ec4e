"""Plots of a two-spacecraft run (PNG at the report's width, :mod:`sms_cli.report.figstyle`): relative (shape)
error, locked and shape twists, momentum and the kinetic-energy split. Pushes are dashed and named."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sms_cli.report import figstyle as S


@S.styled
def plot_formation(trace: dict, spec, names: tuple[str, str], out_dir: Path) -> list[Path]:
    t = trace["t"]
    files: list[Path] = []
    if t.size < 2:
        return files
    starts = [float(t[0])] + [float(p.at) for p in spec.pushes]  # phase_marks draws from the second start on
    labels = ["start"] + [f"{np.linalg.norm(p.force):g} N on {p.body}" for p in spec.pushes]

    def finish(fig, axes, filename):
        files.append(S.save_time_figure(fig, axes, t, starts, labels, out_dir / filename))

    fig, axes = S.new(S.FULL_PX, 420, 2, 1, sharex=True)
    pos = trace["shape_position"] * 100.0
    for i, c in enumerate("xyz"):
        axes[0].plot(t, pos[:, i], lw=1.1, label=c)
    axes[0].set(ylabel="position (cm)",
                   title=f"Relative (shape) error: {names[1]} in {names[0]}'s frame vs its setpoint")
    axes[0].legend(loc="upper right", ncols=3)
    axes[1].plot(t, np.degrees(trace["shape_angle"]), lw=1.1, color="C3")
    axes[1].set(ylabel="angle (deg)")
    finish(fig, [axes[0], axes[1]], "formation_shape_error.png")

    fig, axes = S.new(S.FULL_PX, 420, 2, 1, sharex=True)
    for key, ax, what in (("V_L", axes[0], f"locked twist V_L ({names[0]} frame)"),
                          ("V_E", axes[1], f"shape twist V_E ({names[1]} frame)")):
        V = trace[key]
        ax.plot(t, np.linalg.norm(V[:, :3], axis=1), lw=1.1, label="|v| (m/s)")
        ax.plot(t, np.linalg.norm(V[:, 3:], axis=1), lw=1.1, label="|ω| (rad/s)")
        ax.set(ylabel=what.split(" (")[0], title=what if ax is axes[0] else None)
        ax.legend(loc="upper right", ncols=2)
    axes[0].set_title("Locked (total) and shape (relative) motion, Vicariotto 2023 (5.5)")
    finish(fig, [axes[0], axes[1]], "formation_twists.png")

    fig, axes = S.new(S.FULL_PX, 420, 2, 1, sharex=True)
    H = trace["H_world"]
    for i, c in enumerate(("px", "py", "pz")):
        axes[0].plot(t, H[:, i], lw=1.1, label=c)
    for i, c in enumerate(("kx", "ky", "kz")):
        axes[1].plot(t, H[:, 3 + i], lw=1.1, label=c)
    axes[0].set(ylabel="linear (N s)", title="Total momentum of the pair (world frame, about its origin)")
    axes[1].set(ylabel="angular (N m s)")
    axes[0].legend(loc="upper right", ncols=3)
    axes[1].legend(loc="upper right", ncols=3)
    finish(fig, [axes[0], axes[1]], "formation_momentum.png")

    fig, ax = S.new(S.FULL_PX, 300)
    ax.plot(t, trace["T_L"], lw=1.1, label="locked ½V_LᵀM_LV_L")
    ax.plot(t, trace["T_E"], lw=1.1, label="shape ½V_EᵀM_EV_E")
    ax.plot(t, trace["T"] - trace["T_L"] - trace["T_E"], lw=1.1, label="wheels")
    ax.plot(t, trace["W"], lw=1.1, ls="--", color="k", label="Lyapunov W")
    ax.set(ylabel="energy (J)", title="Kinetic energy split and the law's Lyapunov function")
    ax.legend(loc="upper right", ncols=2)
    finish(fig, [ax], "formation_energy.png")
    return files
