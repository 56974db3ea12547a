"""Example arms written from parameters, each a URDF with its meshes beside it and nothing else (no YAML), for the
tests and the benchmarks to run the study on and for anyone trying the toolkit on an arm other than the Panda:

- STUDY_ARMS, written by `write_arm` from an ArmDesign: different sizes and joint counts (6 and 7), one with a
  two-finger gripper and a fixed tool frame, one whose links' meshes overlap at the joints (STL collision meshes, OBJ
  and COLLADA visuals), one mounted high on a pedestal;
- LAB_ARMS, written by `write_lab_arm` from their Parts as a lab's ROS description package would hold them: a UR5
  from Universal Robots' published DH parameters, a five-joint desktop arm and a SCARA.

`write_example_arm` writes either kind by name.

One concern, and a long one: arms written from parameters. The lab arms' Parts, one table an arm, are nearly half of it;
both kinds share the mesh writers (STL, OBJ, COLLADA) and `write_example_arm`.
"""

from __future__ import annotations

import dataclasses
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "LAB_ARMS",
    "LAB_ARM_EE_LINKS",
    "STUDY_ARMS",
    "ArmDesign",
    "Part",
    "with_effort",
    "write_arm",
    "write_example_arm",
    "write_lab_arm",
]


@dataclass(frozen=True)
class ArmDesign:
    name: str
    joints: int  # 6 or 7
    scale: float  # lengths, against a Panda-sized arm at 1
    gripper: bool = False  # a hand with two prismatic fingers and a fixed tool frame between their tips
    overlapping_meshes: bool = False  # links as meshes that reach past their joints into their neighbours
    pedestal: float = 0.0  # m of column under the arm, part of its base link (mounted high)


STUDY_ARMS = (
    ArmDesign("small_gripper_arm", 6, 0.85, gripper=True),
    ArmDesign("meshed_arm7", 7, 1.0, overlapping_meshes=True),
    ArmDesign("pedestal_arm", 6, 1.1, pedestal=0.4),
)


def _inertial(mass: float, length: float) -> str:
    inertia = mass * length**2 / 12 + 1e-4
    return (
        f'<inertial><origin xyz="0 0 {length / 2:.4f}"/><mass value="{mass:.3f}"/>'
        f'<inertia ixx="{inertia:.6f}" ixy="0" ixz="0" iyy="{inertia:.6f}" iyz="0" izz="{inertia:.6f}"/></inertial>'
    )


def _box_triangles(low: np.ndarray, high: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]  # outward
    triangles = []
    for a, b, c, d in faces:
        triangles += [(corners[a], corners[b], corners[c]), (corners[a], corners[c], corners[d])]
    return triangles


def _write_stl(path: Path, low: np.ndarray, high: np.ndarray) -> None:
    """A binary STL (what pybullet reads; it skips ASCII ones)."""
    triangles = _box_triangles(low, high)
    data = bytearray(b"box".ljust(80, b" ")) + struct.pack("<I", len(triangles))
    for a, b, c in triangles:
        normal = np.cross(b - a, c - a)
        data += struct.pack("<12fH", *(normal / np.linalg.norm(normal)), *a, *b, *c, 0)
    path.write_bytes(bytes(data))


def _write_obj(path: Path, low: np.ndarray, high: np.ndarray) -> None:
    triangles = _box_triangles(low, high)
    lines = [f"v {v[0]:.6f} {v[1]:.6f} {v[2]:.6f}" for triangle in triangles for v in triangle]
    lines += [f"f {3 * k + 1} {3 * k + 2} {3 * k + 3}" for k in range(len(triangles))]
    path.write_text("\n".join(lines) + "\n")


