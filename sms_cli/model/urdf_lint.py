"""URDF lint with line numbers, before Pinocchio sees the file.

Errors (the file is rejected, exit 2): XML syntax, a number that is not a finite decimal
(``sms_cli.model.urdf_numbers``), undefined parent/child links, several roots, a link with two
parents, links cut off from the base (a loop of joints), duplicate names, unknown joint types, a
negative mass, zero axes.
Accepted and reported (``sms_cli.model.urdf_inertia``): massless frame links, point masses,
inertias off the triangle inequality or negative by rounding, non-physical inertias (with the
likely cause); with ``strict`` these are errors, as a lint. Also warned: non-unit axes
(normalised), revolute/prismatic joints without ``<limit>`` (accepted as SPART does: unbounded
position, no effort/velocity limit). Whether the assembled model is usable (mass matrix positive
definite) is checked after the build, in ``sms_cli.model.mass_check``.

``lint_urdf`` returns the cleaned XML (axes normalised, missing limits filled with huge
values so that urdfdom accepts it) and a ``UrdfInfo`` describing the tree.
"""
from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from sms_cli.errors import InputError, Location, Problem, Warnings
from sms_cli.inputs import read_input_bytes
from sms_cli.model.urdf_inertia import KIND_SUMMARY, classify_inertial
from sms_cli.model.urdf_numbers import check_numbers, number, vector

MOVABLE = {"revolute", "continuous", "prismatic"}
SUPPORTED = MOVABLE | {"fixed"}
UNBOUNDED = 1e10  # stand-in for "no limit" in the cleaned XML; reported as inf


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


def _xml_message(msg: str) -> str:
    """libxml2's message without its function name ("xmlParseEntityRef: ") and repeated position."""
    msg = re.sub(r"^xml\w+: ", "", msg or "syntax error")
    return re.sub(r", line \d+, column \d+$", "", msg)


def _read_xml(path: Path, where: Location | None):
    """The parsed <robot> element of a URDF file (InputError with the line on syntax errors)."""
    raw = read_input_bytes(path, "URDF", where)  # a regular file of at most 16 MiB: no FIFO, device or symlink loop
    try:
        root = etree.fromstring(raw, parser=etree.XMLParser(remove_comments=False, resolve_entities=False, huge_tree=False))
    except etree.XMLSyntaxError as exc:
        line, col = (exc.position if exc.position else (0, 0))
        raise InputError(problems=[Problem(f"URDF is not well-formed XML: {_xml_message(exc.msg)}", Location(path, line, col),
                                           hint="fix the XML at that line (an editor with XML checking shows it)")]) from None
    if root.tag != "robot":
        raise InputError(problems=[Problem(f"root element is <{root.tag}>, expected <robot>", Location(path, root.sourceline or 0))])
    return root


