"""Kinematic indices of a free-floating space manipulator at many joint configurations.

Per sample: one CRBA (mass matrix M, Pinocchio free-flyer coordinates) and one end-effector
frame Jacobian (LOCAL); everything else is batched numpy linear algebra over the samples.

Frames and conventions
- Satellite frame R_sat = the base-link frame. The base attitude and position are the ones of
  the template configuration; every index is invariant to them (tested).
- Pinocchio base velocity v_b = [v (base frame, base-link origin); ω (base frame)].
- Zero total momentum (Kraiem 2022 (3.5)): the base rows of M give the total spatial momentum, so
  M_bb v_b + M_bm q̇_m + M_br q̇_r = 0 and v_b = -M_bb⁻¹ [M_bm M_br] [q̇_m; q̇_r].
- End-effector twist in R_sat, [v; ω] (linear first, velocity of the EE frame origin relative to
  the inertial frame, expressed in R_sat). J*_mEE (3.8) and J*_rEE map q̇_m, q̇_r to it.
- μ(J) = product of the min(rows, cols) singular values = sqrt(det) of the smaller Gram
  matrix: seed (3.11) when rows ≤ cols, (3.14)'s JᵀJ form otherwise (a 3-DoF arm has
  μ(J*_mEE 6×3) > 0 away from singularities). μ² is the determinant of the test (3.10).

Index columns (SI units)
- ee_x, ee_y, ee_z (m): EE origin in R_sat, from the base-link origin; ee_roll/pitch/yaw (rad): Z-Y-X
Task rows: the EE linear velocity for arms with fewer than 6 joints (position task, the
  ṙ_EE of Kraiem 2022 Fig. 3.7), the full twist otherwise; ``task`` overrides.
- mu_fixed: μ of the arm Jacobian on a fixed base (task rows)
- mu_gjm: μ of the free-floating generalized Jacobian J*_mEE (task rows), wheels locked (q̇_r = 0)
- gjm_cond: σ_min/σ_max of J*_mEE (task rows); singular: 1 when gjm_cond < tolerance (test (3.10))
- mu_ratio: mu_gjm / mu_fixed (NaN where the fixed-base arm is singular)
- mu_dyn: dynamic manipulability (3.14) (task rows), J◇ = J*_mEE H*_m⁻¹ diag(τ_max)
  [erratum: the thesis writes W_τ with τ̂ = W_τ τ; the torque box maps through W_τ⁻¹ = diag(τ_max)]
  with H*_m = M_mm - M_mb M_bb⁻¹ M_bm (base free, wheels locked)
- K_m, K_r: base indices (3.18) with Q_max, Ω_max; (K_m)² + (K_r)² = 1
- mu_scal_lin: μ of the scaled EE linear Jacobian J^scal_rEE (3.23) [J*_mEE Q_max, J*_rEE Ω_max] (base free)
- mu_null_lin, mu_null_ang: null-motion manipulabilities μ^N_rEE, μ^N_ωEE (3.25), fixed base attitude
  (values below the round-off floor 1e-7·‖X‖_F³ of the formula used are reported as 0)
- mu_scal_lin_norm, mu_null_lin_norm: mu_scal_lin and mu_null_lin over the fixed-base
  μ(J_m,lin Q_max) (the normalisation of Fig. 3.7-3.8; NaN where the fixed-base arm is singular)
- joint_limit_margin: min over limited arm joints of 2·min(q-lo, hi-q)/(hi-lo) ∈ [0, 1]
- h_arm_max (N m s): largest arm angular momentum about the system CoM over |q̇_i| ≤ q̇max_i
- h_ratio: gauge of that momentum in the wheels' momentum zonotope {Σ h_i Ω_i, |Ω_i| ≤ Ω_max,i}
  (≤ 1: the wheels can absorb the arm's worst-case momentum; zonotope about zero wheel speed)
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from sms_cli.analysis import kernels as K

#: Columns produced by each index group.
GROUP_COLUMNS: dict[str, tuple[str, ...]] = {
    "pose": ("ee_x", "ee_y", "ee_z", "ee_roll", "ee_pitch", "ee_yaw"),
    "manipulability": ("mu_fixed", "mu_gjm", "gjm_cond", "singular", "mu_ratio"),
    # manipulability of a kinematics-only robot (robot.kinematics_only): the fixed-base part alone
    "fixed_manipulability": ("mu_fixed", "fixed_cond", "singular"),
    "dynamic_manipulability": ("mu_dyn",),
    "base_indices": ("K_m", "K_r"),
    "null_motion": ("mu_scal_lin", "mu_null_lin", "mu_null_ang", "mu_scal_lin_norm", "mu_null_lin_norm"),
    "joint_limits": ("joint_limit_margin",),
    "momentum": ("h_arm_max", "h_ratio"),
}

#: Whether a larger value of a column is better (for "best configurations").
HIGHER_IS_BETTER: dict[str, bool] = {
    **{c: True for cols in GROUP_COLUMNS.values() for c in cols},
    "K_m": False, "singular": False, "h_arm_max": False, "h_ratio": False,
}

UNITS: dict[str, str] = {
    "ee_x": "m", "ee_y": "m", "ee_z": "m", "ee_roll": "rad", "ee_pitch": "rad", "ee_yaw": "rad",
    "h_arm_max": "N m s",
}


@dataclass
class ArmLayout:
    """Where the arm and the wheels sit in the model, and their limits (SI, NaN/inf = none).

    ``q_index``/``kinds`` locate each arm joint in q (continuous joints use cos/sin, 2 entries);
    ``v_arm``/``v_wheels`` are v indices; ``sampled`` lists the arm joints (positions in the arm
    list) whose values a sample row gives, in order.
    """

    names: list[str]
    q_index: np.ndarray
    kinds: list[str]
    v_arm: np.ndarray
    v_wheels: np.ndarray
    wheel_names: list[str]
    sampled: list[int]
    lower: np.ndarray
    upper: np.ndarray
    q_max: np.ndarray  # joint speed limits (rad/s or m/s)
    tau_max: np.ndarray  # joint effort limits (N m or N)
    omega_max: np.ndarray  # wheel speed limits (rad/s)
    skipped: dict[str, str] = field(default_factory=dict)


#: Groups that need no mass matrix, and why the others are skipped on a kinematics-only robot.
KINEMATIC_GROUPS = ("fixed_manipulability", "joint_limits")
KINEMATICS_ONLY = "needs the mass matrix; the robot is kinematics-only (robot.kinematics_only: placeholder inertias)"


#: Samples per thread below which a block is evaluated on the calling thread alone.
MIN_PART = 256
_EXECUTOR: list = []


def analysis_threads() -> int:
    """Threads that evaluate a block's indices: ``SMS_ANALYSIS_THREADS``, else the cores this process
    may use (the values do not depend on it)."""
    from sms_cli.workers import usable_cores

    return usable_cores("SMS_ANALYSIS_THREADS")


def _executor():
    """The process's pool of index threads (started on first use)."""
    if not _EXECUTOR:
        from concurrent.futures import ThreadPoolExecutor

        _EXECUTOR.append(ThreadPoolExecutor(max_workers=analysis_threads(), thread_name_prefix="sms-indices"))
    return _EXECUTOR[0]