def _write_dae(path: Path, low: np.ndarray, high: np.ndarray) -> None:
    triangles = _box_triangles(low, high)
    positions = " ".join(f"{c:.6f}" for triangle in triangles for v in triangle for c in v)
    indices = " ".join(str(k) for k in range(3 * len(triangles)))
    path.write_text(
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">'
        '<asset><unit meter="1"/><up_axis>Z_UP</up_axis></asset>'
        '<library_geometries><geometry id="box"><mesh>'
        f'<source id="box-pos"><float_array id="box-pos-array" count="{9 * len(triangles)}">{positions}</float_array>'
        f'<technique_common><accessor source="#box-pos-array" count="{3 * len(triangles)}" stride="3">'
        '<param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>'
        "</accessor></technique_common></source>"
        '<vertices id="box-vtx"><input semantic="POSITION" source="#box-pos"/></vertices>'
        f'<triangles count="{len(triangles)}"><input semantic="VERTEX" source="#box-vtx" offset="0"/>'
        f"<p>{indices}</p></triangles></mesh></geometry></library_geometries>"
        '<library_visual_scenes><visual_scene id="scene"><node id="box-node">'
        '<instance_geometry url="#box"/></node></visual_scene></library_visual_scenes>'
        '<scene><instance_visual_scene url="#scene"/></scene></COLLADA>\n'
    )


def _shapes(design: ArmDesign, folder: Path, link: str, length: float, radius: float, index: int) -> str:
    """The link's visual and collision: a cylinder along its z from 0 to `length`; or, with overlapping meshes, a
    box mesh reaching `radius` past both ends (STL collision; OBJ or COLLADA visual, in turn)."""
    if not design.overlapping_meshes:
        cylinder = (
            f'<origin xyz="0 0 {length / 2:.4f}"/>'
            f'<geometry><cylinder radius="{radius:.4f}" length="{length:.4f}"/></geometry>'
        )
        return f"<visual>{cylinder}</visual><collision>{cylinder}</collision>"
    low, high = np.array([-radius, -radius, -radius]), np.array([radius, radius, length + radius])
    (folder / "meshes").mkdir(exist_ok=True)
    _write_stl(folder / "meshes" / f"{link}.stl", low, high)
    visual = f"{link}.{'dae' if index % 2 else 'obj'}"
    (_write_dae if index % 2 else _write_obj)(folder / "meshes" / visual, low, high)
    return (
        f'<visual><geometry><mesh filename="meshes/{visual}"/></geometry></visual>'
        f'<collision><geometry><mesh filename="meshes/{link}.stl"/></geometry></collision>'
    )


def _joint(name: str, kind: str, parent: str, child: str, z: float, axis: str, limit: str = "") -> str:
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 {z:.4f}" rpy="0 0 0"/><axis xyz="{axis}"/>{limit}</joint>'
    )


