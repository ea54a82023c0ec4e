"""What wrenches a thruster set can produce (``sms compile``), and the refusal of a set that lacks a
direction the mission commands.

Pure wrench along a unit 6-D direction u: the largest a with a u = B x, 0 ≤ x ≤ x_max (an LP,
``Allocator.pure_capability``). The achievable pure torques (force zero) form a convex set containing 0,
so the set has full torque authority exactly when all six ±axis capabilities are positive (the convex
hull of those six points contains a ball about 0); likewise for forces and for the full 6-D wrench.
The minimum over directions is sampled (``n_dirs`` Fibonacci-sphere directions plus the axes): an
upper bound on the true minimum, which the axes' octahedron bounds from below (min axis / √3).
"""

from __future__ import annotations

import numpy as np

from sms_cli.thrusters.allocation import Allocator
from sms_cli.thrusters.layout import ThrusterSet

AXES = ("x", "y", "z")


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) nearly uniform unit vectors."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    th = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], axis=1)


def axis_capability(ts: ThrusterSet, kind: str) -> dict[str, float]:
    """{'+x': a, '-x': a, …}: largest pure force (kind 'force', N) or pure torque ('torque', N m) per axis."""
    alloc = Allocator(ts.B, ts.max_force)
    off = 0 if kind == "force" else 3
    out = {}
    for k, ax in enumerate(AXES):
        for sign in (1, -1):
            u = np.zeros(6)
            u[off + k] = sign
            out[f"{'+' if sign > 0 else '-'}{ax}"] = alloc.pure_capability(u)
    return out


def min_over_directions(ts: ThrusterSet, kind: str, n_dirs: int = 100) -> tuple[float, list[float]]:
    """(smallest sampled pure capability, its direction) over unit force or torque directions."""
    alloc = Allocator(ts.B, ts.max_force)
    off = 0 if kind == "force" else 3
    dirs = np.vstack([fibonacci_sphere(n_dirs), np.eye(3), -np.eye(3)])
    best, arg = np.inf, None
    for d in dirs:
        u = np.zeros(6)
        u[off:off + 3] = d
        a = alloc.pure_capability(u)
        if a < best:
            best, arg = a, d
    return float(best), [float(c) for c in arg]


def capability_report(ts: ThrusterSet) -> dict:
    """The compile summary's ``thrusters`` entry."""
    force, torque = axis_capability(ts, "force"), axis_capability(ts, "torque")
    fmin, fdir = min_over_directions(ts, "force")
    tmin, tdir = min_over_directions(ts, "torque")
    return {
        "count": ts.n, "firing_cycle_s": ts.firing_cycle, "mib_s": ts.mib, "quantization": ts.quantization,
        "propellant_kg": ts.propellant, "tank_position_m": ts.tank_position.tolist(),
        "pure_force_N": force, "pure_torque_Nm": torque,
        "min_pure_force_N": {"value": fmin, "direction": fdir},
        "min_pure_torque_Nm": {"value": tmin, "direction": tdir},
        "thrusters": [{"name": n, "position_m": p.tolist(), "direction": d.tolist(), "max_force_N": float(f),
                       "isp_s": float(i)} for n, p, d, f, i in zip(ts.names, ts.position, ts.direction, ts.max_force, ts.isp)],
    }


def missing_directions(ts: ThrusterSet, kind: str, tol: float = 1e-9) -> list[str]:
    """The ±axes (e.g. '-z torque') along which the set produces no pure force or torque."""
    cap = axis_capability(ts, kind)
    scale = float(np.linalg.norm(ts.B, axis=0) @ ts.max_force)
    return [f"{k} {kind}" for k, a in cap.items() if a <= tol * scale]


def format_report(r: dict) -> list[str]:
    """Lines for ``format_summary``."""
    f, t = r["pure_force_N"], r["pure_torque_Nm"]
    return [
        f"thrusters {r['count']}, firing cycle {r['firing_cycle_s']:g} s, MIB {r['mib_s']:g} s, quantization "
        f"{r['quantization']:g} of the cycle, propellant {r['propellant_kg']:g} kg",
        "          pure force  (N)   " + "  ".join(f"{k} {v:.4g}" for k, v in f.items()),
        "          pure torque (N m) " + "  ".join(f"{k} {v:.4g}" for k, v in t.items()),
        f"          minimum over directions: force {r['min_pure_force_N']['value']:.4g} N, torque "
        f"{r['min_pure_torque_Nm']['value']:.4g} N m",
    ]
