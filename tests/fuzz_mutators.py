"""Mutations of the shipped inputs for the fuzz suite (``tests/test_fuzz_inputs.py``) and the fuzz
campaign (``benches/fuzz_campaign.py``): plain functions of a ``random.Random``, so that hypothesis
drives them in tests and a seeded generator drives them in the campaign."""

from __future__ import annotations

import random
import re

#: Replacement values a user (or an attacker) might type for a YAML scalar.
YAML_TOKENS = [".nan", ".inf", "-.inf", "-1", "0", "1e2", "1e400", "-150 kg", "0.2 furlong", "150 m/s", "abc", "''",
               "[]", "{}", "null", "true", "[1, 2]", "[.nan, 0, 0]", "'" + "9" * 300 + "'", "!!python/object:os.system x",
               "*undefined_alias", "&a [*a]", "\"\\x00\"", "1 rpm", "-0.0", "2147483648", "0x10", "1_000"]
#: Replacement values for a URDF numeric attribute.
URDF_TOKENS = ["nine", "", "0x10", "0 0 1 1", "null", "nan", "inf", "-inf", "1e308", "-1", "0", "1e-300", "1,5",
               "1 2", "+", "1e", "\u00a01", "-0"]

_SCALAR_LINE = re.compile(r"^(\s*(?:- )?[A-Za-z_][\w]*:\s*)([^\s#{\[][^#\n]*?)\s*(#.*)?$")
_URDF_NUMBER = re.compile(r'((?:xyz|rpy|value|ixx|iyy|izz|ixy|ixz|iyz|lower|upper|effort|velocity|size|radius|length)=")([^"]*)(")')


def mutate_mission(text: str, rng: random.Random) -> str:
    """A mission text with one or two edits: a scalar replaced, a line dropped or doubled, a key
    renamed, the text cut, a byte inserted, a line indented."""
    lines = text.splitlines()
    for _ in range(rng.randint(1, 2)):
        kind = rng.choice(["scalar", "scalar", "scalar", "drop", "double", "rename", "cut", "byte", "indent"])
        i = rng.randint(0, max(len(lines) - 1, 0))
        if kind == "scalar":
            targets = [k for k, ln in enumerate(lines) if _SCALAR_LINE.match(ln)]
            if targets:
                k = rng.choice(targets)
                lines[k] = _SCALAR_LINE.match(lines[k]).group(1) + rng.choice(YAML_TOKENS)
        elif kind == "drop" and lines:
            del lines[i]
        elif kind == "double" and lines:
            lines.insert(i, lines[i])
        elif kind == "rename" and lines:
            lines[i] = re.sub(r"^(\s*(?:- )?)([A-Za-z_]\w*):", lambda m: m.group(1) + m.group(2) + "x:", lines[i], count=1)
        elif kind == "cut":
            joined = "\n".join(lines)
            lines = joined[: rng.randint(0, len(joined))].splitlines()
        elif kind == "byte" and lines:
            b = rng.choice(["\x00", "\t", "\x1b", "\ufeff", "\udcff", ":", "[", "{", "&", "*", "|", "%"])
            pos = rng.randint(0, len(lines[i]))
            lines[i] = lines[i][:pos] + b + lines[i][pos:]
        elif kind == "indent" and lines:
            lines[i] = " " + lines[i]
    return "\n".join(lines) + "\n"


def mutate_urdf(text: str, rng: random.Random) -> str:
    """A URDF text with one or two edits: a number replaced, a link reference changed, a joint type
    changed, an element dropped, a name duplicated, the text cut."""
    for _ in range(rng.randint(1, 2)):
        kind = rng.choice(["number", "number", "number", "link_ref", "type", "drop", "dup_name", "cut"])
        spots = {"number": list(_URDF_NUMBER.finditer(text)),
                 "link_ref": list(re.finditer(r'<(?:parent|child) link="([^"]*)"', text)),
                 "type": list(re.finditer(r'type="(\w*)"', text)),
                 "drop": list(re.finditer(r"<(?:inertial|inertia|mass|origin|axis|limit)\b[^>]*/?>", text)),
                 "dup_name": list(re.finditer(r'<(?:link|joint) name="([^"]*)"', text))}.get(kind)
        if kind == "cut":
            text = text[: rng.randint(0, len(text))]
            continue
        if not spots:
            continue
        m = rng.choice(spots)
        group = 2 if kind == "number" else 1
        if kind == "number":
            new = rng.choice(URDF_TOKENS)
        elif kind == "link_ref":
            new = rng.choice(re.findall(r'<link name="([^"]*)"', text) + ["nowhere"])
        elif kind == "type":
            new = rng.choice(["fixed", "revolute", "continuous", "prismatic", "floating", "planar", ""])
        elif kind == "dup_name":
            new = rng.choice(re.findall(r'<(?:link|joint) name="([^"]*)"', text))
        else:
            text = text[: m.start()] + text[m.end():]
            continue
        text = text[: m.start(group)] + new + text[m.end(group):]
    return text


def corrupt_bytes(raw: bytes, rng: random.Random, cut: bool = False) -> bytes:
    """``raw`` cut at a random length, or with 1–8 random bytes overwritten."""
    if cut:
        return raw[: rng.randint(0, len(raw))]
    out = bytearray(raw)
    for _ in range(rng.randint(1, 8)):
        out[rng.randrange(len(out))] = rng.randrange(256)
    return bytes(out)
