"""Momentum-based attitude laws of Vicariotto 2023 ch. 4, each with its Lyapunov function W (issue #12 item 3).

Unlike the laws of ``attitude`` (a base torque the engine allocates to the wheels or the thrusters), these
laws return what they actuate: ``actuate(sensed, ref) -> (wheel torques (n_w,) or None, base wrench (6,) or
None)``, the wrench in Pinocchio's base joint frame ``[f; n]`` about the base origin (the thrusters' input).
``lyapunov_terms(q, v, ref_quat) -> dict`` evaluates the law's W and its terms on a state (recorded on
``/control/lyapunov``).

Quantities (base frame, SI; ``sms_cli.dynamics.locked``, Vicariotto 2023 (4.2)-(4.8)): I the locked inertia
about the CoM, G J the wheel coupling, Λ = I⁻¹GJ, μ = ω + Λθ̇, M_θ = J − JGᵀI⁻¹GJ (the wheels' shape inertia).
Attitude error (Vicariotto 2023 L361): R_e = R_dᵀR, R (world ← base) the base attitude and R_d (world ←
reference) the phase's reference, held constant (regulation, the thesis's case; a slewing reference is not
covered by the proofs). Potential Φ = ½ tr(K_p(1 − R_e)) (L375) with K_p = diag(kp), γ = (skew(K_p R_e))^∨
(4.11, L718), so that Φ̇ = γᵀω.

Exact dynamics used by the proofs (derived here from the mass matrix blocks, any wheel axes G; the thesis's
(4.6)/(4.7) with its errata, notes §9 items 12 and 18):

- locked: I μ̇ + ω × (Iμ) = τ_c (external torque about the CoM), so d/dt ½μᵀIμ = μᵀτ_c + μᵀ((Λθ̇) × Iμ);
- shape: τ_w = J(Gᵀω̇ + θ̈) gives M_θ θ̈ = τ_w − Λᵀτ_c + Λᵀ(ω × Iμ).

Shaped wheel kinetic energy ½θ̇ᵀXθ̇: X = M_θ (plain) or X = ΛᵀM_θ (inertia shaping, §4.2.2, (4.14); needs
3 wheels and ΛᵀM_θ symmetric positive definite, true for A = I as in the thesis). The wheel law
τ_w = M_θX⁻¹(Λᵀγ − K_dθ̇) gives d/dt(½θ̇ᵀXθ̇ + Φ) = −θ̇ᵀK_dθ̇ at μ = 0: with X = M_θ it is (4.13) exactly,
τ_w = Λᵀγ − K_dθ̇; with X = ΛᵀM_θ and A = I it is τ_w = γ − Λ⁻ᵀK_dθ̇, the notes' reading (§4.3) of the garbled
L772-L776 law "τ_w = γ − K_dθ̇" (the stiffness enters without the Λᵀ factor, the rotors behave as if their
inertia were ΛᵀM_θ), with the damping written so that Ẇ_θ = −θ̇ᵀK_dθ̇ as the thesis prints.

The arithmetic of every law and of its W is in the numba kernels of ``sms_cli.sim.compiled.momentum_laws`` (one
implementation, callable from a compiled loop); the classes here compute the locked/shape quantities with
Pinocchio (``sms_cli.dynamics.locked``), hold the gains (``par``) and the law's state (``mem``) as flat arrays,
and call the kernels.
"""

from __future__ import annotations

import numpy as np

from sms_cli.sim.interfaces import AttitudeRef, Sensed


def _kernels():
    from sms_cli.sim.compiled import momentum_laws

    return momentum_laws


def _gains(x, n: int, name: str) -> np.ndarray:
    """A diagonal gain as its n diagonal values (one positive value or n)."""
    a = np.asarray(x, float)
    a = np.full(n, float(a)) if a.ndim == 0 else a
    if a.shape != (n,) or not np.all(a > 0):
        raise ValueError(f"{name}: one positive value or {n}")
    return a.copy()


