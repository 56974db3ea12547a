"""An approach path made joint motion and checked before it is ever run: IK of every sample
(sim.geometry.kinematics), joint position and velocity limits, no contact with the table, the hand or the robot
itself (pybullet's collision shapes; of its own link pairs only those that can really meet, see
sim.engine.self_contact), and the stand-off actually reached (FK of the planned end). An infeasible
combination is reported with every reason, never run. Distances to the hand are the scene's (Scene.distance):
by default from the robot's collision geometry, so a path's end is where its nearest surface is the stand-off.

The end effector keeps one orientation throughout: its tool pointing straight down, turned the least from home
(sim.study.design.tool; the Panda's is its home's). An arm of six joints or more keeps it on every axis its chain
controls (sim.control.scenarios.defaults). An arm of fewer keeps what it can, per path (Constraints): the position
and the tool axis pointing down, the roll about it free (5-D); where that fails, the position alone. Each approach is
one IK branch: its start solved from home (then from random seeds, the one nearest home kept), every later sample
warm-started from the one before, and a jump between samples (a flip or a fold) is a problem named as such.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Tuple

import numpy as np

from sim.control.scenarios.defaults import controllable_weights
from sim.geometry.kinematics import POSITION_WEIGHTS, KinematicChain, PathIKResult, chain_for, solve_ik, solve_path_ik
from sim.robots import RobotSpec
from sim.robots.identity import robot_identity
from sim.study.design.errors import DesignError
from sim.study.design.holding import holding_line, shortfalls
from sim.study.design.kept_plans import keep_plan, read_plan
from sim.study.design.paths import ApproachPath, approach_path
from sim.study.design.planned import PlannedApproach
from sim.study.design.scene import Scene
from sim.study.design.tool import approach_rotation
from sim.study.design.verdicts import Kept, verdict_key
from sim.study.design.world import CONTACT_MARGIN, SceneWorld

__all__ = [
    "AXIS_WEIGHTS",
    "BRANCH_JUMP",
    "CONSTRAINTS",
    "REMEDIES",
    "remedies",
    "Approaches",
    "CONTACT_MARGIN",
    "STANDOFF_TOLERANCE",
    "Combination",
    "FITTED",
    "PlannedApproach",
    "SceneWorld",
    "check_holds_home",
    "ik_attempts",
    "approach_targets",
    "plan_approach",
    "solve_approach",
    "plan_combination",
    "plan_combinations",
]

STANDOFF_TOLERANCE = 0.002  # m: FK of the planned end vs the path's stand-off
_IK_RESTARTS = 20
_BRANCH_SEEDS = 8  # random seeds for an approach's first sample, besides home
_BEHIND = 0.1  # m: a joint this far behind the base, away from the hand, reaches over the arm's head
_STANDOFF_ROUNDS = 4
# Position and the tool axis along the base's z (the roll about it free): an arm of fewer than six joints, upright
AXIS_WEIGHTS = (1.0, 1.0, 1.0, 1.0, 1.0, 0.0)
# What an approach keeps, by its IK weights' name
CONSTRAINTS = {"pose": "position and orientation", "axis": "position and tool axis", "position": "position only"}
# rad: the most a joint may move between two samples of one branch; a path's samples are 20 ms apart and the study's
# speeds are at most 1 m/s, so a continuous branch moves a joint some hundredths of a radian; a flip moves it by ~π
BRANCH_JUMP = 0.5

# path name, stand-off (m), peak speed (m/s); typing.Tuple, as an alias is evaluated at run time (3.8 has no tuple[])
Combination = Tuple[str, float, float]


# What to change, by the kind of problem: said with the combinations that are not feasible
REMEDIES = {
    "reach": "the hand within the arm's reach (the scene's hand.xyz), or the scene `sim.study scene` proposes",
    "branch": "another path, or the hand placed elsewhere (the arm must change its configuration mid-path)",
    "limits": "another path, or the hand placed elsewhere",
    "speed": "a lower peak speed",
    "table": "a larger stand-off, or the table lower",
    "hand": "a larger stand-off, or another path",
    "self": "another path, or the hand placed elsewhere",
    "standoff": "another stand-off, or the hand placed elsewhere",
    "effort": "a joint that holds the arm (see the URDF's effort limits and masses; a link without <inertial> "
    "weighs 1 kg in pybullet), or the hand placed where the arm weighs less on that joint",
}


def remedies(approaches: Iterable[PlannedApproach]) -> str:
    """What to change for these approaches, each remedy once: "" when all are feasible."""
    return "; ".join(dict.fromkeys(remedy for approach in approaches for remedy in approach.remedies))


def _solve_branch(
    chain: KinematicChain, targets: np.ndarray, home: np.ndarray, weights: tuple[float, ...]
) -> PathIKResult:
    """One IK branch along `targets`: the first sample's solution (_branch_start), then each sample warm-started
    from the one before."""
    return solve_path_ik(chain, targets, _branch_start(chain, targets[0], home, weights), weights=weights)


# The first samples' solutions already found, by chain, target, home and weights: the combinations of one path share
# its start (they differ in stand-off and speed), so a scene's ~40 approaches have some five starts
_STARTS: dict[tuple[int, bytes, bytes, tuple[float, ...]], np.ndarray] = {}
_STARTS_KEPT = 4096


def _branch_start(
    chain: KinematicChain, target: np.ndarray, home: np.ndarray, weights: tuple[float, ...]
) -> np.ndarray:
    """Where an approach's branch starts: `target` solved from home and from _BRANCH_SEEDS random seeds. Of the
    solutions that keep every joint on the target's side of the base (none reaching over the arm's own head), the
    one standing highest (elbow up, away from the table) is kept, home's where it stands within a centimetre of it.
    Where none solves, the best of _IK_RESTARTS more random restarts (as a lone IK would try)."""
    key = (id(chain), target.tobytes(), home.tobytes(), tuple(weights))
    if key in _STARTS:
        return _STARTS[key].copy()
    rng = np.random.default_rng(0)
    lower, upper = np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi)
    seeds = [home] + [rng.uniform(lower, upper) for _ in range(_BRANCH_SEEDS)]
    found = [solve_ik(chain, target, seed, weights=weights) for seed in seeds]
    solved = [result for result in found if result.success]
    towards = target[:2, 3] / max(float(np.linalg.norm(target[:2, 3])), 1e-9)
    facing = [result for result in solved if _behind(chain, result.q, towards) <= _BEHIND]
    first = found[0]
    for result in facing or solved:
        if not first.success or _height(chain, result.q) > _height(chain, first.q) + 0.01:
            first = result
    if not first.success:
        first = solve_ik(chain, target, home, weights=weights, restarts=_IK_RESTARTS, rng=0)
    if len(_STARTS) >= _STARTS_KEPT:
        _STARTS.clear()
    _STARTS[key] = first.q.copy()
    return first.q


def _height(chain: KinematicChain, q: np.ndarray) -> float:
    """How high the arm stands at q: the mean height of its joints above its base (m)."""
    return float(np.mean([frame[2, 3] for frame in chain.fk_link_frames(q)]))


def _behind(chain: KinematicChain, q: np.ndarray, towards: np.ndarray) -> float:
    """How far (m) the arm's joints reach behind its base at q, away from the horizontal direction `towards`."""
    return float(max(-(frame[:2, 3] @ towards) for frame in chain.fk_link_frames(q)))


