"""The files a URDF's shapes name (meshes, textures), found the way ROS finds them, for pybullet. Pure logic: the
caller passes how to find a ROS package.

pybullet resolves a `package://pkg/path` URI only relative to the URDF's own folder, and refuses the whole URDF
when a collision mesh is missing. ROS resolves it through the package path (rospack). `resolve_shapes` rewrites
every filename to an absolute path found either way, and drops the <visual> or <collision> whose mesh is nowhere:
the physics takes masses and inertias from <inertial> and has no contacts, so only pictures lose that shape.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

from sim.robots.urdf_model import urdf_root

__all__ = ["PACKAGE_SCHEME", "FILE_SCHEME", "resolve_filename", "resolve_shapes", "without_shapes"]

PACKAGE_SCHEME = "package://"
FILE_SCHEME = "file://"


def resolve_filename(filename: str, urdf_dir: Path, find_package: Callable[[str], Path | None]) -> Path | None:
    """The existing file `filename` names (package://, file:// or a path relative to the URDF), or None."""
    candidates: list[Path] = []
    if filename.startswith(PACKAGE_SCHEME):
        package, _, rest = filename[len(PACKAGE_SCHEME) :].partition("/")
        found = find_package(package)
        if found is not None:
            candidates.append(found / rest)
        candidates += [urdf_dir / package / rest, urdf_dir / rest]  # pybullet's guesses, beside the URDF
        candidates += [parent / package / rest for parent in urdf_dir.parents]  # a description package above it
    elif filename.startswith(FILE_SCHEME):
        candidates.append(Path(filename[len(FILE_SCHEME) :]))
    else:
        path = Path(filename)
        candidates.append(path if path.is_absolute() else urdf_dir / path)
    return next((candidate.resolve() for candidate in candidates if candidate.is_file()), None)


def _resolve(
    element: ET.Element, urdf_dir: Path, find_package: Callable[[str], Path | None], missing: list[str]
) -> bool:
    """Make `element`'s filename absolute; False (and the name noted in `missing`) when the file is nowhere."""
    filename = element.get("filename", "")
    found = resolve_filename(filename, urdf_dir, find_package)
    if found is None:
        missing.append(filename)
        return False
    element.set("filename", str(found))
    return True


def resolve_shapes(urdf_text: str, urdf_dir: Path, find_package: Callable[[str], Path | None]) -> tuple[str, list[str]]:
    """(URDF text with every mesh and texture filename absolute, the filenames found nowhere). The <visual> or
    <collision> holding a missing mesh is dropped, and so is a missing <texture>."""
    root = urdf_root(urdf_text)
    missing: list[str] = []
    for link in root.findall("link"):
        for shape in link.findall("visual") + link.findall("collision"):
            mesh = shape.find("geometry/mesh")
            if mesh is not None and mesh.get("filename") and not _resolve(mesh, urdf_dir, find_package, missing):
                link.remove(shape)
    for parent in root.iter():
        for texture in parent.findall("texture"):
            if not _resolve(texture, urdf_dir, find_package, missing):
                parent.remove(texture)
    return ET.tostring(root, encoding="unicode"), missing


def without_shapes(urdf_text: str) -> str:
    """The URDF with no <visual> and no <collision>: what the dynamics need, loaded in milliseconds (pybullet parses
    every mesh file a shape names, even when told to ignore the shapes: 0.3 s for the Panda)."""
    root = urdf_root(urdf_text)
    for link in root.findall("link"):
        for shape in link.findall("visual") + link.findall("collision"):
            link.remove(shape)
    return ET.tostring(root, encoding="unicode")