def _f64(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


class _MomentumLaw:
    """Common part: the locked/shape quantities (cached on a wheel-only rigid robot; recomputed per call when
    the mass changes, i.e. with real thrusters and propellant), the gains ``par`` and state ``mem`` in the
    kernels' layouts (``sms_cli.sim.compiled.momentum_laws``), and the calls of the law's two kernels
    (``kernel``, ``kernel + "_lyapunov"``). ``terms``: the W terms the law reports."""

    uses_wrench = False
    needs_wheels = True
    kernel = ""
    code = 0  # the kernel's code in ``momentum_laws.momentum_law`` (the compiled loop's dispatch)
    terms: tuple = ()

    def __init__(self, sm, kp, shaping: bool):
        from sms_cli.dynamics.locked import locked_shape, shape_invariant

        K = _kernels()
        if not sm.wheels and self.needs_wheels:
            raise ValueError("this law needs reaction wheels")
        if not shape_invariant(sm):
            raise ValueError("this law needs a rigid base whose only other joints are balanced wheels (no arm, no modes): "
                             "its Λ, I and M_θ are taken constant along the motion")
        self.sm = sm
        self.shaping = shaping
        n = len(sm.idx.wheels)
        self.par = np.zeros(K.P_N + n)
        self.par[K.P_KP:K.P_KP + 3] = _gains(kp, 3, "kp")
        self.par[K.P_SHAPING] = float(shaping)
        self.mem = np.zeros(K.M_N)
        self.mem[K.M_STAGE] = 1.0
        self._mem0 = self.mem.copy()
        self._wheels = np.asarray(sm.idx.wheels, dtype=np.int64)
        self._fixed_mass = sm.thrusters is None
        self._ls = locked_shape(sm, sm.q0) if self._fixed_mass else None
        self._locked_shape = locked_shape
        self._args0 = self._model_args(self._ls) if self._fixed_mass else None
        ls = self._quantities(sm.q0)
        if shaping:
            if ls.Lambda.shape[1] != 3:
                raise ValueError("inertia shaping (Vicariotto 2023 §4.2.2) needs 3 wheels: X = ΛᵀM_θ is n×n only for n = 3")
            X = ls.Lambda.T @ ls.M_theta
            if np.abs(X - X.T).max() > 1e-9 * np.abs(X).max() or np.linalg.eigvalsh(0.5 * (X + X.T)).min() <= 0:
                raise ValueError("inertia shaping needs ΛᵀM_θ symmetric positive definite (wheel axes along the locked "
                                 "inertia's principal axes, as A = I in Vicariotto 2023 L762)")

    def _quantities(self, q):
        if self._fixed_mass:
            return self._ls
        return self._locked_shape(self.sm, q, self.sm.rigid_mass_matrix(q))

    def _model_args(self, ls) -> tuple:
        """The kernels' model arguments (wheels, mass, com_base, Tv, I, G, J, Λ, M_θ) of the locked/shape quantities."""
        return (self._wheels, float(ls.mass), _f64(ls.com_base), _f64(ls.T[0:3, 3:]), _f64(ls.I), _f64(ls.G), _f64(ls.J),
                _f64(ls.Lambda), _f64(ls.M_theta))

    def _args(self, q) -> tuple:
        return self._args0 if self._fixed_mass else self._model_args(self._quantities(q))

    @property
    def fixed_mass(self) -> bool:
        """Whether the law's locked/shape quantities are constant (no propellant spent): then ``model_args``."""
        return self._fixed_mass

    def model_args(self, q=None) -> tuple:
        """The kernels' model arguments (wheels, mass, com_base, Tv, I, G, J, Λ, M_θ) a compiled loop passes to
        ``momentum_laws.momentum_law``: constant while the mass is fixed, else at q and the model's current mass."""
        return self._args0 if self._fixed_mass else self._model_args(self._quantities(np.asarray(q, float)))

    def locked_velocity(self, q, v) -> np.ndarray:
        """μ (3,) rad/s, base frame, from the law's locked/shape quantities (cached while the mass is fixed)."""
        return self._quantities(q).locked_velocity(np.asarray(v, float))

    def _actuate(self, q, v, ref_quat) -> tuple[np.ndarray, np.ndarray]:
        """(wheel torques (n,), base wrench (6,)) of the law's kernel (updates ``mem``)."""
        q = _f64(q)
        tau_w, wrench = np.empty(len(self._wheels)), np.empty(6)
        getattr(_kernels(), self.kernel)(q, _f64(v), _f64(ref_quat), *self._args(q), self.par, self.mem, tau_w, wrench)
        return tau_w, wrench

    def lyapunov_terms(self, q, v, ref_quat) -> dict:
        """W and its terms (``terms``) on the state (q, v) for the reference ``ref_quat`` (J; ``dissipation`` is
        the proof's −Ẇ)."""
        K = _kernels()
        q = _f64(q)
        out = np.empty(K.T_N)
        getattr(K, self.kernel + "_lyapunov")(q, _f64(v), _f64(ref_quat), *self._args(q), self.par, self.mem, out)
        return {name: float(out[K.TERM_NAMES.index(name)]) for name in self.terms}

    def warm_calls(self) -> list:
        """The kernel calls of a run (``sms_cli.sim.compiled.kernels``): the law and its W, with the run's
        argument types (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        K = _kernels()
        q = _f64(self.sm.q0).copy()
        v, ref = np.zeros(self.sm.nv), np.array([0.0, 0.0, 0.0, 1.0])
        args = tuple(a.copy() if isinstance(a, np.ndarray) else a for a in self._args(q))
        mod = "sms_cli.sim.compiled.momentum_laws"
        n = len(self._wheels)
        # cold-cache costs measured on the shared 2-core machine: 10-15 s for the first law kernel (its callees,
        # the potential, the wheel law and LAPACK's solve, compile with it), 1-3 s for its W kernel
        return [KernelCall(f"{mod}:{self.kernel}", (q, v, ref, *args, self.par.copy(), self.mem.copy(), np.empty(n),
                                                    np.empty(6)), cost=10.0),
                KernelCall(f"{mod}:{self.kernel}_lyapunov", (q, v, ref, *args, self.par.copy(), self.mem.copy(),
                                                             np.empty(K.T_N)), cost=2.0)]

    def reset(self) -> None:
        self.mem[:] = self._mem0


class WheelsFreeFloating(_MomentumLaw):
    """Free-floating, wheels only (Vicariotto 2023 (4.13), L737): τ_w = Λᵀγ − K_dθ̇; with inertia shaping
    (§4.2.2, L762-L780) τ_w = M_θ(ΛᵀM_θ)⁻¹(Λᵀγ − K_dθ̇) (= γ − Λ⁻ᵀK_dθ̇ for A = I). No base wrench.

    W (4.9) = ½μᵀIμ + ½θ̇ᵀM_θθ̇ + Φ (plain), W_θ (L768) = ½θ̇ᵀΛᵀM_θθ̇ + Φ (shaped; ½μᵀIμ is reported as a term).
    At zero momentum (μ = 0, no external torque) Ẇ = −θ̇ᵀK_dθ̇ (L741, L780).
    Computed by ``sms_cli.sim.compiled.momentum_laws.wheels_free_floating``."""

    kernel = "wheels_free_floating"
    code = 1  # momentum_laws.WHEELS_FREE_FLOATING
    terms = ("locked", "shape", "potential", "W", "dissipation")

    def __init__(self, sm, kp, kd, inertia_shaping: bool = False):
        super().__init__(sm, kp, inertia_shaping)
        self.par[_kernels().P_N:] = _gains(kd, len(sm.wheels), "kd")

    def actuate(self, s: Sensed, ref: AttitudeRef):
        return self._actuate(s.q, s.v, ref.quat)[0], None


class FreeFlying(_MomentumLaw):
    """Free-flying, thrusters + wheels (Vicariotto 2023 (4.15)/(4.16), L793-L801), translation PD (3.7):

    τ_c = −γ − K_d^b μ + (Iμ) × (Λθ̇)                         (4.15: the torque about the CoM)
    τ_w = Λᵀτ_c + M_θX⁻¹(Λᵀγ − K_d^w θ̇) − Λᵀ(ω × Iμ)          (4.16: the Coriolis coupling cancelled)
    f   = Rᵀ(−K_p^x Δx − K_d^x ċ)                             ((3.7) in the world frame, rotated into the base
                                                                frame: erratum 3 of the notes, L351 vs (3.13))

    Δx = c − c_d, c the system CoM (world), c_d its value at the first control tick (or ``target_com``); the
    wrench about the base origin is [f; τ_c + c_b × f] (c_b the CoM in the base frame). X = ΛᵀM_θ (inertia-
    shaped rotors, "considering the shaped-inertia kinetic energy", L791) or M_θ.
    W = ½m|ċ|² + ½ΔxᵀK_p^xΔx + ½μᵀIμ + ½θ̇ᵀXθ̇ + Φ, Ẇ = −ċᵀK_d^xċ − μᵀK_d^bμ − θ̇ᵀK_d^wθ̇ (4.17).
    Computed by ``sms_cli.sim.compiled.momentum_laws.free_flying``."""

    uses_wrench = True
    kernel = "free_flying"
    code = 2  # momentum_laws.FREE_FLYING

    def __init__(self, sm, kp, kd_base, kd_wheels, inertia_shaping: bool = True, kp_position=None,
                 kd_position=None, target_com=None):
        super().__init__(sm, kp, inertia_shaping)
        K = _kernels()
        self.par[K.P_KD:K.P_KD + 3] = _gains(kd_base, 3, "kd_base")
        self.par[K.P_N:] = _gains(kd_wheels, len(sm.wheels), "kd_wheels")
        self._init_translation(kp_position, kd_position, target_com)
        self.terms = ("locked", "shape", "potential", "translation") + ("position_error",) * self.translate + ("W", "dissipation")

    def _init_translation(self, kp_position, kd_position, target_com) -> None:
        """The translation PD (3.7) on the CoM: gains (N/m, N s/m) and target (world, m; none: the CoM at
        the first tick)."""
        K = _kernels()
        self.translate = kp_position is not None
        self.par[K.P_TRANSLATE] = float(self.translate)
        if self.translate:
            self.par[K.P_KX:K.P_KX + 3] = _gains(kp_position, 3, "kp_position")
            self.par[K.P_DX:K.P_DX + 3] = _gains(kd_position, 3, "kd_position")
        self.target = target_com
        self._mem0 = self.mem.copy()

    @property
    def target(self) -> np.ndarray | None:
        """The CoM target (world, m), None until the first tick sets it (without ``target_com``)."""
        K = _kernels()
        return self.mem[K.M_TARGET:K.M_TARGET + 3].copy() if self.mem[K.M_TARGET_SET] else None

    @target.setter
    def target(self, c) -> None:
        K = _kernels()
        self.mem[K.M_TARGET_SET] = float(c is not None)
        self.mem[K.M_TARGET:K.M_TARGET + 3] = 0.0 if c is None else np.asarray(c, float)

    def actuate(self, s: Sensed, ref: AttitudeRef):
        return self._actuate(s.q, s.v, ref.quat)


class Hierarchical(_MomentumLaw):
    """Hierarchical (Vicariotto 2023 §4.2.4, L814-L840): task 1, the thrusters detumble the locked motion,
    τ_c = −K_d^b μ + (Iμ) × (Λθ̇) (L826; wheels idle), W_1 = ½μᵀIμ, Ẇ_1 = −μᵀK_d^bμ; once |μ| ≤
    ``mu_threshold`` (rad/s; the thesis gives none, "once the cancellation of any residual momentum is
    accomplished", L814) task 2 for the rest of the run (latched): no wrench, the wheels' inertia-shaped law
    (4.18) τ_w = M_θX⁻¹(Λᵀγ − K_d^wθ̇), W_2 = ½θ̇ᵀXθ̇ + Φ (L830). W_2's proof assumes μ = 0; the residual μ
    left by the threshold adds the power ``residual`` = γᵀμ + θ̇ᵀXM_θ⁻¹Λᵀ(ω × Iμ) to Ẇ_2 = −θ̇ᵀK_d^wθ̇.
    Computed by ``sms_cli.sim.compiled.momentum_laws.hierarchical``."""

    uses_wrench = True
    kernel = "hierarchical"
    code = 3  # momentum_laws.HIERARCHICAL
    terms = ("locked", "shape", "potential", "stage", "W", "dissipation", "residual")

    def __init__(self, sm, kp, kd_base, kd_wheels, mu_threshold: float, inertia_shaping: bool = True):
        super().__init__(sm, kp, inertia_shaping)
        K = _kernels()
        self.par[K.P_KD:K.P_KD + 3] = _gains(kd_base, 3, "kd_base")
        self.par[K.P_N:] = _gains(kd_wheels, len(sm.wheels), "kd_wheels")
        self.par[K.P_THRESHOLD] = float(mu_threshold)
        self.threshold = float(mu_threshold)

    @property
    def stage(self) -> int:
        """The task (1: the thrusters detumble, 2: the wheels regulate), latched at 2."""
        return int(self.mem[_kernels().M_STAGE])

    @stage.setter
    def stage(self, k: int) -> None:
        self.mem[_kernels().M_STAGE] = float(k)

    def actuate(self, s: Sensed, ref: AttitudeRef):
        return self._actuate(s.q, s.v, ref.quat)


class Se3PD(FreeFlying):
    """Bullo-Murray PD on SE(3) (Vicariotto 2023 (3.7), (3.9), L351, L385) with the thrusters (or the ideal
    source), the wheels idle (zero torque): τ_c = −γ − K_dω about the CoM (erratum 4: (3.9) read as
    u_t = −γ − K_dω_b), f = Rᵀ(−K_p^xΔx − K_d^xċ) ((3.7) rotated into the base frame, erratum 3).
    W (L449) = ½m|ċ|² + ½ωᵀ(I − GJGᵀ)ω + ½ΔxᵀK_p^xΔx + Φ: the rigid body's, with I − GJGᵀ the inertia
    without the rotors' axial parts (idle rotors keep their axial momentum J(Gᵀω + θ̇), whose energy is
    constant), so that Ẇ = −ċᵀK_d^xċ − ωᵀK_dω ((3.15); = L449 exactly without wheels).
    Computed by ``sms_cli.sim.compiled.momentum_laws.se3_pd``."""

    needs_wheels = False
    kernel = "se3_pd"
    code = 4  # momentum_laws.SE3_PD

    def __init__(self, sm, kp, kd, kp_position=None, kd_position=None, target_com=None):
        _MomentumLaw.__init__(self, sm, kp, False)
        K = _kernels()
        self.par[K.P_KD:K.P_KD + 3] = _gains(kd, 3, "kd")
        self._init_translation(kp_position, kd_position, target_com)
        self.terms = ("rotation", "potential", "translation") + ("position_error",) * self.translate + ("W", "dissipation")


class QuaternionLyapunov(Se3PD):
    """The quaternion PD of Vicariotto 2023 §3.3.1 (L417-L435) with its Lyapunov function, on the base
    (thrusters or the ideal source; wheels idle; optional translation PD (3.7) as ``se3_pd``):
    τ_c = −k q₀ q − K_dω, (q₀, q) the error quaternion q_ref⁻¹ ⊗ q (scalar part q₀, vector part q, body
    frame), W = ½ωᵀ(I − GJGᵀ)ω + k qᵀq (+ the translation terms), Ẇ = −ωᵀK_dω: since
    q̇ = ½(q₀ω + q × ω), d/dt(k qᵀq) = k q₀ qᵀω, so the potential's γ is k q₀ q. k is one number (a diagonal
    K would leave qᵀK(q × ω) ≠ 0). ``quaternion_pd`` is L443's alternative τ = −k q_e − K_dω, without this W.
    Computed by ``sms_cli.sim.compiled.momentum_laws.quaternion_lyapunov``."""

    kernel = "quaternion_lyapunov"
    code = 5  # momentum_laws.QUATERNION_LYAPUNOV

    def __init__(self, sm, k, kd, kp_position=None, kd_position=None, target_com=None):
        super().__init__(sm, np.full(3, float(k)), kd, kp_position, kd_position, target_com)
        self.k = float(k)
        self.par[_kernels().P_K] = self.k


def lyapunov_metrics(result, spans, phase: np.ndarray, W: np.ndarray, stage: np.ndarray | None = None,
                     position_error: np.ndarray | None = None) -> None:
    """Add W's figures to ``result`` (a ``SimResult``) from the series of W evaluations (the phase start's, then one
    per plant step; ``phase``: their phase indices; ``stage``: the hierarchical law's task, None: 1; ``position_error``:
    the translation PD's |Δx|, m, None without it). Per phase of ``spans``: W at its start and end, the largest increase
    of W over one plant step and the sum of the increases (within one stage); overall: the largest of them."""
    worst = 0.0
    stage = np.ones_like(W) if stage is None else stage
    for summary, (ip, _, _) in zip(result.phases, spans):
        rows = phase == ip
        if not np.any(rows):
            continue
        w, st = W[rows], stage[rows]
        inc = np.diff(w)[np.diff(st) == 0] if w.size > 1 else np.zeros(0)
        up = float(inc.max()) if inc.size else 0.0
        summary["lyapunov_start"], summary["lyapunov_end"] = float(w[0]), float(w[-1])
        summary["lyapunov_increase_max"] = up
        summary["lyapunov_increase_total"] = float(inc[inc > 0].sum()) if inc.size else 0.0
        if position_error is not None:  # translation PD (3.7): the CoM's distance to its target (m)
            dist = position_error[rows]
            summary["com_position_error_m"] = {"max": float(dist.max()), "final": float(dist[-1])}
        worst = max(worst, up)
    result.overall["lyapunov_increase_max"] = worst