def _lint_inertials(link, name: str, loc, problems: list[Problem], found: dict[str, list]) -> tuple | None:
    """(mass, origin xyz, origin rpy, moments) of a link's <inertial>, classifying what it says."""
    inertial = link.find("inertial")
    if inertial is None:
        return None
    mass_el, ine, org = inertial.find("mass"), inertial.find("inertia"), inertial.find("origin")
    mass = number(mass_el, "value", 0.0)
    moments = [number(ine, k, 0.0) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
    finding = classify_inertial(name, mass, moments)
    if finding is not None:
        where = loc(ine if ine is not None and finding.kind not in ("negative_mass", "massless") else (mass_el if mass_el is not None else inertial))
        if finding.kind == "negative_mass":
            problems.append(Problem(finding.message, where, hint=finding.hint))
            return None
        found.setdefault(finding.kind, []).append((finding, where))
    return (mass, np.array(vector(org, "xyz", (0.0, 0.0, 0.0))), np.array(vector(org, "rpy", (0.0, 0.0, 0.0))), moments)


def _report_inertials(found: dict[str, list], warnings: Warnings) -> None:
    """One warning per accepted kind (links listed with lines), one per non-physical inertia."""
    for kind, items in found.items():
        if kind == "nonphysical":
            for finding, where in items:
                warnings.add(finding.message, where, "inertial", finding.hint, lint=True)
            continue
        head, hint = KIND_SUMMARY[kind]
        names = [f"{f.message} (line {w.line})" for f, w in items[:6]]
        more = f" and {len(items) - 6} more" if len(items) > 6 else ""
        warnings.add(f"{len(items)} {head}: {', '.join(names)}{more}", items[0][1], "inertial", hint, lint=True)


def _unreachable(root_link: str, links: dict[str, int], children: dict[str, list[str]], joints: dict) -> list[str]:
    """Links that no chain of joints connects to the root link (they sit on a loop of joints)."""
    seen, stack = {root_link}, [root_link]
    while stack:
        for jn in children.get(stack.pop(), []):
            child = joints[jn].child
            if child not in seen:
                seen.add(child)
                stack.append(child)
    return [name for name in links if name not in seen]


def lint_urdf(path: Path, warnings: Warnings, where: Location | None = None) -> UrdfInfo:
    """Check a URDF file; raise InputError listing every error, collect warnings, return the tree.

    ``where`` is the place that named the file (the mission's ``robot.urdf``), for read errors."""
    path = Path(path)
    root = _read_xml(path, where)
    problems: list[Problem] = []

    def loc(el) -> Location:
        return Location(path, el.sourceline or 0)

    check_numbers(root, path, problems, warnings)

    links: dict[str, int] = {}
    masses: dict[str, float] = {}
    inertials: dict[str, tuple] = {}
    found: dict[str, list] = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            problems.append(Problem("<link> without a name", loc(link), hint='add name="..."'))
            continue
        if name in links:
            problems.append(Problem(f"duplicate link name '{name}' (first at line {links[name]})", loc(link)))
            continue
        links[name] = link.sourceline or 0
        data = _lint_inertials(link, name, loc, problems, found)
        if data is not None:
            inertials[name] = data
            if data[0] > 0.0:
                masses[name] = data[0]
    _report_inertials(found, warnings)

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
                close = difflib.get_close_matches(link_name, list(links), n=1)
                problems.append(Problem(f"joint '{name}': {role} link '{link_name}' is not defined", loc(el if el is not None else j),
                                        hint=f"did you mean '{close[0]}'?" if close else "define the <link> or fix the name"))
        if not parent or not child or parent not in links or child not in links:
            continue
        if child in parent_of:
            problems.append(Problem(f"link '{child}' has two parent joints ('{parent_of[child]}' and '{name}')", loc(j),
                                    hint="a URDF is a tree: each link has at most one parent joint"))
            continue
        if child == parent:
            problems.append(Problem(f"joint '{name}' connects link '{child}' to itself", loc(j)))
            continue
        axis = np.array([1.0, 0.0, 0.0])
        ax_el = j.find("axis")
        if kind in MOVABLE:
            axis = np.array(vector(ax_el, "xyz", (1.0, 0.0, 0.0)))
            norm = float(np.linalg.norm(axis))
            if norm < 1e-12:
                problems.append(Problem(f"joint '{name}' has a zero axis", loc(ax_el if ax_el is not None else j),
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
                info.lower = number(lim, "lower", 0.0)
                info.upper = number(lim, "upper", 0.0)
                if info.lower > info.upper:
                    problems.append(Problem(f"joint '{name}': lower limit {info.lower:g} > upper limit {info.upper:g}", loc(lim),
                                            hint="swap them"))
        if lim is not None and info.has_limit or (kind == "continuous" and lim is not None):
            eff, vel = number(lim, "effort", 0.0), number(lim, "velocity", 0.0)
            info.effort = eff if 0 < eff < UNBOUNDED else math.inf
            info.velocity = vel if 0 < vel < UNBOUNDED else math.inf
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
    elif roots:
        cut = _unreachable(roots[0], links, children, joints)
        if cut:
            loop = [jn for jn, jt in joints.items() if jt.child in cut]
            problems.append(Problem(f"links {', '.join(cut)} are not connected to the base '{roots[0]}': "
                                    f"joints {', '.join(loop)} form a loop", Location(path, links[cut[0]]),
                                    hint="a URDF is a tree: give one of these links its parent in the tree"))
    if not links:
        problems.append(Problem("the URDF defines no link", loc(root)))

    if problems:
        raise InputError(f"{path}: {len(problems)} problem(s) in the URDF", problems)

    xml = etree.tostring(root, encoding="unicode")
    return UrdfInfo(path, root.get("name", path.stem), roots[0], links, masses, joints, xml, inertials=inertials, children=children)
