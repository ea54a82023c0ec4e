"""Linearised model of the flexible system at a configuration, its coupled modes, and export.

State x = [δq (tangent of q: base position and attitude in the base frame, joints); η;
           v (Pinocchio velocity); η̇], restricted to the free coordinates: with ``joints="locked"``
the arm joints and wheels are clamped by their servos and drop out. Inputs: arm joint and wheel
torques (free joints only) and the external base wrench [f; n] in the base frame. Outputs: the
whole state (C = I, D = 0), every row named. Units SI.

Linearisation: M(q0) ẍ = f(q, v, η, η̇) + S u with f = internal (springs, modal stiffness and
damping) − bias forces; ∂f is taken by central differences (exact for the affine internal
forces and the quadratic bias forces in the velocities). The operating point must be an
equilibrium (arm at rest, base not rotating; wheels may spin): the M(q) variation term is
then zero. The residual acceleration at the point is reported.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sms_cli.results import atomic_path


@dataclass
class LinearModel:
    """ẋ = A x + B u, y = C x + D u, with named states, inputs and outputs."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: list[str]
    inputs: list[str]
    outputs: list[str]
    q: np.ndarray
    residual: float  # norm of the acceleration at the operating point (rad/s², m/s²)
    n_pos: int  # number of position-like states (δq and η)


def _coordinate_names(sm) -> list[str]:
    """One name per velocity coordinate (nv): base, then every joint's DoFs."""
    names = ["base_x", "base_y", "base_z", "base_rx", "base_ry", "base_rz"]
    model = sm.model
    for j in range(2, model.njoints):
        nvj = model.joints[j].nv
        names += [model.names[j]] if nvj == 1 else [f"{model.names[j]}_{k}" for k in range(nvj)]
    return names


def linearize(sm, q: np.ndarray | None = None, joints: str = "free", v: np.ndarray | None = None) -> LinearModel:
    """The linear model at configuration q (default sm.q0) and velocity v (default sm.v0 with the
    arm and base at rest, i.e. only the initial wheel speeds)."""
    import pinocchio as pin

    model = sm.model
    nv, nm = sm.nv, sm.n_modes
    q0 = np.array(sm.q0 if q is None else q, dtype=float)
    if v is None:
        v0 = np.zeros(nv)
        v0[sm.idx.wheels] = sm.v0[sm.idx.wheels]
    else:
        v0 = np.asarray(v, float)
    eta0 = np.zeros(nm)
    etadot0 = np.zeros(nm)
    locked = set(np.concatenate([sm.idx.arm, sm.idx.wheels]).tolist()) if joints == "locked" else set()
    keep = np.array([i for i in range(nv) if i not in locked], dtype=int)
    kx = np.concatenate([keep, nv + np.arange(nm)]).astype(int)  # kept rows of the augmented vector

    def f(qq, vv, ee, ed):
        return sm.internal_forces(qq, vv, ee, ed) - sm.bias_forces(qq, vv, ed)

    n_p = len(kx)
    Fp = np.zeros((sm.nx, n_p))
    Fv = np.zeros((sm.nx, n_p))
    hq, hv = 1e-6, 1e-4
    for col, i in enumerate(keep):
        dq = np.zeros(nv)
        dq[i] = hq
        Fp[:, col] = (f(pin.integrate(model, q0, dq), v0, eta0, etadot0)
                      - f(pin.integrate(model, q0, -dq), v0, eta0, etadot0)) / (2 * hq)
        dv = np.zeros(nv)
        dv[i] = hv
        Fv[:, col] = (f(q0, v0 + dv, eta0, etadot0) - f(q0, v0 - dv, eta0, etadot0)) / (2 * hv)
    for k in range(nm):
        e = np.zeros(nm)
        e[k] = hq
        Fp[:, len(keep) + k] = (f(q0, v0, eta0 + e, etadot0) - f(q0, v0, eta0 - e, etadot0)) / (2 * hq)
        e[k] = hv
        Fv[:, len(keep) + k] = (f(q0, v0, eta0, etadot0 + e) - f(q0, v0, eta0, etadot0 - e)) / (2 * hv)
    M = sm.mass_matrix(q0)[np.ix_(kx, kx)]
    coord = _coordinate_names(sm)
    inputs, S_cols = [], []
    if joints == "free":
        for a in sm.arm:
            inputs.append(f"tau_{a.name}")
            S_cols.append(a.v_index)
        for w in sm.wheels:
            inputs.append(f"tau_{w.name}")
            S_cols.append(w.v_index)
    for k, n in enumerate(("f_x", "f_y", "f_z", "n_x", "n_y", "n_z")):
        inputs.append(f"base_{n}")
        S_cols.append(k)
    S = np.zeros((sm.nx, len(S_cols)))
    for c, i in enumerate(S_cols):
        S[i, c] = 1.0
    Minv = np.linalg.inv(M)
    A = np.zeros((2 * n_p, 2 * n_p))
    A[:n_p, n_p:] = np.eye(n_p)
    A[n_p:, :n_p] = Minv @ Fp[kx]
    A[n_p:, n_p:] = Minv @ Fv[kx]
    B = np.zeros((2 * n_p, len(inputs)))
    B[n_p:] = Minv @ S[kx]
    residual = float(np.linalg.norm(Minv @ f(q0, v0, eta0, etadot0)[kx]))
    mode_names = []
    for a in sm.appendages:
        mode_names += [f"{a.name}_eta{k + 1}" for k in range(a.omega.size)]
    pos = [coord[i] for i in keep] + mode_names
    vel = [f"{coord[i]}_rate" for i in keep] + [f"{n}_rate" for n in mode_names]
    states = pos + vel
    return LinearModel(A, B, np.eye(len(states)), np.zeros((len(states), len(inputs))), states, inputs, list(states),
                       q0, residual, n_p)


def coupled_modes(lin: LinearModel, min_frequency: float = 1e-5) -> list[dict]:
    """Oscillatory modes of A: natural frequency (rad/s, Hz), damping ratio and dominant coordinate."""
    lam, vec = np.linalg.eig(lin.A)
    modes = []
    for k in np.argsort(np.abs(lam)):
        z = lam[k]
        if z.imag <= 1e-9 or abs(z) < min_frequency:
            continue
        wn = abs(z)
        phi = np.abs(vec[: lin.n_pos, k])
        modes.append({"frequency_rad_s": wn, "frequency_hz": wn / (2 * np.pi), "damping": -z.real / wn,
                      "dominant": lin.states[int(np.argmax(phi))]})
    return modes


def export(lin: LinearModel, stem: Path, formats: list[str]) -> list[Path]:
    """Write the model as ``stem.npz`` and/or ``stem.mat`` (atomic)."""
    data = {"A": lin.A, "B": lin.B, "C": lin.C, "D": lin.D, "q": lin.q}
    names = {"states": lin.states, "inputs": lin.inputs, "outputs": lin.outputs}
    out = []
    if "npz" in formats:
        path = Path(f"{stem}.npz")
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **data, **{k: np.array(v) for k, v in names.items()})
        out.append(path)
    if "mat" in formats:
        import scipy.io

        path = Path(f"{stem}.mat")
        with atomic_path(path) as tmp:
            scipy.io.savemat(tmp, {**data, **{k: np.array(v, dtype=object) for k, v in names.items()}},
                             appendmat=False, do_compression=True)
        out.append(path)
    return out
