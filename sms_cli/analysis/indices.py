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


def _finite_positive(x: np.ndarray) -> bool:
    return x.size > 0 and bool(np.all(np.isfinite(x) & (x > 0)))


def det3(A: np.ndarray) -> np.ndarray:
    """Determinants of a stack of 3×3 matrices (closed form)."""
    return (A[..., 0, 0] * (A[..., 1, 1] * A[..., 2, 2] - A[..., 1, 2] * A[..., 2, 1])
            - A[..., 0, 1] * (A[..., 1, 0] * A[..., 2, 2] - A[..., 1, 2] * A[..., 2, 0])
            + A[..., 0, 2] * (A[..., 1, 0] * A[..., 2, 1] - A[..., 1, 1] * A[..., 2, 0]))


def inv3(A: np.ndarray) -> np.ndarray:
    """Inverses of a stack of 3×3 matrices (adjugate over determinant)."""
    c0 = np.cross(A[..., 1, :], A[..., 2, :])
    c1 = np.cross(A[..., 2, :], A[..., 0, :])
    c2 = np.cross(A[..., 0, :], A[..., 1, :])
    det = np.einsum("...i,...i->...", A[..., 0, :], c0)
    return np.stack([c0, c1, c2], axis=-1) / det[..., None, None]


def eig_sym3(G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest eigenvalues of a stack of symmetric 3×3 matrices (Smith 1961)."""
    q = (G[..., 0, 0] + G[..., 1, 1] + G[..., 2, 2]) / 3.0
    p1 = G[..., 0, 1] ** 2 + G[..., 0, 2] ** 2 + G[..., 1, 2] ** 2
    p2 = (G[..., 0, 0] - q) ** 2 + (G[..., 1, 1] - q) ** 2 + (G[..., 2, 2] - q) ** 2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    safe = np.where(p > 0, p, 1.0)
    B = (G - q[..., None, None] * np.eye(3)) / safe[..., None, None]
    r = np.clip(det3(B) / 2.0, -1.0, 1.0)
    phi = np.arccos(r) / 3.0
    hi = np.where(p > 0, q + 2.0 * p * np.cos(phi), q)
    lo = np.where(p > 0, q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0), q)
    return lo, hi


def gram(X: np.ndarray) -> np.ndarray:
    """The smaller Gram matrix of each matrix of a stack (X Xᵀ if rows ≤ cols, else Xᵀ X)."""
    Xt = np.swapaxes(X, -1, -2)
    return X @ Xt if X.shape[-2] <= X.shape[-1] else Xt @ X


def mu_of_gram(G: np.ndarray) -> np.ndarray:
    """sqrt(det G), clipped at 0 (closed form for 3×3)."""
    n = G.shape[-1]
    d = det3(G) if n == 3 else (np.linalg.det(G) if n else np.ones(G.shape[:-2]))
    return np.sqrt(np.maximum(d, 0.0))


def manipulability(X: np.ndarray) -> np.ndarray:
    """μ of a stack of matrices (k×r×c): product of the min(r, c) singular values = sqrt(det) of
    the smaller Gram matrix (0 when rank-deficient)."""
    r, c = X.shape[-2:]
    if r == 0 or c == 0:
        return np.zeros(X.shape[0])
    if r == c == 3:
        return np.abs(det3(X))
    return mu_of_gram(gram(X))


def cond_of_gram(G: np.ndarray) -> np.ndarray:
    """σ_min/σ_max of the matrix whose Gram matrix is G (0 for a zero matrix)."""
    if G.shape[-1] == 3:
        lo, hi = eig_sym3(G)
    elif G.shape[-1] == 0:
        return np.zeros(G.shape[:-2])
    else:
        ev = np.linalg.eigvalsh(G)
        lo, hi = ev[..., 0], ev[..., -1]
    return np.sqrt(np.clip(lo, 0.0, None) / np.where(hi > 0, hi, np.inf))


def _skew_stack(v: np.ndarray) -> np.ndarray:
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def _cross_cols(c: np.ndarray, X: np.ndarray) -> np.ndarray:
    """c × each column of X: c (k×3), X (k×3×n) → k×3×n."""
    c0, c1, c2 = c[:, 0, None], c[:, 1, None], c[:, 2, None]
    x0, x1, x2 = X[:, 0], X[:, 1], X[:, 2]
    return np.stack([c1 * x2 - c2 * x1, c2 * x0 - c0 * x2, c0 * x1 - c1 * x0], axis=1)


def _rpy_zyx(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) of a stack of rotations."""
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    pitch = np.arcsin(np.clip(-R[:, 2, 0], -1.0, 1.0))
    roll = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    return np.column_stack([roll, pitch, yaw])


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
            self._vertices = _box_vertices(self.nm) * layout.q_max[:, None]

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
        """Indices from the mass matrices and LOCAL EE Jacobians of the configurations Q."""
        L, nm, nr, g = self.L, self.nm, self.nr, self.groups
        arm = L.v_arm.astype(int)
        out: dict[str, np.ndarray] = {}
        # EE frame → R_sat: the base-angular columns of the LOCAL Jacobian are R_eeᵀ R_0.
        Rs = np.swapaxes(Js[:, 3:6, 3:6], -1, -2)  # R_sat←ee
        Jl = Rs @ Js[:, 0:3, :][:, :, np.r_[3:6, arm]]  # linear rows: [-[d]× | J_m,lin]
        Jm_lin, Jm_ang = Jl[:, :, 3:], Rs @ Js[:, 3:6, :][:, :, arm]  # fixed-base arm Jacobian (R_sat)
        d = np.column_stack([Jl[:, 1, 2], Jl[:, 2, 0], Jl[:, 0, 1]])  # EE origin in R_sat
        rpy = _rpy_zyx(Rs)
        out.update(ee_x=d[:, 0], ee_y=d[:, 1], ee_z=d[:, 2], ee_roll=rpy[:, 0], ee_pitch=rpy[:, 1], ee_yaw=rpy[:, 2])
        self._joint_limits(Q, out)
        if "fixed_manipulability" in g:
            Jt_fix = Jm_lin if self.task == "position" else np.concatenate([Jm_lin, Jm_ang], axis=1)
            cond = cond_of_gram(gram(Jt_fix))
            out.update(mu_fixed=manipulability(Jt_fix), fixed_cond=cond, singular=(cond < self.tol).astype(float))
        if not set(g) - set(KINEMATIC_GROUPS):
            return out

        A, xa, xl, Jst_lin, Jst_ang = self._free_floating(Ms, d, Jm_lin, Jm_ang)
        if self.task == "position":
            Jt_star, Jt_fix = Jst_lin[:, :, :nm], Jm_lin
        else:
            Jt_star = np.concatenate([Jst_lin[:, :, :nm], Jst_ang[:, :, :nm]], axis=1)  # J*_mEE, k × 6 × nm
            Jt_fix = np.concatenate([Jm_lin, Jm_ang], axis=1)
        if "manipulability" in g or "null_motion" in g:
            fixed_regular = cond_of_gram(gram(Jt_fix)) >= self.tol
        if "manipulability" in g:
            cond = cond_of_gram(gram(Jt_star))
            mu_s, mu_f = manipulability(Jt_star), manipulability(Jt_fix)
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(fixed_regular, mu_s / mu_f, np.nan)
            out.update(mu_fixed=mu_f, mu_gjm=mu_s, gjm_cond=cond, singular=(cond < self.tol).astype(float),
                       mu_ratio=ratio)
        if "dynamic_manipulability" in g:
            Xm = np.concatenate([xl[:, :, :nm], xa[:, :, :nm]], axis=1)  # M_bb⁻¹ M_bm
            Hstar = Ms[:, arm][:, :, arm] - Ms[:, arm, 0:6] @ Xm  # H*_m: base free, wheels locked
            Hinv = inv3(Hstar) if nm == 3 else np.linalg.inv(Hstar)
            out["mu_dyn"] = manipulability((Jt_star @ Hinv) * L.tau_max)  # J◇ = J* H*⁻¹ diag(τ_max)
        if "base_indices" in g:
            fm = np.einsum("kij,kij->k", A[:, :, :nm], A[:, :, :nm] * L.q_max ** 2)  # ‖S_U J^ω0_m0 Q_max‖²_F
            fr = np.einsum("kij,kij->k", A[:, :, nm:], A[:, :, nm:] * L.omega_max ** 2) if nr else np.zeros_like(fm)
            tot = np.sqrt(fm + fr)
            with np.errstate(divide="ignore", invalid="ignore"):
                out.update(K_m=np.sqrt(fm) / tot, K_r=np.sqrt(fr) / tot)
        if "null_motion" in g:
            scale = np.concatenate([L.q_max, L.omega_max[:nr]])
            lin, ang = Jst_lin * scale, Jst_ang * scale  # J^scal_rEE, J^scal_ωEE (3.23)
            mun_l, mun_a = _null_motion_mu(-xa * scale, lin, ang)  # J^scal_ω0 (3.17a)
            mus_l = manipulability(lin)
            mu_fs = manipulability(Jm_lin * L.q_max)
            ok = fixed_regular & (mu_fs > 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                out.update(mu_scal_lin=mus_l, mu_null_lin=mun_l, mu_null_ang=mun_a,
                           mu_scal_lin_norm=np.where(ok, mus_l / mu_fs, np.nan),
                           mu_null_lin_norm=np.where(ok, mun_l / mu_fs, np.nan))
        if "momentum" in g:
            H = A[:, :, :nm] @ self._vertices  # k × 3 × n_vertices
            out["h_arm_max"] = np.sqrt(np.einsum("kiv,kiv->kv", H, H).max(axis=1))
            if nr:
                if self._wheel_rank is None:
                    self._wheel_rank = int(np.linalg.matrix_rank(A[0, :, nm:]))
                out["h_ratio"] = _zonotope_gauge(H, A[:, :, nm:] * L.omega_max, self._wheel_rank)
            else:
                out["h_ratio"] = np.full(len(Q), np.inf)
        return out

    def _free_floating(self, Ms, d, Jm_lin, Jm_ang):
        """Centroidal momentum columns A and the zero-momentum maps, all in R_sat.

        Returns A (h_G per actuator rate), xa = -ω_b and xl = -v_b per actuator rate, and the EE
        generalized Jacobians [J*_mEE J*_rEE] split in linear and angular rows.
        """
        nm = self.nm
        # Base block of M = [[m I, -m[c]×], [m[c]×, I_O]] (R_sat, base-link origin O, CoM c).
        m = Ms[:, 0, 0][:, None, None]
        c = np.column_stack([Ms[:, 5, 1], Ms[:, 3, 2], Ms[:, 4, 0]]) / m[:, 0]
        Bact = Ms[:, 0:6, :][:, :, self._act]  # momentum [p; h_O] per actuator rate
        A = Bact[:, 3:6] - _cross_cols(c, Bact[:, 0:3])  # h_G = h_O - c × p: arm columns, then wheels
        # Zero momentum, seed (3.5): ω_b = -S_U⁻¹ A, S_U = I_O + m[c]×[c]× (locked inertia about
        # the CoM, the Schur complement of (3.7)); v_b = -(p/m + c × S_U⁻¹ A).
        SU = Ms[:, 3:6, 3:6] + m * (c[:, :, None] * c[:, None, :] - np.einsum("ki,ki->k", c, c)[:, None, None] * np.eye(3))
        xa = inv3(SU) @ A
        xl = Bact[:, 0:3] / m + _cross_cols(c, xa)
        # J* (3.8): [J_m; 0] plus the base-velocity map (EE velocity v_b + ω_b × d, EE rate ω_b).
        Jst_lin = _cross_cols(d, xa) - xl
        Jst_lin[:, :, :nm] += Jm_lin
        Jst_ang = -xa
        Jst_ang[:, :, :nm] += Jm_ang
        return A, xa, xl, Jst_lin, Jst_ang

    def generalized_jacobians(self, samples: np.ndarray) -> dict[str, np.ndarray]:
        """J*_mEE, J*_rEE (3.8) and the fixed-base J_m at each sample: k × 6 × n, EE twist [v; ω] in R_sat."""
        Q = self.configurations(samples)
        Ms, Js = self.pinocchio_terms(Q)
        Rs = np.swapaxes(Js[:, 3:6, 3:6], -1, -2)
        arm = self.L.v_arm.astype(int)
        Jl = Rs @ Js[:, 0:3, :][:, :, np.r_[3:6, arm]]
        Jm_lin, Jm_ang = Jl[:, :, 3:], Rs @ Js[:, 3:6, :][:, :, arm]
        d = np.column_stack([Jl[:, 1, 2], Jl[:, 2, 0], Jl[:, 0, 1]])
        A, xa, xl, Jst_lin, Jst_ang = self._free_floating(Ms, d, Jm_lin, Jm_ang)
        J = np.concatenate([Jst_lin, Jst_ang], axis=1)
        return {"J_mEE": J[:, :, :self.nm], "J_rEE": J[:, :, self.nm:], "J_m_fixed": np.concatenate([Jm_lin, Jm_ang], axis=1),
                "h_G": A, "ee_position": d}

    def _joint_limits(self, Q: np.ndarray, out: dict[str, np.ndarray]) -> None:
        if "joint_limits" not in self.groups:
            return
        L = self.L
        qa = self.arm_positions(Q)
        lim = np.isfinite(L.lower) & np.isfinite(L.upper) & (L.upper > L.lower)
        lo, hi = L.lower[lim], L.upper[lim]
        margin = 2.0 * np.minimum(qa[:, lim] - lo, hi - qa[:, lim]) / (hi - lo)
        out["joint_limit_margin"] = np.clip(margin.min(axis=1), 0.0, 1.0)


def centroidal_columns(Ms: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Angular momentum about the system CoM per unit rate of the joints ``cols`` (base still), R_sat.

    From the base rows of M: h_O = M[3:6], p = M[0:3], h_G = h_O - c × p with the CoM
    c = vee(M[3:6, 0:3]) / m. Equals -S_U J^{ω0} of Kraiem 2022 (3.15)-(3.16).
    """
    m = Ms[:, 0, 0]
    c = np.column_stack([Ms[:, 5, 1], Ms[:, 3, 2], Ms[:, 4, 0]]) / m[:, None]
    B = Ms[:, 0:6, :][:, :, cols]
    return B[:, 3:6] - _cross_cols(c, B[:, 0:3])


def _null_motion_mu(Jw0: np.ndarray, lin: np.ndarray, ang: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """μ(X N) for X = lin, ang with N = I - J⁺J, J = Jw0 (3 × n) (3.24)-(3.25).

    N is a symmetric projector, so (XN)(XN)ᵀ = X Xᵀ - (X Jᵀ)(J Jᵀ)⁻¹(X Jᵀ)ᵀ when J has full row
    rank; other samples (and n < 3) use the pseudo-inverse.
    """
    k, _, n = Jw0.shape
    res = [np.empty(k), np.empty(k)]
    if n >= 3:
        Jt = np.swapaxes(Jw0, -1, -2)
        G = Jw0 @ Jt
        tr = (G[:, 0, 0] + G[:, 1, 1] + G[:, 2, 2]) / 3.0
        ok = det3(G) > 1e-14 * tr ** 3  # J Jᵀ well conditioned (cond(J) ≲ 1e7)
        Gi = inv3(np.where(ok[:, None, None], G, np.eye(3)))
        for r, X in zip(res, (lin, ang)):
            XJ = X @ Jt
            XX = X @ np.swapaxes(X, -1, -2)
            r[:] = mu_of_gram(XX - XJ @ Gi @ np.swapaxes(XJ, -1, -2))
            # the subtraction keeps ~half the digits: below √eps·‖X‖³ the value is round-off, report 0
            floor = 1e-7 * (XX[:, 0, 0] + XX[:, 1, 1] + XX[:, 2, 2]) ** 1.5
            r[r < floor] = 0.0
        bad = np.flatnonzero(~ok)
    else:
        bad = np.arange(k)
    if bad.size:
        N = np.eye(n)[None] - np.linalg.pinv(Jw0[bad]) @ Jw0[bad]
        res[0][bad] = manipulability(lin[bad] @ N)
        res[1][bad] = manipulability(ang[bad] @ N)
    return res[0], res[1]


def _zonotope_gauge(H: np.ndarray, G: np.ndarray, rank: int) -> np.ndarray:
    """Per sample, max over the columns h of H of the gauge of h in the zonotope {G t, |t|∞ ≤ 1}.

    A 3-D zonotope's facets are parallel to pairs of generators, so the gauge is
    max_n |nᵀh| / Σ_i |nᵀ g_i| over n = g_i × g_j (pairs of parallel generators give n = 0 and
    are ignored). Coplanar or collinear wheel axes (``rank`` < 3) use the exact
    lower-dimensional gauge (inf for momentum outside the wheels' span).
    """
    k, _, nr = G.shape
    gmax = float(np.abs(G).max()) if G.size else 0.0
    tiny = 1e-12 * max(gmax, 1e-300)
    if rank < 3:
        return np.array([_gauge_low_rank(H[s], G[s], tiny) for s in range(k)])
    i, j = np.triu_indices(nr, 1)
    normals = np.swapaxes(_cross_cols_pairs(G, i, j), 1, 2)  # k × P × 3
    nn = np.sqrt(np.einsum("kpi,kpi->kp", normals, normals))
    valid = nn > tiny * gmax
    normals = normals / np.where(valid, nn, 1.0)[:, :, None]
    supp = np.abs(normals @ G).sum(axis=2)  # support function of the zonotope, k × P
    proj = np.abs(normals @ H)  # k × P × V
    ratio = np.where(valid[:, :, None], proj / np.where(supp > 0, supp, np.inf)[:, :, None], 0.0)
    return ratio.max(axis=(1, 2))


def _cross_cols_pairs(G: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """G[:, :, i] × G[:, :, j] for index pairs (k × 3 × P)."""
    a, b = G[:, :, i], G[:, :, j]
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


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
