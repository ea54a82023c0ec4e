"""The thrusters in the simulation loop: one allocation + modulation per control tick, and the plant
stepped piecewise between thruster switchings with the base mass updated as propellant is spent.

Timing: the control period is a whole number k ≥ 1 of firing cycles (checked at compile,
``sms_cli.thrusters.check``). At each control tick t0 the commanded wrench is allocated
(``Allocator``) and modulated (``on_times``); that firing pattern repeats in each of the k cycles
of the tick: thruster i is on at full force during [t0 + jT, t0 + jT + t_i). A plant step is cut at
every switching instant inside it, so the plant sees each firing exactly, and each piece is
integrated with the base body holding the mass at the piece's midpoint (a constant burn is then the
rocket equation up to O((ṁh/m)³) per piece). When the tank is empty the thrusters deliver nothing.
"""

from __future__ import annotations

import numpy as np

from sms_cli.thrusters.allocation import Allocator
from sms_cli.thrusters.layout import ThrusterSet
from sms_cli.thrusters.modulation import on_times
from sms_cli.thrusters.propellant import Tank


class ThrusterDrive:
    """State of the thruster set during a run (see the module docstring). Wrenches are [f; n] in the
    base joint frame (N, N m); times in s; masses in kg."""

    def __init__(self, sm, ts: ThrusterSet, on_change=None):
        self.ts = ts
        self.B = ts.B
        self.allocator = Allocator(self.B, ts.max_force)
        self.tank = Tank(sm, ts.tank_position, ts.propellant)
        self.mdot = ts.mass_flow
        self.on_change = on_change  # called after the model's base inertia changed (compiled plant refresh)
        self.used = 0.0
        self.t0 = 0.0
        self.on = np.zeros(ts.n)  # on-times of the current pattern
        self.thrust_cmd = np.zeros(ts.n)
        self.commanded = np.zeros(6)
        self.delivered = np.zeros(6)  # averaged over the last plant step
        self.thrust_step = np.zeros(ts.n)  # per thruster, averaged over the last plant step

    def command(self, t0: float, wrench: np.ndarray) -> bool:
        """Allocate and modulate ``wrench`` for the tick starting at t0; True when it was out of reach."""
        self.t0 = float(t0)
        self.commanded = np.asarray(wrench, float).copy()
        a = self.allocator.solve(self.commanded)
        self.thrust_cmd = a.thrust
        ts = self.ts
        self.on = on_times(a.thrust, ts.max_force, ts.firing_cycle, ts.mib, ts.quantization)
        return a.saturated

    @property
    def pattern_thrust(self) -> np.ndarray:
        """(n,) N: each thruster's thrust in the current firing pattern, averaged over its firing cycle."""
        return self.ts.max_force * self.on / self.ts.firing_cycle

    @property
    def pattern_wrench(self) -> np.ndarray:
        """[f; n] (N, N m, base joint frame) of the current firing pattern averaged over its firing cycle:
        what the modulation delivers of ``commanded`` (the two differ by the quantisation and the MIB)."""
        return self.B @ self.pattern_thrust

    def _breaks(self, t: float, t1: float) -> list[float]:
        T = self.ts.firing_cycle
        j0 = int(np.floor((t - self.t0) / T + 1e-12))
        pts = {t, t1}
        for j in range(j0, j0 + int(np.ceil((t1 - t) / T)) + 2):
            c = self.t0 + j * T
            for x in (c, *(c + self.on[self.on > 0])):
                if t < x < t1:
                    pts.add(float(x))
        return sorted(pts)

    def _on_at(self, tm: float) -> np.ndarray:
        T = self.ts.firing_cycle
        phase = (tm - self.t0) % T
        return phase < self.on

    def step(self, s, t: float, dt: float, tau: np.ndarray, advance):
        """The state after the plant step [t, t + dt] under the generalized forces ``tau`` (nv, without
        the thrusters) plus the firings; ``advance(s, tau, h, t)`` is one plant step of length h."""
        def advance_one(s, wrenches, h, a):
            tau_p = np.array(tau, float)
            tau_p[:6] += wrenches[0]
            return advance(s, tau_p, h, a)

        return step_drives([self], s, t, dt, advance_one)

    def _burning(self, tm: float) -> tuple[np.ndarray, float]:
        """(on mask, total mass flow kg/s) at time tm (nothing once the tank is empty)."""
        on = self._on_at(tm) if self.used < self.ts.propellant else np.zeros(self.ts.n, bool)
        return on, float(self.mdot[on].sum())


def step_drives(drives: list[ThrusterDrive], s, t: float, dt: float, advance):
    """The state after the plant step [t, t + dt] with the firings of every drive (one per spacecraft):
    ``advance(s, wrenches, h, a)`` is one plant step of length h from a with ``wrenches[k]`` the base
    wrench [f; n] of drive k's thrusters on over that piece. The step is cut at every switching of any
    drive and where a tank empties; each piece sees each body's mass at the piece's midpoint."""
    impulses = [np.zeros(d.ts.n) for d in drives]
    pts = sorted(set().union(*(d._breaks(t, t + dt) for d in drives)))
    for a, b in zip(pts[:-1], pts[1:]):
        while b - a > 0:
            burning = [d._burning(0.5 * (a + b)) for d in drives]
            h = b - a
            for d, (_, mdot) in zip(drives, burning):  # a tank that empties inside cuts the piece there
                if mdot > 0 and d.used + mdot * h > d.ts.propellant:
                    h = min(h, (d.ts.propellant - d.used) / mdot)
            for d, (_, mdot) in zip(drives, burning):
                if d.tank.set_removed(d.used + 0.5 * mdot * h) and d.on_change is not None:
                    d.on_change()
            forces = [np.where(on, d.ts.max_force, 0.0) for d, (on, _) in zip(drives, burning)]
            if h > 0:
                s = advance(s, [d.B @ f for d, f in zip(drives, forces)], h, a)
            for d, (_, mdot), f, imp in zip(drives, burning, forces, impulses):
                empties = mdot > 0 and d.used + mdot * h >= d.ts.propellant - 1e-15 * d.ts.propellant
                d.used = d.ts.propellant if empties and h < b - a else d.used + mdot * h
                imp += f * h
            a = a + h if h < b - a else b
    for d, imp in zip(drives, impulses):
        if d.tank.set_removed(d.used) and d.on_change is not None:
            d.on_change()
        d.thrust_step = imp / dt
        d.delivered = d.B @ d.thrust_step
    return s
