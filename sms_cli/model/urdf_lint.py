"""URDF lint with line numbers, before Pinocchio sees the file.

Errors (the file is rejected, exit 2): XML syntax, undefined parent/child links, several roots,
a link with two parents, duplicate names, unknown joint types, non-positive mass, inertia not
positive definite or violating the triangle inequality, zero axes.
Warnings (accepted, reported): non-unit axes (normalised), revolute/prismatic joints without
``<limit>`` (accepted as SPART does: unbounded position, no effort/velocity limit).

``lint_urdf`` returns the cleaned XML (axes normalised, missing limits filled with huge
values so that urdfdom accepts it) and a ``UrdfInfo`` describing the tree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from sms_cli.errors import InputError, Location, Problem, Warnings

MOVABLE = {"revolute", "continuous", "prismatic"}
SUPPORTED = MOVABLE | {"fixed"}
UNBOUNDED = 1e10  # stand-in for "no limit" in the cleaned XML; reported as inf
INERTIA_RTOL = 1e-9


@dataclass
class UrdfJoint:
    name: str
    kind: str
    parent: str
    child: str
    axis: np.ndarray
    line: int
    has_limit: bool
    lower: float = -math.inf
    upper: float = math.inf
    effort: float = math.inf
    velocity: float = math.inf


@dataclass
class UrdfInfo:
    """The robot's tree as written in the URDF (before Pinocchio merges fixed joints)."""

    path: Path
    name: str
    root: str
    links: dict[str, int]  # link name -> line
    masses: dict[str, float]  # links with an <inertial>
    joints: dict[str, UrdfJoint]
    xml: str  # cleaned XML given to Pinocchio
    inertials: dict[str, tuple[float, np.ndarray, np.ndarray, list[float]]] = field(default_factory=dict)
    # link -> (mass, origin xyz, origin rpy, [ixx iyy izz ixy ixz iyz]) as written in <inertial>
    children: dict[str, list[str]] = field(default_factory=dict)  # link -> child joints (tree order)

    def movable_joints_in_tree_order(self) -> list[str]:
        """Movable joints, depth-first from the root (the order Pinocchio uses)."""
        out: list[str] = []

        def walk(link: str) -> None:
            for jn in self.children.get(link, []):
                j = self.joints[jn]
                if j.kind in MOVABLE:
                    out.append(jn)
                walk(j.child)

        walk(self.root)
        return out


def _f(text: str | None, default: float = 0.0) -> float:
    if text is None or text.strip() == "":
        return default
    return float(text)


def _vec(text: str | None, default: tuple[float, ...]) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    parts = text.split()
    return np.array([float(p) for p in parts], dtype=float)


def check_inertia(ixx: float, iyy: float, izz: float, ixy: float, ixz: float, iyz: float) -> str | None:
    """Why a rotational inertia (about the CoM) is not physical, or None if it is."""
    tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    eig = np.linalg.eigvalsh(tensor)
    scale = max(abs(eig).max(), 1e-300)
    if eig.min() <= -INERTIA_RTOL * scale or eig.min() <= 0.0 and eig.max() <= 0.0:
        return f"inertia is not positive definite (principal moments {', '.join(f'{e:.6g}' for e in eig)})"
    a, b, c = eig
    tol = INERTIA_RTOL * scale
    if a + b < c - tol:
        return (f"principal moments {a:.6g}, {b:.6g}, {c:.6g} violate the triangle inequality "
                f"({a:.6g} + {b:.6g} < {c:.6g}): no mass distribution has this inertia")
    return None


