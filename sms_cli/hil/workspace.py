"""How much facility workspace a replay needs: absolute versus relative (Vicariotto 2023 §2.2, the
COMRADE replay of an absolute spin "could be handled only for 12 s", thesis L205).

Both replays are expressed as poses (n, 7) of the moving mock-up in the facility world:

- absolute: the mock-up follows its spacecraft's own motion from its mount,
  ``A(t) = mount · g(0)⁻¹ g(t)`` (g = g1 when the master moves, g2 when the other does);
- relative: the commanded pose g_HW(t) of :func:`sms_cli.hil.poses.hil_commands`.

The excursion of a replay is measured from its own first pose: displacement ``d(t) = p(t) − p(0)`` along
the facility world axes (m) and rotation angle of ``R(0)ᵀ R(t)`` (rad). It leaves the envelope at the first
sample where a half-range (|d_i| > h_i), the radius (|d| > r) or the rotation limit is exceeded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sms_cli.hil.poses import compose, inverse, qconj, qmul, rotation_angle

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class Envelope:
    """Half-ranges (3,) along facility x, y, z (m) or a radius (m); largest rotation (rad)."""

    half_ranges: tuple[float, float, float] | None
    radius: float | None
    rotation: float

    def as_dict(self) -> dict:
        return {"translation_half_ranges_m": list(self.half_ranges) if self.half_ranges else None,
                "radius_m": self.radius, "rotation_deg": float(np.degrees(self.rotation))}


@dataclass
class Excursion:
    """A replay's displacement (n, 3) m and rotation angle (n,) rad from its first pose."""

    t: np.ndarray
    displacement: np.ndarray
    angle: np.ndarray

    @classmethod
    def of(cls, t: np.ndarray, poses: np.ndarray) -> "Excursion":
        d = poses[:, :3] - poses[0, :3]
        return cls(np.asarray(t, float), d, rotation_angle(qmul(qconj(poses[0, 3:]), poses[:, 3:])))

    def outside(self, env: Envelope) -> tuple[np.ndarray, list[str]]:
        """Per sample, whether the replay is outside ``env``; and per sample the first limit broken ('' if none)."""
        if env.half_ranges is not None:
            over = np.abs(self.displacement) > np.asarray(env.half_ranges)
            names = [f"translation {a}" for a in AXES]
        else:
            over = (np.linalg.norm(self.displacement, axis=1) > env.radius)[:, None]
            names = ["radius"]
        over = np.column_stack([over, self.angle > env.rotation])
        names = names + ["rotation"]
        which = [names[int(np.argmax(row))] if row.any() else "" for row in over]
        return over.any(axis=1), which

    def metrics(self, env: Envelope) -> dict:
        """Ranges per axis (m), largest distance (m) and rotation (deg), when it first leaves the envelope."""
        out, which = self.outside(env)
        k = int(np.argmax(out)) if out.any() else None
        return {
            "translation_range_m": dict(zip(AXES, (self.displacement.max(axis=0) - self.displacement.min(axis=0)).tolist())),
            "max_displacement_m": dict(zip(AXES, np.abs(self.displacement).max(axis=0).tolist())),
            "max_distance_m": float(np.linalg.norm(self.displacement, axis=1).max()),
            "max_rotation_deg": float(np.degrees(self.angle.max())),
            "leaves_envelope_s": None if k is None else float(self.t[k]),
            "leaves_by": None if k is None else which[k],
            "inside_fraction": float(1.0 - np.count_nonzero(out) / out.size),
        }


def absolute_replay(g: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """A(t) = mount · g(0)⁻¹ g(t) (n, 7): the mock-up replaying its spacecraft's absolute motion."""
    return compose(np.asarray(mount, float), compose(inverse(g[0]), g))


def compare(t: np.ndarray, absolute: np.ndarray, relative: np.ndarray, env: Envelope) -> tuple[dict, Excursion, Excursion]:
    """Workspace figures of both replays (the ``workspace.json`` content) and their excursions."""
    ea, er = Excursion.of(t, absolute), Excursion.of(t, relative)
    return {"envelope": env.as_dict(), "duration_s": float(t[-1] - t[0]), "samples": int(t.size),
            "absolute": ea.metrics(env), "relative": er.metrics(env)}, ea, er


__all__ = ["Envelope", "Excursion", "absolute_replay", "compare", "AXES"]