def arm_urdf(design: ArmDesign, folder: Path) -> str:
    """The URDF of `design`, its meshes (if any) written into `folder`/meshes."""
    s = design.scale
    # (axis, length of the link after the joint, radius, joint range): the elbow and the wrist's pitch bend one way
    # far, like a Panda's; the rolls and the shoulder turn either way
    if design.joints == 6:
        chain = [("0 0 1", 0.15), ("0 1 0", 0.40), ("0 1 0", 0.20), ("0 0 1", 0.15), ("0 1 0", 0.08), ("0 0 1", 0.04)]
    else:
        chain = [
            ("0 0 1", 0.15),
            ("0 1 0", 0.20),
            ("0 0 1", 0.20),
            ("0 1 0", 0.20),
            ("0 0 1", 0.15),
            ("0 1 0", 0.08),
            ("0 0 1", 0.04),
        ]
    base_height = 0.10 * s + design.pedestal
    links = [
        f'<link name="base_link">{_inertial(5.0, base_height)}'
        f"{_shapes(design, folder, 'base_link', base_height, 0.09 * s, 0)}</link>"
    ]
    joints = []
    parent, offset = "base_link", base_height
    pitch_joints = 0
    for k, (axis, length) in enumerate(chain, start=1):
        child = f"link{k}"
        radius = (0.06 if k < 4 else 0.045) * s
        links.append(
            f'<link name="{child}">{_inertial(3.0 if k < 4 else 1.0, length * s)}'
            f"{_shapes(design, folder, child, length * s, radius, k)}</link>"
        )
        if axis == "0 1 0":
            pitch_joints += 1
            lower, upper = (-2.0, 2.0) if pitch_joints == 1 else (-2.8, 2.8)
        else:
            lower, upper = -2.9, 2.9
        limit = f'<limit lower="{lower}" upper="{upper}" velocity="2.0" effort="150"/>'
        joints.append(_joint(f"joint{k}", "revolute", parent, child, offset, axis, limit))
        parent, offset = child, length * s
    if design.gripper:
        hand = _shapes(design, folder, "hand", 0.06 * s, 0.05 * s, 8)
        links.append(f'<link name="hand">{_inertial(0.6, 0.06 * s)}{hand}</link>')
        joints.append(_joint("flange_to_hand", "fixed", parent, "hand", offset, "0 0 1"))
        finger = '<limit lower="0.0" upper="0.04" velocity="0.2" effort="20"/>'
        for side, sign in (("left", 1), ("right", -1)):
            size = f"{0.015 * s:.4f} {0.01 * s:.4f} {0.05 * s:.4f}"
            box = f'<origin xyz="0 0 {0.025 * s:.4f}"/><geometry><box size="{size}"/></geometry>'
            shapes = f"<visual>{box}</visual><collision>{box}</collision>"
            links.append(f'<link name="{side}_finger">{_inertial(0.05, 0.05 * s)}{shapes}</link>')
            joints.append(
                f'<joint name="{side}_finger_joint" type="prismatic"><parent link="hand"/><child link="{side}_finger"/>'
                f'<origin xyz="0 {sign * 0.02 * s:.4f} {0.06 * s:.4f}"/><axis xyz="0 {sign} 0"/>{finger}</joint>'
            )
        links.append('<link name="tool0"/>')
        joints.append(_joint("hand_to_tool0", "fixed", "hand", "tool0", 0.105 * s, "0 0 1"))
    body = "\n  ".join(links + joints)
    return f'<?xml version="1.0"?>\n<robot name="{design.name}">\n  {body}\n</robot>\n'


def write_arm(directory: Path, design: ArmDesign) -> Path:
    """`design` as directory/<name>/<name>.urdf with its meshes beside it; the URDF's path."""
    folder = directory / design.name
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{design.name}.urdf"
    path.write_text(arm_urdf(design, folder))
    return path


def write_example_arm(directory: Path, name: str) -> Path:
    """Arm `name` of STUDY_ARMS or LAB_ARMS written into `directory`; its URDF's path."""
    if name in LAB_ARMS:
        return write_lab_arm(directory, name)
    return write_arm(directory, next(design for design in STUDY_ARMS if design.name == name))


# ------------------------------------------------------------------------------------ arms labs have, as URDFs
# Three arms in the shapes labs actually put beside a table, each written as a ROS description package would hold it
# (<dir>/<name>_description/urdf/<name>.urdf, its meshes under meshes/ named by package:// URLs, STL collision and
# COLLADA visual): a UR5 from Universal Robots' published DH parameters, a five-joint desktop arm and a SCARA.


@dataclass(frozen=True)
class Part:
    """A link and the joint above it. `box` is its collision and visual shape, (low, high) corners in its own frame
    (None: no shape, a frame); the joint's origin is in the parent link's frame."""

    link: str
    parent: str
    kind: str  # "revolute", "prismatic", "continuous" or "fixed"
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: str = "0 0 1"
    limits: tuple[float, float, float] = (0.0, 0.0, 0.0)  # lower, upper, velocity
    box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    mass: float = 1.0
    joint: str = ""  # the joint's name; "" for <link>_joint
    effort: float = 100.0  # the joint's force limit, N·m or N


_TWO_PI = 2.0 * np.pi
_UR_SPEED = 3.15  # rad/s, ur_description's

