"""One URDF holding both spacecraft, for Foxglove's 3D panel: each robot's links, joints and materials
prefixed with its name (``client/bus``), both roots hung from a ``world`` link by floating joints whose
poses the recording's ``/tf`` gives."""

from __future__ import annotations

from lxml import etree

from sms_cli.formation.plant import prefixed


def pair_urdf(robots: list[tuple[str, str, str]]) -> str:
    """The combined URDF of ``robots`` = [(prefix, urdf text, root link)], in order."""
    out = etree.Element("robot", name="formation")
    etree.SubElement(out, "link", name="world")
    for prefix, text, root in robots:
        tree = etree.fromstring(text.encode() if isinstance(text, str) else text)
        for el in tree:
            if not isinstance(el.tag, str) or el.tag not in ("link", "joint", "material"):
                continue  # comments, transmissions, gazebo tags: not for the viewer
            el.set("name", prefixed(el.get("name"), prefix))
            for ref in el.iter("parent", "child"):
                if ref.get("link") is not None:
                    ref.set("link", prefixed(ref.get("link"), prefix))
            for mat in el.iter("material"):
                if mat is not el and mat.get("name"):
                    mat.set("name", prefixed(mat.get("name"), prefix))
            out.append(el)
        joint = etree.SubElement(out, "joint", name=prefixed("floating", prefix), type="floating")
        etree.SubElement(joint, "parent", link="world")
        etree.SubElement(joint, "child", link=prefixed(root, prefix))
    return etree.tostring(out, pretty_print=True, encoding="unicode")
