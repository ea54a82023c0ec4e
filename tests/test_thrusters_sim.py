"""Real thrusters inside the simulation loop (tests/data/thrusters_cube.yaml, one firing cycle per
control tick): over every tick the delivered wrench, averaged over the cycle, is the commanded one
within the modulation bound of sms_cli.thrusters.modulation; the base mass falls by the propellant used."""

from __future__ import annotations

import numpy as np

from conftest import ROOT

from sms_cli.mission.load import load_mission
from sms_cli.model import compile_system
from sms_cli.sim.engine import Simulation
from sms_cli.thrusters.modulation import impulse_error_bound


def test_delivered_over_each_cycle_is_the_command_within_the_bound():
    loaded = load_mission(ROOT / "tests" / "data" / "thrusters_cube.yaml")
    sm = compile_system(loaded)
    m0 = sm.total_mass
    # the Python loop's drive is spied on here (the compiled loop's equals it: tests/test_compiled_momentum.py)
    sim = Simulation(sm, loaded.mission.simulation.model_copy(update={"engine": "python"}), progress=False)
    d = sim.thr
    assert d is not None and not sim.compiled_loop
    ticks, acc = [], {"impulse": np.zeros(d.ts.n), "T": 0.0}
    command, step = d.command, d.step

    def close_tick():
        if acc["T"] > 0:
            e = impulse_error_bound(d.thrust_cmd, d.ts.max_force, d.ts.firing_cycle, d.ts.mib, d.ts.quantization)
            ticks.append((d.commanded.copy(), d.B @ acc["impulse"] / acc["T"], np.abs(d.B) @ (d.ts.max_force * e) / acc["T"],
                          d.on.copy()))
        acc["impulse"][:] = 0.0
        acc["T"] = 0.0

    def spy_command(t0, w):
        close_tick()
        return command(t0, w)

    def spy_step(s, t, dt, tau, advance):
        s = step(s, t, dt, tau, advance)
        acc["impulse"] += d.thrust_step * dt
        acc["T"] += dt
        return s

    d.command, d.step = spy_command, spy_step
    result = sim.run()
    close_tick()
    assert result.status == "completed" and len(ticks) == 300
    assert abs(acc["T"]) == 0.0
    fired = 0
    for cmd, delivered, bound, on in ticks:
        assert np.all(np.abs(delivered - cmd) <= bound + 1e-9)
        assert np.all((on == 0) | (on >= d.ts.mib))
        fired += int(np.any(on > 0))
    assert fired > 10  # the law's torques are above the MIB's in some ticks
    used = result.overall["propellant_used_kg"]
    assert used == d.used and 0 < used < d.ts.propellant
    assert abs(sm.total_mass - (m0 - used)) < 1e-12 * m0