# Universal Robots' DH parameters of the UR5 (d1, a2, a3, d4, d5, d6) laid out as ur_description lays its links out:
# the shoulder offset 0.13585 m sideways, the elbow 0.1197 m back, three wrist joints, tool0 on the flange turned to
# point out of it; the robot on base_link under a `world` root, with ur_description's `base` and `ee_link` frames
UR5_DH = {"d1": 0.089159, "a2": 0.425, "a3": 0.39225, "d4": 0.10915, "d5": 0.09465, "d6": 0.0823}
UR5_LIKE = (
    Part("base_link", "world", "fixed", box=((-0.06, -0.06, 0.0), (0.06, 0.06, 0.07)), mass=4.0, joint="world_joint"),
    Part("base", "base_link", "fixed", rpy=(0.0, 0.0, -np.pi), joint="base_link-base_fixed_joint"),
    Part(
        "shoulder_link",
        "base_link",
        "revolute",
        (0.0, 0.0, UR5_DH["d1"]),
        limits=(-_TWO_PI, _TWO_PI, _UR_SPEED),
        box=((-0.055, -0.055, -0.045), (0.055, 0.075, 0.055)),
        mass=3.7,
        joint="shoulder_pan_joint",
    ),
    Part(
        "upper_arm_link",
        "shoulder_link",
        "revolute",
        (0.0, 0.13585, 0.0),
        (0.0, np.pi / 2, 0.0),
        "0 1 0",
        (-_TWO_PI, _TWO_PI, _UR_SPEED),
        ((-0.045, -0.045, -0.035), (0.045, 0.045, 0.46)),
        8.393,
        joint="shoulder_lift_joint",
    ),
    Part(
        "forearm_link",
        "upper_arm_link",
        "revolute",
        (0.0, -0.1197, UR5_DH["a2"]),
        axis="0 1 0",
        limits=(-np.pi, np.pi, _UR_SPEED),
        box=((-0.04, -0.04, -0.04), (0.04, 0.04, 0.42)),
        mass=2.275,
        joint="elbow_joint",
    ),
    Part(
        "wrist_1_link",
        "forearm_link",
        "revolute",
        (0.0, 0.0, UR5_DH["a3"]),
        (0.0, np.pi / 2, 0.0),
        "0 1 0",
        (-_TWO_PI, _TWO_PI, _UR_SPEED),
        ((-0.035, -0.03, -0.035), (0.035, 0.06, 0.035)),
        1.219,
        joint="wrist_1_joint",
    ),
    Part(
        "wrist_2_link",
        "wrist_1_link",
        "revolute",
        (0.0, UR5_DH["d4"] - 0.01615, 0.0),  # ur_description's 0.093: d4 less the shoulder's and elbow's offsets
        limits=(-_TWO_PI, _TWO_PI, _UR_SPEED),
        box=((-0.035, -0.035, -0.03), (0.035, 0.035, 0.06)),
        mass=1.219,
        joint="wrist_2_joint",
    ),
    Part(
        "wrist_3_link",
        "wrist_2_link",
        "revolute",
        (0.0, 0.0, UR5_DH["d5"]),
        axis="0 1 0",
        limits=(-_TWO_PI, _TWO_PI, _UR_SPEED),
        box=((-0.035, -0.02, -0.035), (0.035, UR5_DH["d6"], 0.035)),
        mass=0.1879,
        joint="wrist_3_joint",
    ),
    Part("ee_link", "wrist_3_link", "fixed", (0.0, UR5_DH["d6"], 0.0), (0.0, 0.0, np.pi / 2), joint="ee_fixed_joint"),
    Part(
        "tool0",
        "wrist_3_link",
        "fixed",
        (0.0, UR5_DH["d6"], 0.0),
        (-np.pi / 2, 0.0, 0.0),
        joint="wrist_3_link-tool0_fixed_joint",
    ),
)