def lint_urdf(path: Path, warnings: Warnings) -> UrdfInfo:
    """Check a URDF file; raise InputError listing every error, collect warnings, return the tree."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(problems=[Problem(f"cannot read URDF: {exc.strerror or exc}", Location(path),
                                           hint="check robot.urdf in the mission file (relative to the mission file)")]) from None
    try:
        root = etree.fromstring(raw, parser=etree.XMLParser(remove_comments=False, resolve_entities=False))
    except etree.XMLSyntaxError as exc:
        line, col = (exc.position if exc.position else (0, 0))
        raise InputError(problems=[Problem(f"URDF is not well-formed XML: {exc.msg}", Location(path, line, col))]) from None

    problems: list[Problem] = []

    def loc(el) -> Location:
        return Location(path, el.sourceline or 0)

    if root.tag != "robot":
        raise InputError(problems=[Problem(f"root element is <{root.tag}>, expected <robot>", loc(root))])

    links: dict[str, int] = {}
    masses: dict[str, float] = {}
    inertials: dict[str, tuple] = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            problems.append(Problem("<link> without a name", loc(link), hint='add name="..."'))
            continue
        if name in links:
            problems.append(Problem(f"duplicate link name '{name}' (first at line {links[name]})", loc(link)))
            continue
        links[name] = link.sourceline or 0
        inertial = link.find("inertial")
        if inertial is None:
            continue
        mass_el = inertial.find("mass")
        mass = _f(mass_el.get("value") if mass_el is not None else None, 0.0)
        if mass <= 0.0:
            problems.append(Problem(f"link '{name}' has non-positive mass {mass:g} kg", loc(mass_el if mass_el is not None else inertial),
                                    hint="give a positive mass, or remove <inertial> for a massless frame link"))
            continue
        masses[name] = mass
        ine = inertial.find("inertia")
        if ine is None:
            problems.append(Problem(f"link '{name}' has a mass but no <inertia>", loc(inertial),
                                    hint="add <inertia ixx= iyy= izz= ixy= ixz= iyz=/> about the CoM"))
            continue
        vals = [_f(ine.get(k)) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
        org = inertial.find("origin")
        inertials[name] = (mass, _vec(org.get("xyz") if org is not None else None, (0.0, 0.0, 0.0)),
                           _vec(org.get("rpy") if org is not None else None, (0.0, 0.0, 0.0)), vals)
        why = check_inertia(*vals)
        if why:
            problems.append(Problem(f"link '{name}': {why}", loc(ine),
                                    hint="inertia is about the link CoM in the <inertial> frame; check units (kg m^2) and signs of products"))

    joints: dict[str, UrdfJoint] = {}
    parent_of: dict[str, str] = {}
    children: dict[str, list[str]] = {}
    for j in root.findall("joint"):
        name = j.get("name")
        kind = j.get("type", "")
        if not name:
            problems.append(Problem("<joint> without a name", loc(j)))
            continue
        if name in joints:
            problems.append(Problem(f"duplicate joint name '{name}' (first at line {joints[name].line})", loc(j)))
            continue
        if kind not in SUPPORTED:
            hint = ("model the base as the root link (sms adds the free-flyer)" if kind == "floating"
                    else "use revolute, continuous, prismatic or fixed")
            problems.append(Problem(f"joint '{name}' has unsupported type '{kind}'", loc(j), hint=hint))
            continue
        pe, ce = j.find("parent"), j.find("child")
        parent = pe.get("link") if pe is not None else None
        child = ce.get("link") if ce is not None else None
        for role, link_name, el in (("parent", parent, pe), ("child", child, ce)):
            if not link_name:
                problems.append(Problem(f"joint '{name}' has no <{role} link=...>", loc(j)))
            elif link_name not in links:
                import difflib

                close = difflib.get_close_matches(link_name, list(links), n=1)
                problems.append(Problem(f"joint '{name}': {role} link '{link_name}' is not defined", loc(el if el is not None else j),
                                        hint=f"did you mean '{close[0]}'?" if close else "define the <link> or fix the name"))
        if not parent or not child or parent not in links or child not in links:
            continue
        if child in parent_of:
            problems.append(Problem(f"link '{child}' has two parent joints ('{parent_of[child]}' and '{name}')", loc(j),
                                    hint="a URDF is a tree: each link has at most one parent joint"))
            continue
        axis = np.array([1.0, 0.0, 0.0])
        ax_el = j.find("axis")
        if kind in MOVABLE:
            axis = _vec(ax_el.get("xyz") if ax_el is not None else None, (1.0, 0.0, 0.0))
            norm = float(np.linalg.norm(axis)) if axis.size == 3 else 0.0
            if axis.size != 3 or norm < 1e-12:
                problems.append(Problem(f"joint '{name}' has a zero or malformed axis", loc(ax_el if ax_el is not None else j),
                                        hint='give a unit axis, e.g. <axis xyz="0 0 1"/>'))
                continue
            if abs(norm - 1.0) > 1e-9:
                warnings.add(f"joint '{name}' axis {axis.tolist()} has norm {norm:.6g}; normalised", loc(ax_el), "axis",
                             "write a unit axis")
                axis = axis / norm
                ax_el.set("xyz", " ".join(repr(float(a)) for a in axis))
        info = UrdfJoint(name, kind, parent, child, axis, j.sourceline or 0, has_limit=False)
        lim = j.find("limit")
        if kind in ("revolute", "prismatic"):
            if lim is None:
                warnings.add(f"{kind} joint '{name}' has no <limit>: accepted as unbounded, no effort or velocity limit (SPART convention)",
                             loc(j), "limit", "add <limit lower= upper= effort= velocity=/> for realistic analysis")
                lim = etree.SubElement(j, "limit")
                for k, v in (("lower", -UNBOUNDED), ("upper", UNBOUNDED), ("effort", UNBOUNDED), ("velocity", UNBOUNDED)):
                    lim.set(k, repr(v))
            else:
                info.has_limit = True
                info.lower = _f(lim.get("lower"), 0.0)
                info.upper = _f(lim.get("upper"), 0.0)
                if info.lower > info.upper:
                    problems.append(Problem(f"joint '{name}': lower limit {info.lower:g} > upper limit {info.upper:g}", loc(lim)))
        if lim is not None and info.has_limit or (kind == "continuous" and lim is not None):
            eff, vel = _f(lim.get("effort"), 0.0), _f(lim.get("velocity"), 0.0)
            info.effort = eff if eff > 0 else math.inf
            info.velocity = vel if vel > 0 else math.inf
        joints[name] = info
        parent_of[child] = name
        children.setdefault(parent, []).append(name)

    roots = [name for name in links if name not in parent_of]
    if len(roots) > 1:
        problems.append(Problem(f"the URDF has {len(roots)} root links ({', '.join(roots)}); a robot has one base",
                                Location(path, links[roots[1]]),
                                hint="connect every link to the tree with a joint (fixed if rigid)"))
    elif not roots and links:
        problems.append(Problem("the URDF has no root link (the joints form a loop)", Location(path, root.sourceline or 0)))
    if not links:
        problems.append(Problem("the URDF defines no link", loc(root)))

    if problems:
        raise InputError(f"{path}: {len(problems)} problem(s) in the URDF", problems)

    xml = etree.tostring(root, encoding="unicode")
    return UrdfInfo(path, root.get("name", path.stem), roots[0], links, masses, joints, xml, inertials=inertials, children=children)
