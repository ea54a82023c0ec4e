"""Simulation plots for the results folder and the report (PNG at the report's width, SI units;
:mod:`sms_cli.report.figstyle`). Phase starts are dashed and named where there is room."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sms_cli.report import figstyle as S

RPM = 60 / (2 * math.pi)


@S.styled
def plot_simulation(trace: dict, sm, phase_names: list[str], out_dir: Path) -> list[Path]:
    """Attitude error, wheel speeds/torques, joint tracking/torques, modal amplitudes, thrusters (ideal vs
    delivered wrench, thrust, propellant), locked velocity μ and Lyapunov W, the NDI command's split vs time."""
    t = trace["t"]
    files: list[Path] = []
    if t.size == 0:
        return files
    present = [i for i in range(len(phase_names)) if np.any(trace["phase"] == i)]
    starts = [float(t[np.argmax(trace["phase"] == i)]) for i in present]
    names = [phase_names[i] for i in present]

    def finish(fig, axes, filename):
        files.append(S.save_time_figure(fig, axes, t, starts, names, out_dir / filename))

    fig, ax = S.new(S.FULL_PX, 280)
    ax.plot(t, np.degrees(trace["att_err"]), lw=1.3, color="C0")
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.set(ylabel="attitude error (deg)", title="Base attitude error: angle of q_ref⁻¹ q (log scale above 0.001 deg)")
    finish(fig, [ax], "sim_attitude_error.png")

    def two_panels(top, bottom, names_, top_label, bottom_label, title, filename, limits=(None, None), units=("", "")):
        fig, axes = S.new(S.FULL_PX, 420, 2, 1, sharex=True)
        handles = axes[0].plot(t, top, lw=1.1)
        axes[0].set(ylabel=top_label, title=title)
        axes[1].plot(t, bottom, lw=1.1)
        axes[1].set(ylabel=bottom_label)
        marks = [m for m in (S.limit_lines(a, lim, d, unit=u) for a, lim, d, u in zip(axes, limits, (top, bottom), units))
                 if m is not None]
        fig.legend(handles + marks[:1], list(names_) + ["limit"] * bool(marks), loc="outside right upper")
        finish(fig, list(axes), filename)

    if sm.wheels:
        speed_lim = min((w.max_speed for w in sm.wheels), default=None)
        torque_lim = min((w.max_torque for w in sm.wheels), default=None)
        two_panels(trace["wheel_speed"] * RPM, trace["wheel_torque"], [w.name for w in sm.wheels],
                   "wheel speed (rpm)", "motor torque (N m)", "Reaction wheels: speeds and torques against their limits",
                   "sim_wheels.png", (speed_lim * RPM if speed_lim else None, torque_lim), ("rpm", "N m"))
    if sm.arm:
        two_panels(trace["joint_err"], trace["joint_torque"], [a.name for a in sm.arm],
                   "tracking error (rad or m)", "joint torque (N m or N)", "Manipulator joints: tracking errors and torques",
                   "sim_joints.png")
    if sm.n_modes:
        fig, ax = S.new(S.FULL_PX, 260)
        ax.plot(t, trace["modal_peak"], lw=1.1, color="C0")
        ax.set(ylabel="max |η| (√kg m)", title="Flexible appendages: largest modal amplitude")
        finish(fig, [ax], "sim_modes.png")
    if "thruster_commanded" in trace:  # Vicariotto 2023 Figs. 4.4d/4.5d: ideal vs delivered, thrust, propellant
        cmd, dlv = trace["thruster_commanded"], trace["thruster_delivered"]
        fig, axes = S.new(S.FULL_PX, 560, 3, 1, sharex=True)
        for ax, first, sym, unit in ((axes[0], 3, "n", "torque (N m)"), (axes[1], 0, "f", "force (N)")):
            for k, c in enumerate("xyz"):
                ax.plot(t, cmd[:, first + k], lw=1.0, color=f"C{k}", label=f"ideal {sym}{c}")
                ax.step(t, dlv[:, first + k], where="post", lw=0.8, ls="--", color=f"C{k}", label=f"delivered {sym}{c}")
            ax.set(ylabel=unit)
        axes[0].set_title("Thrusters: ideal torque vs the firings' cycle average, thrust, propellant")
        axes[2].step(t, trace["thrust_total"], where="post", lw=0.9, color="C0", label="total thrust")
        axes[2].set(ylabel="total thrust (N)")
        ax2 = axes[2].twinx()
        ax2.plot(t, trace["propellant_used"] * 1e3, lw=1.3, color="C3", label="propellant used")
        ax2.set_ylabel("propellant used (g)", color="C3")
        h0, l0 = axes[0].get_legend_handles_labels()
        fig.legend(h0 + axes[2].get_lines() + ax2.get_lines(), l0 + ["total thrust", "propellant used"],
                   loc="outside right upper")
        finish(fig, list(axes), "sim_thrusters.png")
    if "locked" in trace:  # the momentum laws: locked velocity mu (4.8) and Lyapunov function W
        fig, axes = S.new(S.FULL_PX, 420, 2, 1, sharex=True)
        mu = trace["locked"]
        for k, c in enumerate("xyz"):
            axes[0].plot(t, np.degrees(mu[:, k]), lw=1.1, color=f"C{k}", label=f"μ{c}")
        axes[0].set(ylabel="μ (deg/s)", title="Locked velocity μ = ω + Λθ̇ and the law's Lyapunov function W")
        W = trace["lyapunov"]
        axes[1].plot(t, W, lw=1.3, color="C0")
        if np.all(W[np.isfinite(W)] > 0):
            axes[1].set_yscale("log")
        axes[1].set(ylabel="W (J)")
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside right upper")
        finish(fig, list(axes), "sim_momentum.png")
    if "ndi_torque_split" in trace and np.any(trace["ndi_torque_split"]):  # Kraiem 2022 Figs. 3.15, 4.28
        na = trace["ndi_torque_split"].shape[1] // 3
        split = np.abs(trace["ndi_torque_split"].reshape(-1, 3, na))
        groups = [(g, cols) for g, cols in (("wheels", slice(0, len(sm.wheels))), ("arm", slice(len(sm.wheels), na)))
                  if cols.stop > cols.start]
        fig, axes = S.new(S.FULL_PX, 210 * len(groups) + 60, len(groups), 1, sharex=True)
        axes = np.atleast_1d(axes)
        for ax, (group, cols) in zip(axes, groups):
            for c, label in enumerate(("feedback M◇v", "linearising n(x_e = 0)", "disturbance n − n(0) − τ̂_d")):
                y = split[:, c, cols].max(axis=1)
                ax.plot(t, np.where(y > 0, y, np.nan), lw=1.1, color=f"C{c}", label=label)
            ax.set_yscale("log")
            ax.set(ylabel=f"{group}: max |τ| (N m or N)")
        axes[0].set_title("NDI command split (largest over the actuators of each group; log scale)")
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside right upper")
        finish(fig, list(axes), "sim_torque_split.png")
    ee = trace["ee_err"]
    if ee.size and np.any(np.isfinite(ee)):
        fig, ax = S.new(S.FULL_PX, 260)
        ax.plot(t, ee, lw=1.3, color="C0")
        ax.set(ylabel="EE position error (m)", title="End-effector tracking error")
        finish(fig, [ax], "sim_end_effector.png")
    return files
