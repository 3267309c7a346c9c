"""A URDF read as a data file: its link and joint names, so other files can be checked against it.

A scene and a robot config name links and joints of a URDF (``tool_link``, ``arm_joints``...). A
name misspelt there used to pass every check and fail only when the simulator loaded the robot,
without a line. Read here once, each name is checked where it is written. The URDF is hostile
until checked like any other file: no DTD, no entity, no network; one ``file:line: problem``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlparse

from lxml import etree

from datafile.document import MAX_BYTES
from datafile.errors import DataFileError
from datafile.field import Field

__all__ = ["Urdf", "read_urdf"]


@dataclass(frozen=True)
class Urdf:
    """What other files may name in a URDF."""

    path: Path
    links: frozenset[str]
    joints: dict[str, str]  # name -> type (revolute, prismatic, fixed, ...)

    def check_link(self, field: Field, name: str | None = None) -> None:
        """``name`` (default: ``field``'s text) is a link of this URDF, or ``field`` fails."""
        name = field.text() if name is None else name
        if name not in self.links:
            raise field.fail(
                f"the URDF {self.path.name} has no link {name!r}; its links are {', '.join(sorted(self.links))}"
            )

    def check_joint(self, field: Field, name: str | None = None) -> None:
        """``name`` is a joint of this URDF that moves (not ``fixed``), or ``field`` fails."""
        name = field.text() if name is None else name
        moving = sorted(j for j, kind in self.joints.items() if kind != "fixed")
        if name not in self.joints:
            raise field.fail(
                f"the URDF {self.path.name} has no joint {name!r}; its moving joints are {', '.join(moving)}"
            )
        if self.joints[name] == "fixed":
            raise field.fail(f"joint {name!r} of {self.path.name} is fixed: it cannot be moved")


def _line(element: etree._Element) -> int:
    line = element.sourceline
    return line if isinstance(line, int) else 0


def _mesh_path(urdf: Path, filename: str) -> Path | None:
    """The file a mesh ``filename`` names on this host, or None when only a viewer can resolve it."""
    parsed = urlparse(filename)
    if parsed.scheme == "file":
        return Path(unquote(parsed.path))
    if parsed.scheme:  # package://, http://: resolved by whoever draws the robot, not checked here
        return None
    return (urdf.parent / filename).resolve()


def read_urdf(path: Path) -> Urdf:
    """Parse ``path`` and check that every mesh file it names on this host exists.

    Raises:
        DataFileError: the file cannot be read or parsed, is not a ``<robot>`` with links, or names
            a mesh that is not there; with the line of the problem.
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DataFileError(path, 0, "", f"cannot read the URDF: {exc.strerror}") from None
    if len(data) > MAX_BYTES:
        raise DataFileError(path, 0, "", f"a URDF of {len(data)} bytes is over the limit of {MAX_BYTES}")
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise DataFileError(path, 0, "", "a URDF may not have a DOCTYPE or entities")
    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        line = exc.lineno or 0
        raise DataFileError(path, line, "", f"not valid XML: {exc.msg}") from None
    if root.tag != "robot":
        raise DataFileError(path, _line(root), "", f"the root element must be <robot>, not <{root.tag}>")
    links = frozenset(str(link.get("name")) for link in root.iter("link") if link.get("name"))
    if not links:
        raise DataFileError(path, _line(root), "", "the robot has no <link name=...>")
    joints = {str(j.get("name")): str(j.get("type", "")) for j in root.iter("joint") if j.get("name")}
    for mesh in root.iter("mesh"):
        filename = mesh.get("filename", "")
        file = _mesh_path(path, filename)
        if file is not None and not file.is_file():
            raise DataFileError(path, _line(mesh), "", f"mesh file {filename!r} not found ({file})")
    return Urdf(path, links, joints)