def _failure(
    chain: KinematicChain,
    robot: RobotSpec,
    scene: Scene,
    path: ApproachPath,
    targets: np.ndarray,
    k: int,
    kept: str,
) -> tuple[str, str]:
    """(why IK fails at sample k of an approach that kept `kept`, the kind of problem): out of reach; or reachable
    by position but not with the tool pointing down; or, on an approach that already kept the position alone,
    reachable on its own but not along the path from its start (the joints' limits on the way)."""
    where = path.positions[k]
    at = f"at t = {path.times[k]:.2f} s at ({where[0]:.3f}, {where[1]:.3f}, {where[2]:.3f}) m in the world"
    position = solve_ik(chain, targets[k], robot.home, weights=POSITION_WEIGHTS, restarts=_IK_RESTARTS, rng=0)
    if not position.success:
        return f"out of reach {at}, {float(np.linalg.norm(scene.to_base(where))):.3f} m from the robot's base", "reach"
    if kept == "position":
        return f"not reached along the path from its start {at} (the joints' limits on the way)", "limits"
    return f"cannot point the tool down {at} (the position alone is reachable)", "reach"


def ik_attempts(chain: KinematicChain, home: np.ndarray, down: np.ndarray) -> list[tuple[str, tuple[float, ...]]]:
    """What IK keeps along an approach, the most first (a key of CONSTRAINTS, its weights), for a tool pointing
    `down` (base frame): an arm of six joints or more every axis its chain controls; one of fewer the position and
    the tool axis (where down is the base's z, so the roll about it is the z rotation), else the position alone."""
    if chain.dof >= 6:
        return [("pose", controllable_weights(chain, home))]
    if abs(abs(float(down[2])) - 1.0) < 1e-9:
        return [("axis", AXIS_WEIGHTS), ("position", POSITION_WEIGHTS)]
    return [("position", POSITION_WEIGHTS)]