_WARMED: list = []


def _finite_positive(x: np.ndarray) -> bool:
    return x.size > 0 and bool(np.all(np.isfinite(x) & (x > 0)))


def manipulability(X: np.ndarray) -> np.ndarray:
    """μ of a stack of matrices (k×r×c): product of the min(r, c) singular values = sqrt(det) of
    the smaller Gram matrix (0 when rank-deficient); the kernel's formula (``kernels.manipulability``)."""
    return K.manipulability_stack(np.ascontiguousarray(X, dtype=float))


def _box_vertices(n: int) -> np.ndarray:
    """Sign patterns of a centred n-box, one of each ± pair (n × 2^(n-1))."""
    if n == 0:
        return np.zeros((0, 1))
    signs = np.array([(1.0,) + s for s in itertools.product((1.0, -1.0), repeat=n - 1)])
    return signs.T


class IndexKernel:
    """Evaluates the selected index groups on blocks of joint samples.

    ``model`` is a Pinocchio model with a free-flyer root; ``q_template`` is the full
    configuration whose sampled arm entries are overwritten (base pose, other joints kept).
    ``task``: "position" (EE linear rows) or "pose" (full twist) for the singularity test.
    """

    def __init__(self, model, ee_frame_id: int, q_template: np.ndarray, layout: ArmLayout,
                 groups: tuple[str, ...], singular_tolerance: float = 1e-3, task: str = "auto",
                 kinematics_only: bool = False):
        """``kinematics_only``: the model's inertias are placeholders, so only the groups that do not
        use the mass matrix run (pose, fixed-base manipulability, joint limits)."""
        import pinocchio as pin

        self.pin = pin
        self.model = model
        self.data = model.createData()
        self.fid = int(ee_frame_id)
        self.q_template = np.asarray(q_template, dtype=float).copy()
        self.L = layout
        self.tol = float(singular_tolerance)
        self.nm = len(layout.v_arm)
        self.nr = len(layout.v_wheels)
        self.task = ("position" if self.nm < 6 else "pose") if task == "auto" else task
        self.kinematics_only = kinematics_only
        self.groups = self._feasible_groups(tuple(groups))
        self.columns = list(GROUP_COLUMNS["pose"])
        for g in self.groups:
            self.columns.extend(GROUP_COLUMNS[g])
        self._act = np.concatenate([layout.v_arm, layout.v_wheels]).astype(int)  # arm, then wheels
        self._symmetric: bool | None = None
        self._wheel_rank: int | None = None
        if "momentum" in self.groups:
            self._vertices = np.ascontiguousarray(_box_vertices(self.nm) * layout.q_max[:, None])
        # limits as the kernel takes them (float64, contiguous; unused ones may be inf)
        self._q_max = np.ascontiguousarray(layout.q_max, dtype=float)
        self._omega_max = np.ascontiguousarray(layout.omega_max, dtype=float)
        self._tau_max = np.ascontiguousarray(layout.tau_max, dtype=float)

    def _feasible_groups(self, groups: tuple[str, ...]) -> tuple[str, ...]:
        """Drop the groups whose limits are missing; the reason goes to ``layout.skipped``."""
        L = self.L
        out = []
        for g in groups:
            why = ""
            if self.kinematics_only and g == "manipulability":
                L.skipped["manipulability (free-floating part)"] = KINEMATICS_ONLY
                g = "fixed_manipulability"
            if self.nm == 0:
                why = "the robot has no arm joint"
            elif self.kinematics_only and g not in KINEMATIC_GROUPS:
                why = KINEMATICS_ONLY
            elif g == "dynamic_manipulability" and not _finite_positive(L.tau_max):
                why = "joint effort limits missing: set analysis.limits.joint_torque"
            elif g in ("base_indices", "null_motion", "momentum") and not _finite_positive(L.q_max):
                why = "joint speed limits missing: set analysis.limits.joint_speed"
            elif g in ("base_indices", "null_motion") and self.nr and not _finite_positive(L.omega_max):
                why = "wheel speed limits missing: set analysis.limits.wheel_speed"
            elif g == "joint_limits" and not np.any(np.isfinite(L.lower) & np.isfinite(L.upper)):
                why = "no arm joint has finite position limits"
            if why:
                L.skipped[g] = why
            else:
                out.append(g)
        return tuple(out)

    def configurations(self, samples: np.ndarray) -> np.ndarray:
        """Full configurations (k × nq) from sample rows (k × n_sampled)."""
        Q = np.repeat(self.q_template[None, :], samples.shape[0], axis=0)
        for col, j in enumerate(self.L.sampled):
            qi = int(self.L.q_index[j])
            if self.L.kinds[j] == "continuous":
                Q[:, qi] = np.cos(samples[:, col])
                Q[:, qi + 1] = np.sin(samples[:, col])
            else:
                Q[:, qi] = samples[:, col]
        return Q

    def arm_positions(self, Q: np.ndarray) -> np.ndarray:
        """Arm joint coordinates (k × n_m) of full configurations."""
        out = np.empty((Q.shape[0], self.nm))
        for j in range(self.nm):
            qi = int(self.L.q_index[j])
            if self.L.kinds[j] == "continuous":
                out[:, j] = np.arctan2(Q[:, qi + 1], Q[:, qi])
            else:
                out[:, j] = Q[:, qi]
        return out

    def pinocchio_terms(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mass matrices (k × nv × nv) and LOCAL EE Jacobians (k × 6 × nv): the per-sample cost."""
        pin, model, data, fid = self.pin, self.model, self.data, self.fid
        k = Q.shape[0]
        Ms = np.empty((k, model.nv, model.nv))
        Js = np.empty((k, 6, model.nv))
        crba, jac, local = pin.crba, pin.computeFrameJacobian, pin.ReferenceFrame.LOCAL
        for i, q in enumerate(Q):
            Ms[i] = crba(model, data, q)
            Js[i] = jac(model, data, q, fid, local)
        if self._symmetric is None and k:
            self._symmetric = bool(np.allclose(Ms[0], Ms[0].T, rtol=0.0, atol=1e-12 * max(1.0, np.abs(Ms[0]).max())))
        if not self._symmetric:  # some Pinocchio versions fill only the upper triangle
            Ms = np.triu(Ms) + np.swapaxes(np.triu(Ms, 1), -1, -2)
        return Ms, Js

    def evaluate(self, samples: np.ndarray) -> dict[str, np.ndarray]:
        """Every selected index at each sample row; column name → (k,) array."""
        Q = self.configurations(samples)
        Ms, Js = self.pinocchio_terms(Q)
        return self.from_terms(Q, Ms, Js)

    def from_terms(self, Q: np.ndarray, Ms: np.ndarray, Js: np.ndarray) -> dict[str, np.ndarray]:
        """Indices from the mass matrices and LOCAL EE Jacobians of the configurations Q (one compiled
        pass over the samples: ``kernels.block_indices``)."""
        L, nm, nr, g = self.L, self.nm, self.nr, self.groups
        free = bool(set(g) - set(KINEMATIC_GROUPS))
        what = K.FREE if free else 0
        for group, bit in (("manipulability", K.MANIP), ("dynamic_manipulability", K.DYN), ("base_indices", K.BASE),
                           ("null_motion", K.NULL), ("momentum", K.MOMENTUM)):
            if group in g:
                what |= bit
        if "momentum" in g and nr:
            if self._wheel_rank is None and len(Q):  # the wheels' momentum span, from the first sample
                A0 = self._compiled(Ms[:1], Js[:1], K.FREE)[1]
                self._wheel_rank = int(np.linalg.matrix_rank(A0[0, :, nm:]))
            if self._wheel_rank == 3:
                what |= K.ZONOTOPE
        X, A, _ = self._compiled(Ms, Js, what)
        col = dict(zip(K.OUT, X))
        out: dict[str, np.ndarray] = {c: col[c] for c in GROUP_COLUMNS["pose"]}
        self._joint_limits(Q, out)
        fixed_regular = col["fixed_cond"] >= self.tol
        if "fixed_manipulability" in g:
            out.update(mu_fixed=col["mu_fixed"], fixed_cond=col["fixed_cond"], singular=(~fixed_regular).astype(float))
        if not free:
            return out
        if "manipulability" in g:
            mu_s, mu_f = col["mu_gjm"], col["mu_fixed"]
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(fixed_regular, mu_s / mu_f, np.nan)
            out.update(mu_fixed=mu_f, mu_gjm=mu_s, gjm_cond=col["gjm_cond"],
                       singular=(col["gjm_cond"] < self.tol).astype(float), mu_ratio=ratio)
        if "dynamic_manipulability" in g:
            out["mu_dyn"] = col["mu_dyn"]
        if "base_indices" in g:
            out.update(K_m=col["K_m"], K_r=col["K_r"])
        if "null_motion" in g:
            mus_l, mun_l, mu_fs = col["mu_scal_lin"], col["mu_null_lin"], col["mu_fixed_scaled"]
            ok = fixed_regular & (mu_fs > 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                out.update(mu_scal_lin=mus_l, mu_null_lin=mun_l, mu_null_ang=col["mu_null_ang"],
                           mu_scal_lin_norm=np.where(ok, mus_l / mu_fs, np.nan),
                           mu_null_lin_norm=np.where(ok, mun_l / mu_fs, np.nan))
        if "momentum" in g:
            out["h_arm_max"] = col["h_arm_max"]
            if not nr:
                out["h_ratio"] = np.full(len(Q), np.inf)
            elif self._wheel_rank == 3:
                out["h_ratio"] = col["h_ratio"]
            else:
                out["h_ratio"] = _zonotope_gauge(A[:, :, :nm] @ self._vertices, A[:, :, nm:] * L.omega_max, self._wheel_rank)
        return out

    def warm_up(self) -> None:
        """Load (on a cold cache: compile, with the pause shown on stderr) ``kernels.block_indices`` for
        this kernel's argument types, once per process (``_compiled`` does it on its first call)."""
        if _WARMED:
            return
        from sms_cli.sim.compiled.warmup import warm

        warm([[self.warm_call()]], what="analysis")
        _WARMED.append(True)

    def warm_call(self):
        """The ``kernels.block_indices`` call of this kernel on throw-away arrays of its argument types
        (``sms_cli.sim.compiled.warmup.KernelCall``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        nv, n = self.model.nv, self.nm + self.nr
        Ms, Js = np.zeros((1, nv, nv)), np.zeros((1, 6, nv))
        i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
        args = (Ms, Js, i64(self.L.v_arm), i64(self._act), False, 0, self._q_max, self._omega_max, self._tau_max,
                np.zeros((self.nm, 1)), np.full((1, len(K.OUT)), np.nan), np.empty((1, 3, n)), np.empty((1, 6, n)))
        return KernelCall("sms_cli.analysis.kernels:block_indices", args)

    def _compiled(self, Ms: np.ndarray, Js: np.ndarray, what: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``kernels.block_indices`` on a block: (columns ``kernels.OUT`` × k, A k × 3 × n, J* k × 6 × n),
        its parts on :func:`analysis_threads` threads."""
        L, k, n = self.L, len(Ms), self.nm + self.nr
        X = np.full((k, len(K.OUT)), np.nan)
        A, Jst = np.empty((k, 3, n)), np.empty((k, 6, n))
        vertices = self._vertices if "momentum" in self.groups else np.zeros((self.nm, 1))
        Ms, Js = np.ascontiguousarray(Ms, dtype=float), np.ascontiguousarray(Js, dtype=float)
        arm, act = np.ascontiguousarray(L.v_arm, dtype=np.int64), np.ascontiguousarray(self._act, dtype=np.int64)

        self.warm_up()

        def part(a: int, b: int) -> None:
            K.block_indices(Ms[a:b], Js[a:b], arm, act, self.task == "pose", what, self._q_max, self._omega_max,
                            self._tau_max, vertices, X[a:b], A[a:b], Jst[a:b])

        parts = min(analysis_threads(), k // MIN_PART)
        if parts > 1:
            cuts = [k * i // parts for i in range(parts + 1)]
            for f in [_executor().submit(part, a, b) for a, b in zip(cuts[:-1], cuts[1:])]:
                f.result()
        else:
            part(0, k)
        return np.ascontiguousarray(X.T), A, Jst

    def generalized_jacobians(self, samples: np.ndarray) -> dict[str, np.ndarray]:
        """J*_mEE, J*_rEE (3.8) at each sample (k × 6 × n, EE twist [v; ω] in R_sat), the centroidal
        momentum columns h_G (k × 3 × n, arm then wheels) and the EE position in R_sat (k × 3)."""
        Q = self.configurations(samples)
        Ms, Js = self.pinocchio_terms(Q)
        X, A, J = self._compiled(Ms, Js, K.FREE)
        return {"J_mEE": J[:, :, :self.nm], "J_rEE": J[:, :, self.nm:], "h_G": A, "ee_position": X[0:3].T.copy()}

    def _joint_limits(self, Q: np.ndarray, out: dict[str, np.ndarray]) -> None:
        if "joint_limits" not in self.groups:
            return
        L = self.L
        qa = self.arm_positions(Q)
        lim = np.isfinite(L.lower) & np.isfinite(L.upper) & (L.upper > L.lower)
        lo, hi = L.lower[lim], L.upper[lim]
        margin = 2.0 * np.minimum(qa[:, lim] - lo, hi - qa[:, lim]) / (hi - lo)
        out["joint_limit_margin"] = np.clip(margin.min(axis=1), 0.0, 1.0)


def _zonotope_gauge(H: np.ndarray, G: np.ndarray, rank: int) -> np.ndarray:
    """Per sample, max over the columns h of H of the gauge of h in the zonotope {G t, |t|∞ ≤ 1}.

    A 3-D zonotope's facets are parallel to pairs of generators, so the gauge is
    max_n |nᵀh| / Σ_i |nᵀ g_i| over n = g_i × g_j (``kernels.zonotope_gauge``). Coplanar or
    collinear wheel axes (``rank`` < 3) use the exact lower-dimensional gauge (inf for momentum
    outside the wheels' span).
    """
    k, _, nr = G.shape
    gmax = float(np.abs(G).max()) if G.size else 0.0
    tiny = 1e-12 * max(gmax, 1e-300)
    if rank < 3:
        return np.array([_gauge_low_rank(H[s], G[s], tiny) for s in range(k)])
    return K.zonotope_gauge_stack(np.ascontiguousarray(H, dtype=float), np.ascontiguousarray(G, dtype=float))


def _gauge_low_rank(H: np.ndarray, G: np.ndarray, tiny: float) -> float:
    """Gauge of the columns of H in the zonotope of G (3 × n) when rank(G) < 3."""
    U, s, _ = np.linalg.svd(G)
    r = int(np.sum(s > tiny))
    if r == 0:
        return float(np.inf) if np.abs(H).max() > tiny else 0.0
    basis, ortho = U[:, :r], U[:, r:]
    if np.abs(ortho.T @ H).max() > 1e-9 * max(np.abs(H).max(), tiny):
        return float(np.inf)
    Hc, Gc = basis.T @ H, basis.T @ G
    if r == 1:
        return float(np.abs(Hc).max() / np.abs(Gc).sum())
    rot = np.array([[0.0, -1.0], [1.0, 0.0]])
    normals = rot @ Gc  # in-plane edge normals of the zonogon
    nn = np.linalg.norm(normals, axis=0)
    normals = normals[:, nn > tiny] / nn[nn > tiny]
    supp = np.abs(normals.T @ Gc).sum(axis=1)
    return float((np.abs(normals.T @ Hc) / supp[:, None]).max())
