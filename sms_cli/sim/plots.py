"""Simulation plots for the results folder and the report (PNG, labelled, SI units)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sms_cli.results import atomic_path


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, target: Path) -> Path:
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    return target


def plot_simulation(trace: dict, sm, phase_names: list[str], out_dir: Path) -> list[Path]:
    """Attitude error, wheel speeds/torques, joint tracking/torques, modal amplitudes vs time."""
    plt = _figure()
    t = trace["t"]
    files = []
    if t.size == 0:
        return files
    starts = [float(t[np.argmax(trace["phase"] == i)]) for i in range(len(phase_names)) if np.any(trace["phase"] == i)]

    def phases(ax):
        for s in starts[1:]:
            ax.axvline(s, color="0.7", lw=0.8, ls="--")

    fig, ax = plt.subplots(figsize=(8, 3.2))
    ax.plot(t, np.degrees(trace["att_err"]), lw=1.2)
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.set(xlabel="time (s)", ylabel="attitude error (deg)", title="Base attitude error (angle of q_ref⁻¹ q)")
    ax.grid(alpha=0.3)
    phases(ax)
    files.append(_save(fig, out_dir / "sim_attitude_error.png"))
    plt.close(fig)

    def two_panels(top, bottom, names, top_label, bottom_label, title, filename):
        fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
        axes[0].plot(t, top, lw=1)
        axes[0].set(ylabel=top_label, title=title)
        axes[1].plot(t, bottom, lw=1)
        axes[1].set(xlabel="time (s)", ylabel=bottom_label)
        axes[0].legend(names, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        for a in axes:
            a.grid(alpha=0.3)
            phases(a)
        files.append(_save(fig, out_dir / filename))
        plt.close(fig)

    if sm.wheels:
        two_panels(trace["wheel_speed"] * 60 / (2 * math.pi), trace["wheel_torque"], [w.name for w in sm.wheels],
                   "wheel speed (rpm)", "motor torque (N m)", "Reaction wheels", "sim_wheels.png")
    if sm.arm:
        two_panels(trace["joint_err"], trace["joint_torque"], [a.name for a in sm.arm],
                   "tracking error (rad or m)", "joint torque (N m or N)", "Manipulator joints", "sim_joints.png")
    if sm.n_modes:
        fig, ax = plt.subplots(figsize=(8, 3.2))
        ax.plot(t, trace["modal_peak"], lw=1)
        ax.set(xlabel="time (s)", ylabel="max |η| (√kg m)", title="Peak modal amplitude (flexible appendages)")
        ax.grid(alpha=0.3)
        phases(ax)
        files.append(_save(fig, out_dir / "sim_modes.png"))
        plt.close(fig)
    ee = trace["ee_err"]
    if ee.size and np.any(np.isfinite(ee)):
        fig, ax = plt.subplots(figsize=(8, 3.2))
        ax.plot(t, ee, lw=1.2)
        ax.set(xlabel="time (s)", ylabel="EE position error (m)", title="End-effector tracking error")
        ax.grid(alpha=0.3)
        phases(ax)
        files.append(_save(fig, out_dir / "sim_end_effector.png"))
        plt.close(fig)
    return files