def approach_targets(chain: KinematicChain, robot: RobotSpec, scene: Scene, path: ApproachPath) -> np.ndarray:
    """(N, 4, 4): the end effector's pose at every sample of `path`, in the base frame, its tool pointing down."""
    targets = np.tile(chain.fk(robot.home), (len(path.times), 1, 1))
    targets[:, :3, :3] = approach_rotation(chain, robot.home, scene.to_base_direction(np.array([0.0, 0.0, -1.0])))
    targets[:, :3, 3] = scene.to_base(path.positions)
    return targets


def solve_approach(
    chain: KinematicChain, robot: RobotSpec, scene: Scene, targets: np.ndarray
) -> tuple[PathIKResult, str]:
    """One IK branch along `targets` keeping the most it can (ik_attempts), and what it kept (a key of
    CONSTRAINTS); the last attempt's result where none solves every sample."""
    down = scene.to_base_direction(np.array([0.0, 0.0, -1.0]))
    for name, weights in ik_attempts(chain, robot.home, down):  # the most kept first; the last one's result stands
        solved, kept = _solve_branch(chain, targets, robot.home, weights), name
        if solved.all_succeeded:
            break
    return solved, kept


def plan_approach(robot: RobotSpec, scene: Scene, path: ApproachPath, world: SceneWorld) -> PlannedApproach:
    """Joint motion for `path` (IK of every sample, one branch, module doc), checked (module doc)."""
    chain = chain_for(robot)
    targets = approach_targets(chain, robot, scene, path)
    problems: list[str] = []
    kinds: list[str] = []
    solved, kept = solve_approach(chain, robot, scene, targets)
    if not solved.all_succeeded:
        failed = np.flatnonzero(~solved.success)
        cause, kind = _failure(chain, robot, scene, path, targets, int(failed[0]), kept)
        problems.append(f"IK failed at {failed.size} of {len(path.times)} samples, first {cause}")
        kinds.append(kind)
    elif len(solved.q) > 1:
        jumps = np.abs(np.diff(solved.q, axis=0))
        if jumps.max() > BRANCH_JUMP:
            k, j = np.unravel_index(int(np.argmax(jumps)), jumps.shape)
            problems.append(
                f"{robot.joint_names[j]} jumps by {jumps[k, j]:.2f} at t = {path.times[k + 1]:.2f} s: the arm changes "
                "its configuration mid-path"
            )
            kinds.append("branch")
    positions = solved.q
    velocities = np.gradient(positions, path.dt, axis=0)
    velocities[0] = velocities[-1] = 0.0
    outside = ~((positions >= robot.lower - 1e-9) & (positions <= robot.upper + 1e-9))
    if outside.any():
        k, j = np.argwhere(outside)[0]
        problems.append(
            f"{robot.joint_names[j]} leaves its limits ({positions[k, j]:.3f} at t = {path.times[k]:.2f} s)"
        )
        kinds.append("limits")
    too_fast = np.abs(velocities) > robot.max_velocity
    if too_fast.any():
        k, j = np.argwhere(too_fast)[0]
        problems.append(
            f"{robot.joint_names[j]} exceeds its velocity limit ({abs(velocities[k, j]):.3f} > "
            f"{robot.max_velocity[j]:.3f} at t = {path.times[k]:.2f} s)"
        )
        kinds.append("speed")
    lowest = {"table": math.inf, "hand": math.inf, "self": math.inf}
    where = {"table": 0, "hand": 0, "self": 0}
    for sample in range(len(path.times)):
        for what, distance in world.clearance(positions[sample]).items():
            if distance < lowest[what]:
                lowest[what], where[what] = distance, sample
    for what, distance in lowest.items():
        if distance < CONTACT_MARGIN:
            closest = where[what]
            links = world.nearest_links(positions[closest], what)
            problems.append(
                f"the robot comes within {max(distance, 0.0) * 1000:.1f} mm of "
                f"{'itself' if what == 'self' else 'the ' + what} ({links}, at t = {path.times[closest]:.2f} s, "
                f"q = [{', '.join(f'{v:.2f}' for v in positions[closest])}])"
            )
            kinds.append(what)
    solved_samples = np.flatnonzero(solved.success)
    loads = np.array([world.gravity_loads(positions[k]) for k in solved_samples]).reshape(-1, robot.dof)
    for short in shortfalls(robot.joint_names, robot.joint_types, loads, robot.max_effort):
        problems.append(holding_line(short, f"at t = {path.times[solved_samples[short.sample]]:.2f} s"))
        kinds.append("effort")
    distances = np.array([world.hand_distance(q) for q in positions])
    reached = float(distances[-1])
    if abs(reached - path.standoff) > STANDOFF_TOLERANCE:
        problems.append(f"the planned end is {reached:.4f} m from the hand, not the stand-off {path.standoff} m")
        kinds.append("standoff")
    unreachable = int((~solved.success).sum())
    fixes = [REMEDIES[kind] for kind in dict.fromkeys(kinds)]
    return PlannedApproach(path, positions, velocities, reached, lowest, distances, problems, unreachable, fixes, kept)


