"""Quick start of the sms Python API: load, compile, budget, simulate, without writing a file.

    .venv/bin/python examples/api_quickstart.py

Run by the tests (tests/test_api.py), from an empty folder that must stay empty.
"""

from pathlib import Path

import sms_cli as sms

MISSIONS = Path(__file__).resolve().parents[1] / "missions"

# A shipped mission from its file: Caldera 2019's scenario S1 (a 60° slew of a small satellite
# with a 3-joint arm held straight up). Its robot.urdf and extends: resolve against its folder.
mission = sms.load_mission(MISSIONS / "caldera_s1_slew.yaml")
model = sms.compile(mission)
print(f"{mission.mission.name}: mass {model.total_mass:.2f} kg, {model.nx} DoF "
      f"(base 6, wheels {len(model.wheels)}, arm {len(model.arm)}, flexible modes {model.n_modes})")

# The same mission from a string, its slew shortened to 30 s; paths inside resolve against base_dir.
text = (MISSIONS / "caldera_s1_slew.yaml").read_text().replace("duration: 240 s", "duration: 30 s")
short = sms.load_mission_text(text, base_dir=MISSIONS)
assert sms.compile(short).total_mass == model.total_mass

# The ΔV budget of a Hipparcos-class transfer from low Earth orbit (nothing written: no out=).
budget = sms.budget(MISSIONS / "hipparcos_leo.yaml")
print(f"budget: ΔV {budget.dv_m_s:.1f} m/s, propellant {budget.propellant_kg:.1f} kg, "
      f"{'closes' if budget.closes else 'does not close'}")

# A 30 s simulation: not recorded (no MCAP), nothing written; metrics and trace arrays in memory.
run = sms.simulate(short)
trace = run.trace
print(f"simulate: {run.status}, {run.t_end_s:.1f} s simulated in {run.steps} steps, attitude error "
      f"{run.attitude_error_max_deg:.2f}° max, {run.attitude_error_final_deg:.2f}° at the end, "
      f"wheel speed peak {run.wheel_speed_peak_rad_s:.1f} rad/s")
print(f"trace: {trace['t'].size} samples of {', '.join(sorted(trace))}")

# Errors are exceptions with the file, line and field of each problem.
try:
    sms.load_mission_text(text.replace("dt: 0.05 s", "dt: 0.05 furlong"), base_dir=MISSIONS)
except sms.InputError as exc:
    p = exc.problems[0]
    print(f"InputError at line {p.location.line}, {p.field}: {p.message}")