# A five-joint desktop arm in a WidowX 200's proportions: base yaw, shoulder, elbow, wrist pitch, wrist roll (about
# the forearm's line, x), the upper arm L-shaped (up, then a step forward), reach some 0.55 m
WIDOWX_LIKE = (
    Part("base_link", "world", "fixed", box=((-0.06, -0.06, 0.0), (0.06, 0.06, 0.05)), mass=0.8),
    Part(
        "shoulder_link",
        "base_link",
        "revolute",
        (0.0, 0.0, 0.072),
        limits=(-np.pi, np.pi, np.pi),
        box=((-0.035, -0.035, -0.005), (0.035, 0.035, 0.03)),
        mass=0.25,
        joint="waist",
    ),
    Part(
        "upper_arm_link",
        "shoulder_link",
        "revolute",
        (0.0, 0.0, 0.039),
        axis="0 1 0",
        limits=(-1.88, 1.97, np.pi),
        box=((-0.02, -0.025, -0.015), (0.02, 0.025, 0.2)),
        mass=0.3,
        joint="shoulder",
    ),
    Part(
        "forearm_link",
        "upper_arm_link",
        "revolute",
        (0.05, 0.0, 0.2),
        axis="0 1 0",
        limits=(-1.88, 1.62, np.pi),
        box=((-0.02, -0.02, -0.02), (0.2, 0.02, 0.02)),
        mass=0.2,
        joint="elbow",
    ),
    Part(
        "wrist_link",
        "forearm_link",
        "revolute",
        (0.2, 0.0, 0.0),
        axis="0 1 0",
        limits=(-1.75, 2.15, np.pi),
        box=((-0.015, -0.02, -0.02), (0.065, 0.02, 0.02)),
        mass=0.1,
        joint="wrist_angle",
    ),
    Part(
        "gripper_link",
        "wrist_link",
        "revolute",
        (0.065, 0.0, 0.0),
        axis="1 0 0",
        limits=(-np.pi, np.pi, np.pi),
        box=((0.0, -0.03, -0.02), (0.06, 0.03, 0.02)),
        mass=0.1,
        joint="wrist_rotate",
    ),
    Part("ee_gripper_link", "gripper_link", "fixed", (0.1, 0.0, 0.0)),
)

# A SCARA with a lift: a column, a carriage on a prismatic lift, two arm links turning about z and a quill that
# rolls about z and carries the tool downwards (reach some 0.6 m)
SCARA_LIKE = (
    Part("base_link", "world", "fixed", box=((-0.1, -0.1, 0.0), (0.1, 0.1, 0.8)), mass=15.0),
    Part(
        "carriage",
        "base_link",
        "prismatic",
        (0.13, 0.0, 0.1),
        limits=(0.0, 0.6, 0.5),
        box=((-0.03, -0.06, 0.0), (0.05, 0.06, 0.12)),
        mass=4.0,
        joint="lift",
        # a screw-driven lift holds several times what it carries (9.5 kg, and pybullet's 1 kg for the massless
        # tool0: at 100 N, the physics engine's drive could not hold the 103 N and the lift fell)
        effort=400.0,
    ),
    Part(
        "inner_link",
        "carriage",
        "revolute",
        (0.05, 0.0, 0.06),
        limits=(-2.5, 2.5, 2.0),
        box=((-0.04, -0.04, -0.03), (0.34, 0.04, 0.03)),
        mass=3.0,
        joint="shoulder",
    ),
    Part(
        "outer_link",
        "inner_link",
        "revolute",
        (0.3, 0.0, -0.065),
        limits=(-2.6, 2.6, 2.5),
        box=((-0.035, -0.035, -0.025), (0.29, 0.035, 0.025)),
        mass=2.0,
        joint="elbow",
    ),
    Part(
        "quill",
        "outer_link",
        "continuous",
        (0.25, 0.0, -0.03),
        limits=(0.0, 0.0, 4.0),
        box=((-0.015, -0.015, -0.12), (0.015, 0.015, 0.0)),
        mass=0.5,
        joint="wrist_roll",
    ),
    Part("tool0", "quill", "fixed", (0.0, 0.0, -0.12), (np.pi, 0.0, 0.0)),
)

