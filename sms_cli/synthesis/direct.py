"""The structured chapter 3 LMI problem of ``lmi._build_structured`` built directly as numpy
blocks for ``sdp.solve_lmi`` (no cvxpy canonicalisation).

Same variables, same constraints, same objective as ``_build_structured`` (the test suite checks
that every block equals the corresponding cvxpy expression at random values of the variables).
Each block is written once as a numpy function of the variables, evaluated on stacks: its
affine coefficients are read off by evaluating it at 0 and at every unit vector of the variables
it involves (exact, since the block is affine).

Variables (scaled units of ``lmi._scale``): q11, q12, q22, wp, wv (per actuator), P (n_e×n_e
symmetric, parameterised by its upper triangle), We (n_e×n_y), g = γ̃², s (per actuator),
c_e, c_z (per actuator, only with a tracking box).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sms_cli.synthesis.regions import region_blocks
from sms_cli.synthesis.sdp import LmiBlock, single_thread_blas, solve_lmi


@dataclass
class Layout:
    """Positions of named variables in x. kind: 'vec' (n,), 'sym' (n, n), 'mat' (r, c)."""

    slots: dict = field(default_factory=dict)
    m: int = 0

    def add(self, name: str, kind: str, shape: tuple[int, ...]) -> None:
        if kind == "sym":
            size = shape[0] * (shape[0] + 1) // 2
        else:
            size = int(np.prod(shape))
        self.slots[name] = (kind, shape, slice(self.m, self.m + size))
        self.m += size

    def indices(self, names) -> np.ndarray:
        return np.concatenate([np.arange(self.slots[n][2].start, self.slots[n][2].stop) for n in names])

    def unpack(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """x (B, m) → {name: (B, *shape)}."""
        out = {}
        for name, (kind, shape, sl) in self.slots.items():
            v = x[:, sl]
            if kind == "sym":
                n = shape[0]
                iu, ju = np.triu_indices(n)
                S = np.zeros((x.shape[0], n, n))
                S[:, iu, ju] = v
                S[:, ju, iu] = v
                out[name] = S
            else:
                out[name] = v.reshape((x.shape[0],) + tuple(shape))
        return out


def _blocks_of(layout: Layout, names: list[str], fn, group: str) -> list[LmiBlock]:
    """LmiBlocks (one per matrix fn returns) of the affine fn(vars) over the named variables."""
    idx = layout.indices(names)
    B = 1 + len(idx)
    x = np.zeros((B, layout.m))
    x[np.arange(1, B), idx] = 1.0
    mats = fn(layout.unpack(x))
    out = []
    for F in mats:
        F = (F + np.swapaxes(F, -1, -2)) / 2
        F0, Fi = F[0], F[1:] - F[0]
        used = np.any(Fi != 0, axis=(1, 2))
        out.append(LmiBlock(idx[used], F0, Fi[used], group))
    return out


def _mat(entries, B: int) -> np.ndarray:
    """A (B, r, c) stack from a nested list of scalars or (B,) arrays."""
    r, c = len(entries), len(entries[0])
    out = np.zeros((B, r, c))
    for a in range(r):
        for b in range(c):
            out[:, a, b] = entries[a][b]
    return out


def structured_problem(req, sc, eps: float, q_max: float):
    """(layout, c, blocks) of ``_build_structured(req, sc)`` without dropped groups."""
    m0 = sc.models[0]
    n_q, n_e, n_y = m0.n_q, m0.n_e, m0.n_y
    lay = Layout()
    for nm in ("q11", "q12", "q22", "wp", "wv"):
        lay.add(nm, "vec", (n_q,))
    lay.add("P", "sym", (n_e,))
    lay.add("We", "mat", (n_e, n_y))
    lay.add("g", "vec", (1,))
    lay.add("s", "vec", (n_q,))
    lay.add("c_e", "vec", (1,))
    track = req.tracking is not None
    if track:
        lay.add("c_z", "vec", (n_q,))
    creg = req.controller_region.scaled(sc.omega_c)
    oreg = req.observer_region.scaled(sc.omega_c)
    blocks: list[LmiBlock] = []
    ctrl = ["q11", "q12", "q22", "wp", "wv"]
    for i in range(n_q):
        ci = float(sc.d[i] / sc.c_s)

        def qn(V, i=i):
            B = V["q11"].shape[0]
            q11, q12, q22 = V["q11"][:, i], V["q12"][:, i], V["q22"][:, i]
            wp, wv = V["wp"][:, i], V["wv"][:, i]
            Q = _mat([[q11, q12], [q12, q22]], B)
            N = _mat([[q12, q22], [-wp, -wv]], B)  # A_z,i Q_i + B_z,i W_i
            return B, Q, N, wp, wv

        def perf(V, i=i, ci=ci):
            B, Q, N, _, _ = qn(V)
            q11, q12, g, s = V["q11"][:, i], V["q12"][:, i], V["g"][:, 0], V["s"][:, i]
            Gi = np.zeros((B, 3, 3))
            Gi[:, :2, :2] = N + np.swapaxes(N, 1, 2)
            Gi[:, 2, :2] = Gi[:, :2, 2] = ci * np.stack([q11, q12], axis=1)
            Gi[:, 2, 2] = -g
            Mi = np.zeros((B, 4, 4))
            Mi[:, :3, :3] = -Gi - eps * np.eye(3)
            Mi[:, 1, 3] = Mi[:, 3, 1] = 1.0
            Mi[:, 3, 3] = s
            return [Mi]

        blocks += _blocks_of(lay, ctrl + ["g", "s"], perf, "performance")

        def ctrl_blocks(V):
            B, Q, N, _, _ = qn(V)
            return [q_max * np.eye(2) - Q] + region_blocks(N, Q, creg, eps)

        blocks += _blocks_of(lay, ctrl, ctrl_blocks, "controller_region")
        if req.accel_limit is not None and np.isfinite(req.accel_limit[i]):
            a = float(req.accel_limit[i]) / sc.omega_c**2 / sc.d[i]

            def auth(V, a=a):
                B, Q, N, wp, wv = qn(V)
                Mi = np.zeros((B, 3, 3))
                Mi[:, 0, 0] = a * a
                Mi[:, 0, 1:] = Mi[:, 1:, 0] = np.stack([wp, wv], axis=1)
                Mi[:, 1:, 1:] = Q
                return [Mi]

            blocks += _blocks_of(lay, ctrl, auth, "actuator_authority")
        if track:
            e, ed = float(req.tracking[i, 0]) / sc.d[i], float(req.tracking[i, 1]) / sc.omega_c / sc.d[i]
            corners = ([e, ed], [e, -ed]) if ed > 0 else ([e, 0.0],)

            def box(V, i=i, corners=corners):
                B, Q, N, _, _ = qn(V)
                out = []
                for v in corners:
                    Mc = np.zeros((B, 3, 3))
                    Mc[:, 0, 0] = V["c_z"][:, i]
                    Mc[:, 0, 1:] = Mc[:, 1:, 0] = v
                    Mc[:, 1:, 1:] = Q
                    out.append(Mc)
                return out

            blocks += _blocks_of(lay, ctrl + ["c_z"], box, "initial_conditions")
    Ee = np.diag(sc.T) @ req.E_e @ np.diag(sc.T)
    blocks += _blocks_of(lay, ["P", "c_e"], lambda V: [V["c_e"][:, :, None] * Ee - V["P"]], "initial_conditions")
    budget = ["c_e"] + (["c_z"] if track else [])
    blocks += _blocks_of(lay, budget, lambda V: [(1.0 - V["c_e"][:, 0] - (np.sum(V["c_z"], axis=1) if track else 0))
                                                 [:, None, None]], "initial_conditions")
    # nonnegative variables (cvxpy's nonneg=True): g, s, c_e, c_z
    for nm in ("g", "s", "c_e") + (("c_z",) if track else ()):
        blocks += _blocks_of(lay, [nm], lambda V, nm=nm: [V[nm][:, k, None, None] for k in range(V[nm].shape[1])],
                             "positivity")
    for mdl in sc.models:
        def obs(V, mdl=mdl):
            P, We, s = V["P"], V["We"], V["s"]
            PA = P @ mdl.A_e - We @ mdl.C_e
            PAt = np.swapaxes(PA, 1, 2)
            Phi = PA + PAt + np.einsum("ka,bk,kc->bac", mdl.B_eps, s, mdl.B_eps)
            return [-Phi - eps * np.eye(n_e)] + region_blocks(PAt, P, oreg, eps)

        blk = _blocks_of(lay, ["P", "We", "s"], obs, "observer_region")
        blk[0].group = "performance"
        blocks += blk
    c = np.zeros(lay.m)
    c[lay.slots["g"][2]] = 1.0
    return lay, c, blocks


def solve_structured(req, sc, eps: float, q_max: float, tol: float = 1e-8):
    """Solve the structured problem with ``sdp.solve_lmi``: ({name: value}, SdpResult, n_vars)."""
    with single_thread_blas():
        lay, c, blocks = structured_problem(req, sc, eps, q_max)
        res = solve_lmi(c, blocks, tol=tol)
    vals = {k: v[0] for k, v in lay.unpack(res.x[None, :]).items()}
    vals["g"] = float(vals["g"][0])
    return vals, res, lay.m
