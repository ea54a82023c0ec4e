"""What a link's ``<inertial>`` says about the body, in the terms an engineer fixes it in.

Real robot descriptions (CAD exports, xacro macros) carry frame links with zero mass, point
masses, principal moments that miss the triangle inequality by rounding, and round-off negative
moments; Pinocchio accepts all of them. Only what makes the model unusable is refused: a negative
mass here, a singular or indefinite mass matrix after the build (``sms_cli.model.mass_check``).
The rest is accepted and reported; ``strict`` (``sms compile --strict``, ``robot.strict``)
refuses it all, as a lint.

Inertias are about the link CoM in the ``<inertial>`` frame (kg m²), masses in kg.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sms_cli.inertia import inertia_tensor

#: Triangle-inequality violations up to this fraction of the largest principal moment are read as
#: rounding of CAD output (values printed with 2–3 significant digits; the corpora measured in
#: ``benches/bench_urdf_corpus.py`` show 0.2–3 %). Beyond it the moments are likely wrong.
TRIANGLE_RTOL = 0.05
#: Negative principal moments up to this fraction of the largest are floating-point round-off.
ROUNDOFF_RTOL = 1e-6


@dataclass
class InertialFinding:
    """One finding on a link's <inertial>. ``kind`` groups findings in the summary."""

    kind: str  # "negative_mass" (an error) | "massless" | "point_mass" | "rounding" | "nonphysical"
    message: str
    hint: str = ""


def _violation(eig: np.ndarray) -> tuple[float, float]:
    """(most negative moment / largest, triangle-inequality excess / largest) of sorted moments."""
    a, b, c = eig
    scale = max(abs(c), 1e-300)
    return min(a, 0.0) / scale, max(c - a - b, 0.0) / scale


def is_physical(eig: np.ndarray, rtol: float = 0.0) -> bool:
    """Moments of some mass distribution: non-negative and a + b ≥ c, within ``rtol`` of the largest."""
    neg, tri = _violation(np.sort(eig))
    return -neg <= rtol and tri <= rtol


def classify_inertial(link: str, mass: float, moments: list[float]) -> InertialFinding | None:
    """The finding on one link's <inertial> (mass kg, [ixx iyy izz ixy ixz iyz] kg m²), or None."""
    if mass < 0.0:
        return InertialFinding("negative_mass", f"link '{link}' has a negative mass ({mass:g} kg)",
                               "a mass is ≥ 0: check the sign; remove <inertial> for a massless frame link")
    T = inertia_tensor(*moments)
    if mass == 0.0:
        if np.any(T != 0.0):
            return InertialFinding("nonphysical", f"link '{link}' has zero mass but a non-zero inertia",
                                   "give its mass, or zero its inertia if it is only a frame")
        return InertialFinding("massless", f"link '{link}'")
    if not np.any(T != 0.0):
        return InertialFinding("point_mass", f"link '{link}' ({mass:g} kg)")
    eig = np.linalg.eigvalsh(T)
    neg, tri = _violation(eig)
    shown = ", ".join(f"{e:.4g}" for e in eig)
    if -neg <= ROUNDOFF_RTOL and tri == 0.0:
        return None if neg == 0.0 else InertialFinding("rounding", f"link '{link}' (principal moments {shown})")
    if -neg <= ROUNDOFF_RTOL and tri <= TRIANGLE_RTOL:
        return InertialFinding("rounding", f"link '{link}' (a + b < c by {100 * tri:.2g} % of c)")
    what = (f"a negative principal moment ({shown} kg m²)" if -neg > ROUNDOFF_RTOL
            else f"principal moments {shown} kg m² that violate the triangle inequality by {100 * tri:.3g} % of the largest")
    return InertialFinding("nonphysical", f"link '{link}' has {what}: no mass distribution has this inertia",
                           _likely_cause(T))


def _likely_cause(T: np.ndarray) -> str:
    """A hint naming the probable error in a non-physical inertia tensor."""
    flipped = T * np.array([[1, -1, -1], [-1, 1, -1], [-1, -1, 1]])
    if np.any(T - np.diag(np.diag(T))) and is_physical(np.linalg.eigvalsh(flipped), ROUNDOFF_RTOL):
        return ("the products of inertia look sign-flipped: URDF's ixy is −∫xy dm and flipping the sign of "
                "ixy, ixz, iyz makes this inertia physical (some CAD tools export +∫xy dm)")
    return ("the moments are probably mistyped or copied from another part (a digit or an exponent off); "
            "recompute them about the link CoM, or accept them as they are (the model stays usable)")


#: How each accepted kind is summarised (one warning per kind and file).
KIND_SUMMARY = {
    "massless": ("massless links (no mass, no inertia), kept as frames of the body they are fixed to, as Pinocchio does",
                 "nothing to do for frame links (tool0, ee_link, imu…); a moving link needs an <inertial>"),
    "point_mass": ("point masses (mass with zero inertia), accepted as such",
                   "give the inertia about the CoM if the body is not small"),
    "rounding": (f"inertias off the triangle inequality or negative by rounding (within {100 * TRIANGLE_RTOL:g} % of the "
                 f"largest moment, or {ROUNDOFF_RTOL:g} for negative moments), accepted as written",
                 "nothing to do unless you want exact data; sms compile --strict refuses them"),
}


def with_inertials(xml: str, inertials: dict[str, tuple[float, np.ndarray, np.ndarray]]) -> str:
    """The URDF text with each named link's ``<inertial>`` replaced by (mass kg, CoM m in the link
    frame, 3×3 inertia kg m² about the CoM in the link axes): the robot a mission's ``robot.links``
    made, as a file another tool can load (recordings store it)."""
    from lxml import etree

    if not inertials:
        return xml
    root = etree.fromstring(xml.encode("utf-8"))
    for link in root.iter("link"):
        name = link.get("name")
        if name not in inertials:
            continue
        mass, com, I = inertials[name]
        for old in link.findall("inertial"):
            link.remove(old)
        inertial = etree.SubElement(link, "inertial")
        etree.SubElement(inertial, "origin", xyz=" ".join(repr(float(x)) for x in com), rpy="0 0 0")
        etree.SubElement(inertial, "mass", value=repr(float(mass)))
        etree.SubElement(inertial, "inertia", ixx=repr(float(I[0, 0])), iyy=repr(float(I[1, 1])),
                         izz=repr(float(I[2, 2])), ixy=repr(float(I[0, 1])), ixz=repr(float(I[0, 2])),
                         iyz=repr(float(I[1, 2])))
    return etree.tostring(root, encoding="unicode")