def plan_combination(
    robot: RobotSpec, scene: Scene, combination: Combination, dt: float, world: SceneWorld
) -> PlannedApproach:
    """The combination's path planned and checked. Where the robot's distance is its surface's, the path's end (an
    end-effector point) is moved along the approach until that surface, not the point, ends at the stand-off: each
    round moves it by the last round's miss, which shrinks fast since near the end the two differ by about the
    tool's reach beyond the point. The rounds solve the end alone (warm-started from the planned end, on its branch),
    and the path found is planned and checked once more, whole; again from there where the whole path ends otherwise
    than the end alone did (an arm that keeps less than its whole pose)."""
    name, standoff, peak_speed = combination
    path = approach_path(scene, name, standoff, peak_speed, dt)
    planned = plan_approach(robot, scene, path, world)
    if scene.distance == "ee_point" or planned.unreachable:
        return planned  # (where IK fails, the distances say nothing about the path's end)
    chain = chain_for(robot)
    weights = dict(ik_attempts(chain, robot.home, scene.to_base_direction(np.array([0.0, 0.0, -1.0]))))
    point_standoff = standoff
    for _ in range(_STANDOFF_ROUNDS):  # each a whole plan, its end first moved by rounds of the end alone
        end_q, reached, moved = planned.positions[-1], planned.reached_standoff, False
        for _ in range(_STANDOFF_ROUNDS):
            miss = reached - standoff
            if not abs(miss) > STANDOFF_TOLERANCE / 4:
                break  # (NaN or inf: no surface)
            point_standoff -= miss
            try:
                candidate = approach_path(scene, name, standoff, peak_speed, dt, point_standoff)
            except DesignError:
                break  # the end moved out too far for the path's start: the last plan says it misses its stand-off
            target = approach_targets(chain, robot, scene, candidate)[-1]
            end = solve_ik(chain, target, end_q, weights=weights.get(planned.constraints, POSITION_WEIGHTS))
            if not end.success:
                break
            path, end_q, reached, moved = candidate, end.q, world.hand_distance(end.q), True
        if not moved:
            break
        planned = plan_approach(robot, scene, path, world)
        # an arm that keeps less than the whole pose may end the whole path otherwise than the end alone did
        if planned.unreachable or not abs(planned.reached_standoff - standoff) > STANDOFF_TOLERANCE:
            break
    return planned


