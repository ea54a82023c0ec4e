"""Report-only plots made from the recorded simulation (PNG bytes at the report's width,
:mod:`sms_cli.report.figstyle`; labelled, SI units).

* wheel momentum: ``h_i = I_s,i ω_i`` per wheel (N m s) from ``simulation.csv`` and the wheel
  inertias of the ``compile`` section, with the array momentum ``|Σ h_i a_i|`` (base frame);
* joint tracking: joint positions against their references (``/joints/position``,
  ``/joints/reference`` of the MCAP);
* end-effector path: ``/ee/position`` and ``/base/position`` of the MCAP in 3-D (world frame, m).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from sms_cli.report import figstyle as S


def read_topics(mcap_path: Path, topics: list[str]) -> dict[str, tuple[np.ndarray, list[dict]]]:
    """topic → (times in s, decoded messages) for the numeric topics asked for."""
    from sms_cli.recording.read import topic_series

    return {t: (np.array(ts), rows) for t, (ts, rows) in topic_series(mcap_path, topics).items()}


@S.styled
def wheel_momentum_png(csv_path: Path, wheels: list[dict[str, Any]]) -> bytes | None:
    """Per-wheel stored momentum and the array's momentum magnitude against time."""
    if not wheels or not csv_path.exists():
        return None
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or f"wheel_speed_{wheels[0]['name']}" not in rows[0]:
        return None
    t = np.array([float(r["t_s"]) for r in rows])
    h = np.array([[float(r[f"wheel_speed_{w['name']}"]) * w["spin_inertia_kgm2"] for w in wheels] for r in rows])
    axes = np.array([w["axis_base"] for w in wheels], dtype=float)
    h_vec = h @ axes
    fig, ax = S.new(S.FULL_PX, 300)
    for k, w in enumerate(wheels):
        ax.plot(t, h[:, k], lw=1.1, label=f"{w['name']} (capacity ±{w['spin_inertia_kgm2'] * w['max_speed_rad_s']:.3g})")
    ax.plot(t, np.linalg.norm(h_vec, axis=1), color="k", lw=1.6, label="|Σ h_i a_i| (array, base frame)")
    ax.set(xlabel="time (s)", ylabel="wheel momentum (N m s)", title="Reaction-wheel momentum h = I_s ω per wheel and of the array",
           xlim=(float(t[0]), float(t[-1])))
    fig.legend(loc="outside right upper")
    return S.render(fig)


@S.styled
def joint_tracking_png(topics: dict[str, tuple[np.ndarray, list[dict]]]) -> bytes | None:
    """Joint positions (solid) and references (dashed) against time."""
    if "/joints/position" not in topics:
        return None
    t, pos = topics["/joints/position"]
    names = list(pos[0])
    fig, ax = S.new(S.FULL_PX, 300)
    for k, n in enumerate(names):
        ax.plot(t, [p[n] for p in pos], color=f"C{k % 10}", lw=1.3, label=n)
    if "/joints/reference" in topics:
        tr, ref = topics["/joints/reference"]
        for k, n in enumerate(names):
            if n in ref[0]:
                ax.plot(tr, [r[n] for r in ref], color=f"C{k % 10}", lw=1, ls="--")
    ax.set(xlabel="time (s)", ylabel="joint position (rad or m)", title="Joint tracking (solid: measured, dashed: reference)",
           xlim=(float(t[0]), float(t[-1])))
    fig.legend(loc="outside right upper")
    return S.render(fig)


@S.styled
def ee_path_png(topics: dict[str, tuple[np.ndarray, list[dict]]]) -> bytes | None:
    """End-effector and base-origin paths in the world frame (3-D, equal axes)."""
    if "/ee/position" not in topics:
        return None
    _, ee = topics["/ee/position"]
    P = np.array([[p["x"], p["y"], p["z"]] for p in ee])
    fig = S.new_figure(S.HALF_PX, 440)
    ax = fig.add_subplot(111, projection="3d")
    ax.plot(*P.T, color="crimson", lw=1.5, label="end effector")
    ax.scatter(*P[0], color="crimson", marker="o", s=25, label="EE start")
    ax.scatter(*P[-1], color="crimson", marker="*", s=80, label="EE end")
    allp = [P]
    if "/base/position" in topics:
        _, base = topics["/base/position"]
        B = np.array([[p["x"], p["y"], p["z"]] for p in base])
        ax.plot(*B.T, color="navy", lw=1.2, label="base origin")
        allp.append(B)
    A = np.vstack(allp)
    mid = (A.max(axis=0) + A.min(axis=0)) / 2
    span = max(float(np.max(A.max(axis=0) - A.min(axis=0))), 1e-3)
    for setter, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
        setter(m - span / 2 * 1.1, m + span / 2 * 1.1)
    S.box3d(ax)
    travel = float(np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1))) if len(P) > 1 else 0.0
    ax.set_title(f"End-effector path, world frame (length {travel:.3g} m)")
    fig.legend(loc="outside lower center", ncols=2)
    return S.render(fig)
