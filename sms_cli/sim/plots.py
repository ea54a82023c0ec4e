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
    """Attitude error, wheel speeds/torques, joint tracking/torques, modal amplitudes vs time."""
    t = trace["t"]
    files: list[Path] = []
    if t.size == 0:
        return files
    present = [i for i in range(len(phase_names)) if np.any(trace["phase"] == i)]
    starts = [float(t[np.argmax(trace["phase"] == i)]) for i in present]
    names = [phase_names[i] for i in present]

    def finish(fig, axes, filename):
        for a in axes:
            if t[-1] > t[0]:  # a run that stopped at its first sample has no time span to show
                a.set_xlim(float(t[0]), float(t[-1]))
        S.phase_marks(axes[0], starts, names)
        for a in axes[1:]:
            S.phase_marks(a, starts)
        axes[-1].set_xlabel("time (s)")
        files.append(S.save(fig, out_dir / filename))

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
    ee = trace["ee_err"]
    if ee.size and np.any(np.isfinite(ee)):
        fig, ax = S.new(S.FULL_PX, 260)
        ax.plot(t, ee, lw=1.3, color="C0")
        ax.set(ylabel="EE position error (m)", title="End-effector tracking error")
        finish(fig, [ax], "sim_end_effector.png")
    return files
