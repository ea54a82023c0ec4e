"""The NDI + observer loop as it flies, linearised at rest and sampled, along every move of an NDI mission.

Not a speed bench: the analysis behind the README's account of why the chapter 4 LMI gains, flown on
pulsar_full, diverge in the 4-tile carry while the mission's designed gains do not.

At each configuration the script builds the linear sampled-data loop that the law closes every control period T
(``simulation.control_rate``), with the plant and the law's model differing by the mission's model errors
(``simulation.ndi.model_errors``):

* the plant, continuous, at rest (no velocity terms), its torque held over T: X = [q_a; q̇_a; x_e],
  M◇ q̈_a + D◇_x x_e = τ, ẋ_e = A_e x_e + B_τ τ (``SystemModel.reduced.at_rest``: the plant's model);
* the law, at each tick: τ = M◇ˡ (−K_p q_a − K_v q̇_a) + D◇_xˡ x̂_e, and the observer discretised as
  ``ndi_law.ndi_observe`` does (its ``observer_discretisation``), x̂⁺ = Φ x̂ + Γ (B_τˡ τ + L y), Φ = e^{(A_eˡ − L C_e) T},
  Γ = ∫₀ᵀ e^{(A_eˡ − L C_e)s} ds,
  y = C_e x_e (the gyro sampled at the tick); ˡ: the law's model (with errors);
* left out: the attitude hold (k_att), the wheel-rate reference (4.51) and the disturbance observer.

It prints, per move and per gain set, the largest |z| − 1 of the loop's eigenvalues over configurations along the
move (joint-space straight line from the move's start to its end, the payloads it carries attached): > 0 is a
growing mode, e^{ln|z|/T} per second. The eigenvalues at exactly 1 are the loop's integrators (wheel angles
without position feedback, the base attitude without k_att).

    .venv/bin/python benches/sampled_loop.py                          # pulsar_full; synthesises its LMI gains (~30 s)
    .venv/bin/python benches/sampled_loop.py --gains results/gains.yaml
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import scipy.linalg

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sms_cli.mission.load import load_mission  # noqa: E402
from sms_cli.model import compile_system  # noqa: E402
from sms_cli.model.model_errors import law_model  # noqa: E402
from sms_cli.sim.compiled.ndi_law import observer_discretisation  # noqa: E402
from sms_cli.sim.laws.ndi import build_ndi  # noqa: E402
from sms_cli.sim.stage import prepared_simulation  # noqa: E402
from sms_cli.synthesis.reduced import configuration  # noqa: E402


def _zoh(A: np.ndarray, B: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{AT}, ∫₀ᵀ e^{As} ds B)."""
    n, m = B.shape
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * T)
    return E[:n, :n], E[:n, n:]


def sampled_loop(plant, law, kp, kv, L, T: float) -> np.ndarray:
    """The one-period transition matrix of [X; x̂] (module docstring); plant, law: ``RestMatrices``."""
    n_q, n_e = plant.M_dia.shape[0], plant.A_e.shape[0]
    Z, I = np.zeros((n_q, n_q)), np.eye(n_q)
    M_inv = np.linalg.inv(plant.M_dia)
    Ap = np.block([[Z, I, np.zeros((n_q, n_e))], [Z, Z, -M_inv @ plant.D_x], [np.zeros((n_e, 2 * n_q)), plant.A_e]])
    Bp = np.vstack([Z, M_inv, plant.B_tau])
    Ad, Bd = _zoh(Ap, Bp, T)
    Phi, Gamma = np.empty((n_e, n_e)), np.empty((n_e, n_e))  # the law's own discretisation of its observer
    observer_discretisation(np.ascontiguousarray(law.A_e - L @ law.C_e), T, Phi, Gamma)
    K = np.hstack([-law.M_dia @ np.diag(kp), -law.M_dia @ np.diag(kv), np.zeros((n_q, n_e)), law.D_x])  # τ = K [X; x̂]
    nX = 2 * n_q + n_e
    Cy = np.hstack([np.zeros((3, 2 * n_q)), plant.C_e, np.zeros((3, n_e))])
    F = np.zeros((nX + n_e, nX + n_e))
    F[:nX, :nX] = Ad
    F[:nX] += Bd @ K
    F[nX:, nX:] = Phi
    F[nX:] += Gamma @ (law.B_tau @ K + L @ Cy)
    return F


def growth(F: np.ndarray) -> float:
    """The largest |z| − 1 of F's eigenvalues."""
    return float(np.abs(np.linalg.eigvals(F)).max() - 1.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mission", nargs="?", default=str(ROOT / "missions" / "pulsar_full.yaml"))
    ap.add_argument("--gains", help="the LMI gains.yaml (default: sms synthesize the mission into a temporary folder)")
    ap.add_argument("--points", type=int, default=11, help="configurations per move (default 11)")
    args = ap.parse_args()

    loaded = load_mission(args.mission)
    spec = loaded.mission.simulation.ndi
    T = 1.0 / loaded.mission.simulation.control_rate
    gains = Path(args.gains) if args.gains else None
    tmp = None
    if gains is None:
        tmp = tempfile.TemporaryDirectory()
        print(f"sms synthesize {args.mission} ...", flush=True)
        subprocess.run([str(Path(sys.executable).with_name("sms")), "synthesize", args.mission, "-o", tmp.name],
                       check=True, capture_output=True)
        gains = Path(tmp.name) / "gains.yaml"

    plant = compile_system(loaded)
    designed = build_ndi(spec, plant, T)
    lmi = build_ndi(spec.model_copy(update={"kp": None, "kv": None, "L": None, "ndo_bandwidth": None, "Q_d": None}),
                    plant, T, results_dir=gains.parent)
    e = spec.model_errors
    law = law_model(plant, e.inertia, e.com, e.modal_frequency, e.seed) if e is not None else plant
    sets = {"designed": (designed.kp, designed.kv, designed.L), "LMI": (lmi.kp, lmi.kv, lmi.L),
            "LMI K, designed L": (lmi.kp, lmi.kv, designed.L)}
    print(f"{loaded.mission.name}: T = {T} s, model errors {e.model_dump() if e is not None else None}; "
          f"max |L| designed {np.abs(designed.L).max():.3g}, LMI {np.abs(lmi.L).max():.3g}")
    print(f"{'move':24s}" + "".join(f"{k:>20s}" for k in sets) + "   largest |z| − 1 along the move")

    _, sim, _ = prepared_simulation(loaded)
    joints = {a.name: float(plant.q0[a.q_index]) for a in plant.arm}
    for phase in sim.phases:
        for model in (plant, law):
            for name in phase.attach or []:
                model.attach_payload(name)
            for name in phase.detach or []:
                model.detach_payload(name)
        end = dict(joints)
        for w in phase.waypoints or []:
            end.update({j: float(v) for j, v in (getattr(w, "joints", None) or {}).items()})
        if end == joints:
            continue
        worst = {k: -np.inf for k in sets}
        for s in np.linspace(0.0, 1.0, args.points):
            q = configuration(plant, plant.q0, {j: (1 - s) * joints[j] + s * end[j] for j in joints})
            rp, rl = plant.reduced.at_rest(plant.mass_matrix(q)), law.reduced.at_rest(law.mass_matrix(q))
            for k, (kp, kv, L) in sets.items():
                worst[k] = max(worst[k], growth(sampled_loop(rp, rl, kp, kv, L, T)))
        print(f"{phase.name:24s}" + "".join(f"{worst[k]:>+20.2e}" for k in sets), flush=True)
        joints = end
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
