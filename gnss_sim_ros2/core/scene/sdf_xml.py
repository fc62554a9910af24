"""SDF XML reading as sdformat reads it: lenient parsing, element helpers, ``<pose>``.

sdformat parses with TinyXML2, which accepts things a strict XML parser refuses and which real
worlds contain (gz-sim's own ``empty.sdf``, ``default.sdf``, ``sensors.sdf``):

* ``--`` inside a comment (XML 1.0 section 2.5 forbids it): each such comment is rewritten with the
  hyphens separated, on the same lines, before parsing;
* element or attribute prefixes without an ``xmlns:`` declaration (``<gz:system ...>``): a
  declaration ``xmlns:PREFIX="urn:gnss_sim:undeclared:PREFIX"`` is added to the root element, so the
  elements parse as custom elements (which the loader ignores, as Gazebo's geometry reader does);
* element and attribute names with ``::`` (``<gz::system_priority>`` in gz-sim's ``sensors.sdf``): the
  first ``::`` becomes the prefix colon (``gz:system_priority``), then declared as above.

The rewrites keep line numbers, so errors still name the file's own lines.  Anything else that is
not well-formed XML is an :class:`SdfError` naming the file and line.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

#: namespace given to prefixes used without a declaration
UNDECLARED_NS = "urn:gnss_sim:undeclared:"


class SdfError(ValueError):
    """Malformed or unsupported SDF; the message names file, line and element."""


def where(el, file) -> str:
    """``file:line: <tag name='...'>`` for messages."""
    line = getattr(el, "sourceline", None)
    name = el.get("name")
    tag = local(el.tag)
    desc = f"<{tag} name={name!r}>" if name is not None else f"<{tag}>"
    return f"{file}:{line}: {desc}" if line else f"{file}: {desc}"


def local(tag) -> str:
    if not isinstance(tag, str):
        return ""
    return tag.rsplit("}", 1)[-1]


def ns(tag) -> str:
    if isinstance(tag, str) and tag.startswith("{"):
        return tag[1:].split("}", 1)[0]
    return ""


def children(el, tag: str):
    return [c for c in el if isinstance(c.tag, str) and c.tag == tag]


def child(el, tag: str):
    for c in el:
        if isinstance(c.tag, str) and c.tag == tag:
            return c
    return None


def text(el, default: str = "") -> str:
    return (el.text or "").strip() if el is not None else default


def floats(el, file, n: int | tuple[int, ...], what: str | None = None) -> list[float]:
    words = (el.text or "").split()
    counts = (n,) if isinstance(n, int) else n
    try:
        vals = [float(t) for t in words]
    except ValueError as exc:
        raise SdfError(f"{where(el, file)}: {what or local(el.tag)} must be numbers, got {el.text!r}") from exc
    if len(vals) not in counts:
        raise SdfError(f"{where(el, file)}: {what or local(el.tag)} needs {' or '.join(map(str, counts))} "
                       f"numbers, got {len(vals)} ({el.text!r})")
    if not all(math.isfinite(v) for v in vals):
        raise SdfError(f"{where(el, file)}: non-finite value in {el.text!r}")
    return vals


def child_floats(el, tag, file, n, default=None) -> list[float]:
    c = child(el, tag)
    if c is None:
        if default is not None:
            return list(default)
        raise SdfError(f"{where(el, file)}: missing <{tag}>")
    return floats(c, file, n)


def truthy(value) -> bool:
    """SDF booleans: ``true``/``1`` (sdformat accepts both)."""
    return str(value).strip().lower() in ("1", "true")


def euler_matrix(roll, pitch, yaw) -> np.ndarray:
    """SDF pose rotation: R = Rz(yaw) Ry(pitch) Rx(roll) (sdformat.org, pose spec)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def parse_pose(el, file="<sdf>") -> tuple[np.ndarray, str | None]:
    """``<pose>`` -> (4x4 homogeneous transform, relative_to or None)."""
    if el is None:
        return np.eye(4), None
    T = np.eye(4)
    rel = el.get("relative_to")
    if not (el.text or "").strip():
        return T, rel or None
    fmt = (el.get("rotation_format") or "euler_rpy").strip()
    if fmt == "quat_xyzw":
        x, y, z, qx, qy, qz, qw = floats(el, file, 7, "pose (quat_xyzw)")
        q = np.array([qw, qx, qy, qz])
        nq = np.linalg.norm(q)
        if nq == 0:
            raise SdfError(f"{where(el, file)}: zero quaternion")
        w, a, b, c = q / nq
        R = np.array([[1 - 2 * (b * b + c * c), 2 * (a * b - c * w), 2 * (a * c + b * w)],
                      [2 * (a * b + c * w), 1 - 2 * (a * a + c * c), 2 * (b * c - a * w)],
                      [2 * (a * c - b * w), 2 * (b * c + a * w), 1 - 2 * (a * a + b * b)]])
    elif fmt == "euler_rpy":
        x, y, z, r, p, yw = floats(el, file, 6, "pose")
        if truthy(el.get("degrees", "false")):
            r, p, yw = math.radians(r), math.radians(p), math.radians(yw)
        R = euler_matrix(r, p, yw)
    else:
        raise SdfError(f"{where(el, file)}: unknown rotation_format {fmt!r} (euler_rpy or quat_xyzw)")
    T[:3, :3] = R
    T[:3, 3] = (x, y, z)
    return T, rel or None


