"""A scene that fits the robot: where the table and the hand go for this arm's reach and shoulder height, so that
every combination of the design can be run. `python -m sim.study scene --robot X --out scene.yaml` proposes one;
a study command given --robot and no --scene uses the same proposal (computed once per robot and design, kept in
the cache beside the self-contact verdicts), and takes the plans the fit made in it rather than planning them again
(sim.study.design.verdicts).

How. The bundled scene (the thesis's Panda) is tried first, with this robot on its base, as it is. Then the hand goes
out
from the base along x at a fraction of the arm's reach (from its shoulder, the first joint about a horizontal
axis), on a table whose top is at the robot's mounting (the bottom of its base link) or a fraction of the reach
lower, in the order of how close each candidate is to the Panda's
own proportions. The table keeps its size beyond the base and the hand, and the participant's seat keeps its place
beside the hand. The robot's base stays at the origin: it is the URDF's mounting, high or low.

The paths' shapes (their starts and via points, from the hand) are tried at the thesis's size on every placement,
then at 0.85 and 0.7 of it; only for an arm that fits none of those (a small one) are they sized to it (path_scale),
the bundled scene first:
scaled down, in steps of 0.05 from 1 to 0.3, until at every start and via point the wrist (the tool's length above
it, the tool pointing down) lies within SIZE_FRACTION of the wrist's reach (the arm's less the tool) from the
shoulder, and NEAR_FRACTION of it or more out from the shoulder's vertical axis. Stand-offs, speeds, approach
directions and the hand's place relative to the participant stay the design's and the template's.

A candidate is first screened: by reach alone (each approach's start and end within the reach from the shoulder, no
IK; for an arm keeping its tool down, the wrist above each start, middle and end within the wrist's reach), then by
IK of each approach's start, middle and end (cheap), then checked like `check` (every sample planned, limits,
contacts, stand-offs, the drives holding the arm; a candidate's planning stops at its first combination that fails);
the first that passes is the proposal. An arm whose drives cannot hold it at home fits none: that is said first. An
arm of fewer than six joints is offered the candidates where it keeps its tool pointing down first, then all of them
again where it keeps the position alone.

One concern, and a long one: fitting a scene to an arm, screened from cheap to dear, and keeping the proposal by the
arm's content so that it is made once; a scene's YAML, read and written, is sim.study.design.scene's.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sim import cache
from sim.cache import entry_path
from sim.geometry.kinematics import POSITION_WEIGHTS, KinematicChain, chain_for, solve_ik
from sim.robots import RobotSpec
from sim.robots.identity import robot_identity
from sim.study.design.errors import DesignError
from sim.study.design.feasibility import Approaches, Combination, check_holds_home, ik_attempts
from sim.study.design.paths import SHAPES, approach_path, hand_frame
from sim.study.design.plan import make_plan
from sim.study.design.progress import Progress
from sim.study.design.scene import DEFAULT_SCENE, Box, Scene, load_scene, parse_scene, scene_robot, scene_to_data
from sim.study.design.spec import Design, load_design
from sim.study.design.tool import approach_rotation, tool_axis
from sim.study.design.world import SceneWorld
from sim.wire.contract import STEP_S

__all__ = [
    "Candidate",
    "Fit",
    "HAND_FRACTIONS",
    "Proportions",
    "NEAR_FRACTION",
    "SIZE_FRACTION",
    "TABLE_DROPS",
    "design_combinations",
    "fit_scene",
    "fitted_scene",
    "keep",
    "path_scale",
    "proportions",
    "scene_for",
    "screen",
    "tool_down_out_of_reach",
    "WRIST_SLACK",
]

# of the proposal; one kept by another version is proposed again (2: the bundled scene names the arm; 3: sized paths;
# 4: the robot on a pedestal where the table is lower than its mounting; 5: the drives hold the arm along every path)
_VERSION = 5
log = logging.getLogger(__name__)

# The hand's distance from the base, as fractions of the reach, the Panda's first (its bundled scene has about
# this), then ever farther from it; the table top at the robot's mounting (the bottom of its base link: the robot
# stands on the table, as the Panda does) or lower, never higher (the table would cut through the base)
HAND_FRACTIONS = (0.6, 0.65, 0.55, 0.7, 0.5, 0.75, 0.45, 0.8, 0.4)
TABLE_DROPS = (0.0, 0.1, 0.2, 0.3, 0.4)  # below the robot's mounting, as fractions of the reach
_REACH_SAMPLES = 400
# The paths' shapes are made smaller until, at every start and via point, the wrist (the tool's length above it, the
# tool pointing down) lies within this fraction of the wrist's reach (the arm's less the tool's) from the shoulder,
# in these steps. (The Panda's own paths, in its bundled scene, take its wrist to 1.02 of it: that scene is the
# thesis's, used as it is, never sized.)
SIZE_FRACTION = 0.9
# Before sizing, the thesis's shapes are tried whole and at these smaller sizes on every placement: sizing goes below
# them only for an arm that fits none (a small one), as the approaches should start well beyond comfort distances
_APPROACH_SCALES = (1.0, 0.85, 0.7)
# ... and, out from the shoulder's vertical axis, at least this fraction of the wrist's reach (an arm reaches down
# next to its own column badly, a SCARA not at all)
NEAR_FRACTION = 0.25
# A candidate's wrist beyond its reach by more than this fraction of the arm's reach rules it out for an arm that must
# point its tool down, with no IK (tool_down_out_of_reach)
WRIST_SLACK = 0.05
_PATH_SCALES = tuple(round(1.0 - 0.05 * k, 2) for k in range(15))  # 1.0 .. 0.3


@dataclass(frozen=True)
class Proportions:
    """What the proposal scales by: the shoulder's position and the arm's reach from it (m, base frame), and the
    tool's length: from the wrist's pitch (the last joint about an axis across the tool's, at home) to the end
    effector, which stands that far above a point the tool reaches pointing down."""

    shoulder: np.ndarray
    reach: float
    tool: float = 0.0


@dataclass(frozen=True)
class Candidate:
    label: str
    scene: Scene
    verdict: str  # "fits", or why not


@dataclass(frozen=True)
class Fit:
    scene: Scene | None  # None: none of the candidates fits
    proportions: Proportions
    tried: list[Candidate]


def proportions(robot: RobotSpec, chain: KinematicChain) -> Proportions:
    """The shoulder (the first joint about a horizontal axis, at home; else the second joint) and the reach: the
    farthest the end effector gets from it over random joint states (deterministic)."""
    frames = chain.fk_link_frames(robot.home)
    jacobian = chain.jacobian(robot.home)
    horizontal = [k for k in range(chain.dof) if abs(jacobian[5, k]) < 0.5 and np.linalg.norm(jacobian[3:, k]) > 0.5]
    index = horizontal[0] if horizontal else min(1, chain.dof - 1)
    shoulder = frames[index][:3, 3].copy()
    rng = np.random.default_rng(0)
    lower, upper = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    samples = rng.uniform(lower, upper, size=(_REACH_SAMPLES, chain.dof))
    reach = max(float(np.linalg.norm(chain.fk(q)[:3, 3] - shoulder)) for q in samples)
    pose = chain.fk(robot.home)
    along = pose[:3, :3] @ tool_axis(chain, robot.home)
    across = [
        k
        for k in range(chain.dof)
        if np.linalg.norm(jacobian[3:, k]) > 0.5 and abs(float(jacobian[3:, k] @ along)) < 0.5
    ]
    tool = float(np.linalg.norm(pose[:3, 3] - frames[across[-1]][:3, 3])) if across else 0.0
    return Proportions(shoulder, reach, tool)


def candidate_scene(
    template: Scene,
    robot: RobotSpec,
    hand_distance: float,
    table_top: float,
    approach_scale: float = 1.0,
    footprint: tuple[float, float] = (0.2, 0.2),
) -> Scene:
    """`template` with the hand `hand_distance` out along x on a table whose top is at `table_top` (world z, the
    base at the origin): the table as far behind the base and beyond the hand as the template's, the seat as far
    beside the hand."""
    behind = template.table.position[0] - template.table.size[0] / 2.0  # the table's near edge, behind the base
    beyond = template.table.position[0] + template.table.size[0] / 2.0 - template.hand.position[0]
    length = hand_distance + beyond - behind
    table = Box(
        np.array([length, template.table.size[1], template.table.size[2]]),
        np.array([behind + length / 2.0, template.table.position[1], table_top - template.table.size[2] / 2.0]),
        template.table.yaw,
    )
    hand = Box(
        template.hand.size,
        np.array([hand_distance, template.hand.position[1], table_top + template.hand.size[2] / 2.0]),
        template.hand.yaw,
    )
    seat = hand.top + (template.seat - template.hand.top)
    height = -table_top  # the robot stands on a pedestal of the table's drop (its `footprint`), its base at the origin
    pedestal = (
        Box(np.array([footprint[0], footprint[1], height]), np.array([0.0, 0.0, table_top + height / 2.0]))
        if height > 1e-3
        else None
    )
    return dataclasses.replace(
        template,
        robot=scene_robot_name(robot),
        ee_link=robot.ee_link,
        base_position=np.zeros(3),
        base_rpy=np.zeros(3),
        table=table,
        hand=hand,
        seat=seat,
        approach_scale=approach_scale,
        pedestal=pedestal,
    )


def screen(
    robot: RobotSpec,
    chain: KinematicChain,
    scene: Scene,
    combinations: Sequence[Combination],
    dt: float,
    strict: bool = False,
) -> str:
    """Why a candidate cannot fit, from IK of each approach's start, middle and end alone; "" when nothing is found.
    They are solved as the approach would be (ik_attempts: an arm of fewer than six joints may give up the tool
    axis), or, `strict`, with the most an approach keeps (the tool axis too)."""
    target = np.eye(4)
    down = scene.to_base_direction(np.array([0.0, 0.0, -1.0]))
    target[:3, :3] = approach_rotation(chain, robot.home, down)
    attempts = ik_attempts(chain, robot.home, down)[: 1 if strict else None]
    try:
        for name, label, point in _checkpoints(scene, combinations, dt):
            target[:3, 3] = scene.to_base(point)
            if not any(
                solve_ik(chain, target, robot.home, weights=weights, restarts=8, rng=0).success
                for _, weights in attempts
            ):
                position = solve_ik(chain, target, robot.home, weights=POSITION_WEIGHTS, restarts=8, rng=0)
                if position.success:
                    return f"the arm cannot point the tool down at the {name} path's {label}"
                return f"the {name} path's {label} is out of reach"
    except DesignError as error:  # a path that cannot be made on this candidate
        return str(error)
    return ""


def _checkpoints(scene: Scene, combinations: Sequence[Combination], dt: float) -> Iterator[tuple[str, str, np.ndarray]]:
    """Each distinct approach's start, middle and end, in the scene's world: (path name, which, point), path by path
    (DesignError when a path cannot be made)."""
    for name, standoff, speed in dict.fromkeys(combinations):
        path = approach_path(scene, name, standoff, speed, dt)
        middle = path.positions[len(path.positions) // 2]
        for label, point in (("start", path.start), ("middle", middle), ("end", path.end)):
            yield name, label, point


def scene_robot_name(robot: RobotSpec) -> str:
    """The robot as a scene names it: as --robot gave it (a URDF's path), else its name."""
    return str(robot.cli_args[1]) if len(robot.cli_args) > 1 else robot.name


def fit_scene(
    robot: RobotSpec,
    template: Scene,
    combinations: Sequence[Combination],
    dt: float,
    progress: Progress = lambda _done, _total, _line: None,
) -> Fit:
    """The first candidate that fits (module docstring), with every candidate tried and why it did not."""
    chain = chain_for(robot)
    found = proportions(robot, chain)
    bundled = dataclasses.replace(template, robot=scene_robot_name(robot), ee_link=robot.ee_link)
    names = list(dict.fromkeys(name for name, _, _ in combinations))
    sized = dataclasses.replace(bundled, approach_scale=path_scale(bundled, found, names))
    candidates = [("the bundled scene", bundled)]  # the thesis's paths, whole, where the arm can do them there
    with SceneWorld(robot, template) as world:
        check_holds_home(robot, world)  # an arm that cannot hold itself fits no scene: said before any is tried
        mount, footprint = world.base_bottom(), world.base_footprint()
    pairs = sorted(
        ((hand, drop) for hand in HAND_FRACTIONS for drop in TABLE_DROPS),
        key=lambda pair: abs(pair[0] - HAND_FRACTIONS[0]) + pair[1],
    )
    # the thesis's shapes whole, then the fixed smaller sizes, then sized to the arm (module docstring)
    for scale in (*_APPROACH_SCALES, None):
        if scale is None and sized.approach_scale != 1.0:  # sized to the arm: only once no placement fits whole
            candidates.append(("the bundled scene" + _scaled(sized), sized))
        for hand, drop in pairs:
            distance, top = hand * found.reach, mount - drop * found.reach
            scene = candidate_scene(template, robot, distance, top, footprint=footprint)
            sized_scale = path_scale(scene, found, names)
            if scale is None and sized_scale >= _APPROACH_SCALES[-1]:
                continue  # (tried above at a size at least as large)
            scene = dataclasses.replace(scene, approach_scale=sized_scale if scale is None else scale)
            label = f"the hand {distance:.2f} m out, the table top {round(top, 2) + 0.0:+.2f} m" + _scaled(scene)
            candidates.append((label, scene))
    tried = []
    # An arm of fewer than six joints is first offered the scenes where it keeps its tool pointing down, then any
    passes = (True, False) if len(ik_attempts(chain, robot.home, np.array([0.0, 0.0, -1.0]))) > 1 else (False,)
    total = len(passes) * len(candidates)
    for strict in passes:
        for number, (label, scene) in enumerate(candidates, start=1):
            reason = (
                _out_of_reach(scene, found, combinations, dt)
                or (strict and tool_down_out_of_reach(scene, found, combinations, dt))
                or screen(robot, chain, scene, combinations, dt, strict)
            )
            if not reason:
                reason = _first_failure(robot, scene, combinations, dt)
            tried.append(Candidate(label, scene, reason or "fits"))
            progress(len(tried), total, f"{label}: {reason or 'fits'}")
            log.info("scene %d of %d tried: %s: %s", number, len(candidates), label, reason or "fits")
            if not reason:
                return Fit(scene, found, tried)
    return Fit(None, found, tried)


def _first_failure(robot: RobotSpec, scene: Scene, combinations: Sequence[Combination], dt: float) -> str:
    """Why the first combination that is not feasible in `scene` is not, planned in order; "" when all are. The
    rest are not planned: one is enough to rule the candidate out, and planning is most of a proposal's time. Where
    all are, their plans are handed on (Approaches.hand_on): the command that asked for the scene plans the same
    combinations in it next."""
    with Approaches(robot, scene, dt, keep=False) as approaches:  # kept by the planner that takes them (FITTED)
        for name, standoff, speed in dict.fromkeys(combinations):
            approach = approaches.plan((name, standoff, speed))
            if not approach.feasible:
                return f"{name} to {standoff} m at {speed} m/s fails: {approach.problems[0]}"
        approaches.hand_on()
    return ""


def _scaled(scene: Scene) -> str:
    return f", the paths' shapes × {scene.approach_scale:g}" if scene.approach_scale != 1.0 else ""


def path_scale(scene: Scene, found: Proportions, names: Sequence[str]) -> float:
    """The paths' shapes' scale for this arm in `scene` (module docstring): the largest of 1, 0.95, ... 0.3 at which,
    at every start and via point of the paths `names`, the wrist lies within SIZE_FRACTION of the wrist's reach from
    the shoulder and NEAR_FRACTION of it or more out from the shoulder's vertical axis; 0.3 when none does (the hand
    itself is then misplaced, which the screen says)."""
    frame, top = hand_frame(scene), scene.hand.top
    points = [np.array(point) for name in names for point in (SHAPES[name].start, SHAPES[name].via) if point]
    wrist = np.array([0.0, 0.0, found.tool])
    for scale in _PATH_SCALES:
        world = np.array([top + frame @ (scale * point) + wrist for point in points])
        offsets = scene.to_base(world) - found.shoulder
        wrist_reach = found.reach - found.tool
        if np.all(np.linalg.norm(offsets, axis=1) <= SIZE_FRACTION * wrist_reach) and np.all(
            np.linalg.norm(offsets[:, :2], axis=1) >= NEAR_FRACTION * wrist_reach
        ):
            return scale
    return _PATH_SCALES[-1]


def _out_of_reach(scene: Scene, found: Proportions, combinations: Sequence[Combination], dt: float) -> str:
    """Why a candidate cannot fit, from the reach alone (no IK): an approach's start or end farther from the shoulder
    than the arm reaches; "" when none is."""
    for name, standoff, speed in dict.fromkeys(combinations):
        try:
            path = approach_path(scene, name, standoff, speed, dt)
        except DesignError as error:
            return str(error)
        for label, point in (("start", path.start), ("end", path.end)):
            distance = float(np.linalg.norm(scene.to_base(point) - found.shoulder))
            if distance > found.reach:
                return (
                    f"the {name} path's {label} is {distance:.2f} m from the shoulder, beyond the arm's reach "
                    f"({found.reach:.2f} m)"
                )
    return ""


def tool_down_out_of_reach(scene: Scene, found: Proportions, combinations: Sequence[Combination], dt: float) -> str:
    """Why an arm cannot point its tool down along a candidate's approaches, from its proportions alone (no IK): at
    an approach's start, middle or end, its wrist (the tool's length above the point) farther from the shoulder than
    the wrist reaches (the arm's reach less the tool), by more than WRIST_SLACK of the reach (the reach is the most
    that random joint states gave, a little short of the truth: a nearer case is left to IK); "" when none is."""
    wrist_reach = found.reach - found.tool
    try:
        for name, label, point in _checkpoints(scene, combinations, dt):
            wrist = scene.to_base(point + np.array([0.0, 0.0, found.tool]))
            distance = float(np.linalg.norm(wrist - found.shoulder))
            if distance > wrist_reach + WRIST_SLACK * found.reach:
                return (
                    f"the arm cannot point the tool down at the {name} path's {label}: its wrist would be "
                    f"{distance:.2f} m from the shoulder, beyond the wrist's reach ({wrist_reach:.2f} m)"
                )
    except DesignError as error:  # a path that cannot be made on this candidate
        return str(error)
    return ""


def _cache_path(robot: RobotSpec, template_text: str, combinations: Sequence[Combination], dt: float) -> Path:
    """Where the proposal for this robot (by its content, robot_identity: the same arm in another folder shares the
    entry, an edited mesh does not), template, design and step is kept."""
    identity = json.dumps([_VERSION, robot_identity(robot), template_text, sorted(set(combinations)), dt])
    return entry_path("scenes", identity, ".yaml")


def keep(scene: Scene, robot: RobotSpec, template_text: str, combinations: Sequence[Combination], dt: float) -> None:
    """Keep a proposal in the cache, whole or not at all, where fitted_scene finds it."""
    cache.keep(
        _cache_path(robot, template_text, combinations, dt), yaml.safe_dump(scene_to_data(scene), sort_keys=False)
    )


def fitted_scene(
    robot: RobotSpec,
    template: Scene,
    template_text: str,
    combinations: Sequence[Combination],
    dt: float,
    progress: Progress = lambda _done, _total, _line: None,
) -> Scene:
    """The proposal for `robot`, from the cache when this robot, template and design were fitted before;
    DesignError, in one line, when nothing fits."""
    path = _cache_path(robot, template_text, combinations, dt)
    try:
        kept = parse_scene(yaml.safe_load(path.read_text(encoding="utf-8")), str(path))
        # the entry may have been fitted to this arm found elsewhere: the scene names it as --robot gave it here
        return dataclasses.replace(kept, robot=scene_robot_name(robot))
    except (OSError, yaml.YAMLError, DesignError):
        pass  # not fitted yet, or unreadable: fitted again
    fit = fit_scene(robot, template, combinations, dt, progress)
    if fit.scene is None:
        raise DesignError(no_fit_message(robot, fit))
    keep(fit.scene, robot, template_text, combinations, dt)
    return fit.scene


def no_fit_message(robot: RobotSpec, fit: Fit) -> str:
    nearest = fit.tried[1] if len(fit.tried) > 1 else fit.tried[0]
    return (
        f"no scene fits {robot.name} (reach {fit.proportions.reach:.2f} m from its shoulder at "
        f"{fit.proportions.shoulder[2]:.2f} m): with {nearest.label}, {nearest.verdict}; give a scene of your own "
        "with --scene (python -m sim.study scene writes one to start from), or a design with other stand-offs or speeds"
    )


def design_combinations(design: Design) -> list[Combination]:
    """Every combination a session of `design` runs (each participant's plan holds them all)."""
    return list(dict.fromkeys((t.path, t.standoff, t.peak_speed) for t in make_plan(design, 1, 0).trials))


def scene_for(
    scene_path: Path | None,
    robot: str | None,
    overrides: Mapping[str, Any] | None = None,
    progress: Progress = lambda _done, _total, _line: None,
) -> tuple[Scene, RobotSpec]:
    """A study command's scene and robot: the given scene file's; else the bundled scene with its robot; else, for
    another robot (--robot), the scene proposed for it and the bundled design (fitted_scene, at the default step)."""
    if scene_path is not None or not robot or robot == load_scene().robot:
        scene = load_scene(scene_path)
        return scene, scene_robot(scene, robot, overrides)
    template = load_scene()
    spec = scene_robot(template, robot, overrides)
    text = DEFAULT_SCENE.read_text(encoding="utf-8")
    return fitted_scene(spec, template, text, design_combinations(load_design()), STEP_S, progress), spec