LAB_ARMS: dict[str, tuple[Part, ...]] = {"ur5_like": UR5_LIKE, "widowx_like": WIDOWX_LIKE, "scara_like": SCARA_LIKE}
# The link a command names with --ee-link, where the URDF has more than one end (ur_description's ee_link and tool0)
LAB_ARM_EE_LINKS = {"ur5_like": "tool0"}


def _part_urdf(part: Part, package: str) -> tuple[str, str]:
    """(the link's XML, the joint's XML)."""
    shapes = ""
    if part.box is not None:
        low, high = np.array(part.box[0]), np.array(part.box[1])
        centre = (low + high) / 2.0
        inertia = part.mass * float(np.max(high - low)) ** 2 / 12 + 1e-4
        shapes = (
            f'<inertial><origin xyz="{centre[0]:.4f} {centre[1]:.4f} {centre[2]:.4f}"/><mass value="{part.mass}"/>'
            f'<inertia ixx="{inertia:.6f}" ixy="0" ixz="0" iyy="{inertia:.6f}" iyz="0" izz="{inertia:.6f}"/></inertial>'
            + f'<visual><geometry><mesh filename="package://{package}/meshes/visual/{part.link}.dae"/></geometry></visual>'
            + f'<collision><geometry><mesh filename="package://{package}/meshes/collision/{part.link}.stl"/></geometry>'
            + "</collision>"
        )
    link = f'<link name="{part.link}">{shapes}</link>'
    xyz = " ".join(f"{v:.6f}" for v in part.xyz)
    rpy = " ".join(f"{v:.6f}" for v in part.rpy)
    joint = (
        f'<joint name="{part.joint or part.link + "_joint"}" type="{part.kind}"><parent link="{part.parent}"/>'
        f'<child link="{part.link}"/><origin xyz="{xyz}" rpy="{rpy}"/>'
    )
    if part.kind != "fixed":
        lower, upper, velocity = part.limits
        joint += f'<axis xyz="{part.axis}"/><limit lower="{lower:.6f}" upper="{upper:.6f}" velocity="{velocity}" '
        joint += f'effort="{part.effort:g}"/>'
    return link, joint + "</joint>"


def with_effort(parts: tuple[Part, ...], joint: str, effort: float) -> tuple[Part, ...]:
    """`parts` with joint `joint`'s force limit set to `effort` (N·m or N): an arm with a drive too weak, say."""
    return tuple(dataclasses.replace(part, effort=effort) if part.joint == joint else part for part in parts)


def write_lab_arm(directory: Path, name: str, parts: tuple[Part, ...] | None = None) -> Path:
    """Arm `name` of LAB_ARMS (or `parts` under that name) as a description package in `directory`:
    <name>_description/urdf/<name>.urdf, its meshes under meshes/ named by package:// URLs (found in the package
    above the URDF); the URDF's path."""
    package = f"{name}_description"
    folder = directory / package
    for sub in ("urdf", "meshes/collision", "meshes/visual"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    (folder / "package.xml").write_text(
        f'<?xml version="1.0"?>\n<package format="2"><name>{package}</name><version>0.0.0</version>'
        "<description>written by the tests</description><maintainer email='tests@example.org'>tests</maintainer>"
        "<license>BSD</license><buildtool_depend>catkin</buildtool_depend></package>\n"
    )
    links, joints = ['<link name="world"/>'], []
    for part in LAB_ARMS[name] if parts is None else parts:
        link, joint = _part_urdf(part, package)
        links.append(link)
        joints.append(joint)
        if part.box is not None:
            low, high = np.array(part.box[0]), np.array(part.box[1])
            _write_stl(folder / "meshes" / "collision" / f"{part.link}.stl", low, high)
            _write_dae(folder / "meshes" / "visual" / f"{part.link}.dae", low, high)
    body = "\n  ".join(links + joints)
    path = folder / "urdf" / f"{name}.urdf"
    path.write_text(f'<?xml version="1.0"?>\n<robot name="{name}">\n  {body}\n</robot>\n')
    return path
