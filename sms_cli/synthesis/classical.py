"""Classical gain synthesis: per-axis PD, LQR (Riccati), sliding-mode gains.

Every axis is a double integrator J ë = u (J in kg m² or kg, e in rad or m, u in N m or N).

* PD: u = −K_p e − K_d ė with K_p = J_w ω_n², K_d = 2ζω_n J_w on the worst-case (largest)
  inertia J_w over the workspace: for J ≤ J_w the same gains give ω_n(J) = √(K_p/J) ≥ ω_n and
  ζ(J) = K_d/(2√(K_p J)) ≥ ζ, so the requested bandwidth and damping are floors everywhere.
* LQR: the continuous Riccati equation (scipy ``solve_continuous_are``), K = R⁻¹BᵀP.
* Sliding mode, Caldera 2019 (3.17) first-order law u = … − c J tanh(μσ), σ = ė + λe: the surface
  is reached and kept when c J_min ≥ margin · τ_d,max (disturbance torque bound); μ is chosen so
  that the linearised surface dynamics σ̇ = −cμσ are 5× faster than the surface pole λ.
* Twisting, Ruggiero 2020 (3.14)/(4.6): with |σ̈_{u=0}| ≤ C and K_m ≤ ∂σ̈/∂u ≤ K_M, the gains
  r1 > r2 > 0 converge when K_m(r1 + r2) − C > K_M(r1 − r2) + C and K_m(r1 − r2) > C.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sms_cli.errors import NumericalError


@dataclass
class PdGains:
    """Torque gains per axis (N m/rad, N m s/rad) and the range of (ω_n, ζ) over [J_min, J_w]."""

    kp: np.ndarray
    kd: np.ndarray
    inertia_worst: np.ndarray
    omega_n_range: tuple[np.ndarray, np.ndarray]
    zeta_range: tuple[np.ndarray, np.ndarray]


def pd_gains(inertia_worst, bandwidth: float, damping: float, inertia_min=None) -> PdGains:
    """PD gains from bandwidth ω_n (rad/s) and damping ζ on the worst-case inertia per axis."""
    Jw = np.atleast_1d(np.asarray(inertia_worst, dtype=float))
    if np.any(Jw <= 0):
        raise NumericalError("PD synthesis: the worst-case inertia must be positive on every axis")
    Jm = Jw if inertia_min is None else np.atleast_1d(np.asarray(inertia_min, dtype=float))
    kp = Jw * bandwidth**2
    kd = 2.0 * damping * bandwidth * Jw
    wn = lambda J: np.sqrt(kp / J)  # noqa: E731
    ze = lambda J: kd / (2.0 * np.sqrt(kp * J))  # noqa: E731
    return PdGains(kp, kd, Jw, (wn(Jw), wn(Jm)), (ze(Jw), ze(Jm)))


def lqr(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K, P with u = −Kx minimising ∫(xᵀQx + uᵀRu): AᵀP + PA − PBR⁻¹BᵀP + Q = 0."""
    from scipy.linalg import solve_continuous_are

    try:
        P = solve_continuous_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise NumericalError(f"LQR: the Riccati equation has no stabilising solution ({exc}); "
                             "check that (A, B) is stabilisable and Q, R are positive") from exc
    K = np.linalg.solve(R, B.T @ P)
    return K, P


def axis_lqr(inertia: float, q_position: float, q_velocity: float, r_effort: float) -> tuple[float, float]:
    """Torque gains (k_p, k_d) of the LQR of J ë = u with cost ∫(q_p e² + q_v ė² + r u²)."""
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0 / inertia]])
    K, _ = lqr(A, B, np.diag([q_position, q_velocity]), np.array([[r_effort]]))
    return float(K[0, 0]), float(K[0, 1])


@dataclass
class SmcGains:
    """First-order SMC (Caldera 2019 (3.17) base / (4.15) arm): surface slope λ (1/s), switching
    gain c (rad/s², multiplies J), smoothing μ (s/rad)."""

    slope: np.ndarray
    c: np.ndarray
    mu: np.ndarray
    disturbance_bound: np.ndarray


def smc_gains(inertia_min, disturbance_bound, surface_slope: float, margin: float = 1.5) -> SmcGains:
    """c J_min ≥ margin · τ_d,max per axis; μ = 5λ/c (boundary-layer bandwidth 5λ)."""
    Jm = np.atleast_1d(np.asarray(inertia_min, dtype=float))
    td = np.broadcast_to(np.asarray(disturbance_bound, dtype=float), Jm.shape).copy()
    c = margin * np.maximum(td, 1e-12) / Jm
    mu = 5.0 * surface_slope / c
    return SmcGains(np.full(Jm.shape, surface_slope), c, mu, td)


def twisting_ok(C: float, Km: float, KM: float, r1: float, r2: float) -> bool:
    """Ruggiero 2020 (3.14)/(4.6) convergence conditions of the twisting algorithm."""
    return bool(Km * (r1 + r2) - C > KM * (r1 - r2) + C and Km * (r1 - r2) > C and r1 > r2 > 0)


def twisting_gains(C: float, Km: float, KM: float, margin: float = 1.5) -> tuple[float, float]:
    """r1, r2 meeting (4.6) with a margin: r1 − r2 = margin·C/K_m,
    r1 + r2 = margin·(K_M(r1 − r2) + 2C)/K_m."""
    if Km <= 0 or KM < Km:
        raise NumericalError(f"twisting gains: need 0 < K_m ≤ K_M (got K_m={Km:g}, K_M={KM:g})")
    d = margin * C / Km
    s = margin * (KM * d + 2 * C) / Km
    return (s + d) / 2, (s - d) / 2