# The plans of the last scene fitted in this process (sim.study.design.verdicts): an Approaches of the same robot,
# scene and step takes each of them instead of planning it again
FITTED: Kept[PlannedApproach] = Kept()


class Approaches:
    """The combinations of one robot in one scene, each planned when first asked for and kept, and the robot's
    distance to the hand by the scene's definition: what the runner, the simulated participant and the live view
    share. A combination planned before for exactly this robot, scene and step is not planned again: it is taken
    from the last fit in this process (FITTED), else read from the cache where a process of the same code kept it
    (kept_plans); what was not read from there is kept there, for the next process. The drives holding the arm at
    home are checked here all the same. It holds a SceneWorld (a
    pybullet client): close it."""

    def __init__(self, robot: RobotSpec, scene: Scene, dt: float, keep: bool = True) -> None:
        self.robot, self.scene, self.dt = robot, scene, dt
        self.keep = keep  # False: nothing written to the cache (a fit's candidate scenes, most of them never used)
        self.world = SceneWorld(robot, scene)
        try:
            check_holds_home(robot, self.world)
        except DesignError:
            self.world.close()
            raise
        self._planned: dict[Combination, PlannedApproach] = {}
        self._identity: str | None = None  # the robot's content, read when a key is first needed

    def plan(self, combination: Combination) -> PlannedApproach:
        if combination not in self._planned:
            key = self.key(combination)
            planned = FITTED.take(key) if FITTED else None
            read = False
            if planned is None:
                planned = read_plan(key)
                read = planned is not None
            if planned is None:
                planned = plan_combination(self.robot, self.scene, combination, self.dt, self.world)
            if self.keep and not read:
                keep_plan(key, planned)
            self._planned[combination] = planned
        return self._planned[combination]

    def key(self, combination: Combination) -> str:
        """What a plan of `combination` here depends on, as FITTED's key (verdict_key)."""
        if self._identity is None:
            self._identity = robot_identity(self.robot)
        return verdict_key(self._identity, self.scene, combination, self.dt)

    def hand_on(self) -> None:
        """Every combination planned here kept in FITTED (in place of what it held), for the next Approaches of
        the same robot, scene and step: the fit's, for the command that asked for the scene."""
        FITTED.keep({self.key(combination): planned for combination, planned in self._planned.items()})

    def plan_all(self, combinations: Iterable[Combination]) -> dict[Combination, PlannedApproach]:
        """Each distinct combination planned and checked once, in order."""
        return {combination: self.plan(combination) for combination in dict.fromkeys(combinations)}

    def hand_distance(self, q: np.ndarray) -> float:
        return self.world.hand_distance(q)

    def end_effector(self, q: np.ndarray) -> np.ndarray:
        return self.world.end_effector(q)

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> Approaches:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def check_holds_home(robot: RobotSpec, world: SceneWorld) -> None:
    """DesignError, one line per joint, where the arm's drives cannot hold it still at home, where every session
    starts (sim.study.design.holding): no scene or path helps then, so it is said before any is tried."""
    found = shortfalls(robot.joint_names, robot.joint_types, world.gravity_loads(robot.home)[None], robot.max_effort)
    if found:
        lines = "; ".join(holding_line(short, "at home") for short in found)
        raise DesignError(
            f"{robot.name}: {lines}; to change: a joint that holds the arm (see the URDF's effort limits and masses; "
            "a link without <inertial> weighs 1 kg in pybullet)"
        )


def plan_combinations(
    robot: RobotSpec, scene: Scene, combinations: Iterable[Combination], dt: float
) -> dict[Combination, PlannedApproach]:
    """Each distinct combination planned and checked once, in one scene world."""
    with Approaches(robot, scene, dt) as approaches:
        return approaches.plan_all(combinations)