_COMMENT = re.compile(r"<!--(.*?)-->", re.S)
_PREFIX_USE = re.compile(r"</?([A-Za-z_][\w.-]*):[A-Za-z_]|\s([A-Za-z_][\w.-]*):[A-Za-z_][\w.-]*\s*=")
_PREFIX_DECL = re.compile(r"xmlns:([A-Za-z_][\w.-]*)\s*=")
_ROOT_START = re.compile(r"<(?![?!])[A-Za-z_][\w.:-]*")
# a start or end tag (quoted attribute values may hold ">"), and in its attributes a quoted value (kept) or a
# ``PREFIX::name`` attribute name
_TAG = re.compile(r"<(/?)([A-Za-z_][\w.:-]*)((?:[^>\"']|\"[^\"]*\"|'[^']*')*)>")
_ATTR_DOUBLE_COLON = re.compile(r"(\"[^\"]*\"|'[^']*')|(\s)([A-Za-z_][\w.-]*::[\w.:-]*)(?=\s*=)")


def _fix_comment(m: re.Match) -> str:
    body = m.group(1)
    while "--" in body:
        body = body.replace("--", "- -")
    if body.endswith("-"):
        body += " "
    return f"<!--{body}-->"


def _fix_double_colon_name(name: str) -> str:
    """``gz::system_priority`` -> ``gz:system_priority`` (a prefixed name XML accepts; further ``::`` -> ``__``)."""
    head, _, rest = name.partition("::")
    return f"{head}:{rest.replace('::', '__')}"


def _fix_tag_names(m: re.Match) -> str:
    """One start or end tag with its ``PREFIX::name`` element and attribute names made ``PREFIX:name``."""
    slash, name, attrs = m.group(1), m.group(2), m.group(3)
    if "::" in name:
        name = _fix_double_colon_name(name)
    if "::" in attrs:
        attrs = _ATTR_DOUBLE_COLON.sub(
            lambda a: a.group(1) or f"{a.group(2)}{_fix_double_colon_name(a.group(3))}", attrs)
    return f"<{slash}{name}{attrs}>"


def lenient_xml_text(source: str) -> str:
    """The TinyXML2 leniencies (module docstring) applied to an XML text; line numbers unchanged."""
    fixed = _COMMENT.sub(_fix_comment, source)
    if "::" in fixed:
        fixed = _TAG.sub(_fix_tag_names, fixed)
    body = _COMMENT.sub("", fixed)
    used = {a or b for a, b in _PREFIX_USE.findall(body)} - {"xml", "xmlns"}
    missing = sorted(used - set(_PREFIX_DECL.findall(body)))
    if missing:
        m = _ROOT_START.search(fixed, _first_element_pos(fixed))
        if m is not None:
            decl = "".join(f' xmlns:{p}="{UNDECLARED_NS}{p}"' for p in missing)
            fixed = fixed[:m.end()] + decl + fixed[m.end():]
    return fixed


def _first_element_pos(src: str) -> int:
    """Offset of the root element's start tag (after the declaration, comments and PIs)."""
    pos = 0
    while True:
        i = src.find("<", pos)
        if i < 0:
            return len(src)
        if src.startswith("<!--", i):
            pos = src.find("-->", i) + 3
        elif src.startswith("<?", i) or src.startswith("<!", i):
            pos = src.find(">", i) + 1
        else:
            return i
        if pos <= 2:
            return len(src)


def parse_xml(path: Path):
    """Root element of an SDF (or model.config) file, parsed as sdformat does (module docstring)."""
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise SdfError(f"{path}: cannot read: {exc}") from exc
    from lxml import etree  # here: the commands that take --allow-partial import this module for its help text

    parser = etree.XMLParser(remove_comments=True, remove_pis=True)
    try:
        return etree.fromstring(raw, parser, base_url=str(path))
    except etree.XMLSyntaxError as first:
        try:
            src = raw.decode("utf-8")
        except UnicodeDecodeError:
            src = raw.decode("latin-1")
        src = re.sub(r"^\s*<\?xml[^>]*\?>", lambda m: "\n" * m.group(0).count("\n"), src, count=1)
        try:
            return etree.fromstring(lenient_xml_text(src), parser, base_url=str(path))
        except etree.XMLSyntaxError as exc:
            raise SdfError(f"{path}: malformed SDF/XML: {exc}") from first
