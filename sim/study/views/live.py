"""The experimenter's live 3-D view: a web page (viser) of the robot from its URDF, the table, the hand, the planned
path of the trial running, the end effector's trail and the stop point, updated live from the joint states
(`python -m sim.study view --port ENDPOINT_PORT [--http-port 8080]`, then open http://localhost:8080).

It is one more client of the endpoint, without rospy, as a Unity scene would be: it subscribes to the robot's joint
states, `/study/trial` and `/study/stop`. The page is updated at most `rate` times a second (in lockstep the joint
states come hundreds of times a second), and once more whenever a trial comes to rest, so the last picture is exact.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from bridge.client import TcpClient
from sim.geometry.frames import matrix_to_quat
from sim.geometry.kinematics import chain_for
from sim.robots import RobotSpec, find_ros_package
from sim.robots.meshes import resolve_filename
from sim.study.design.feasibility import Approaches
from sim.study.design.scene import Box, Scene
from sim.study.errors import StudyError
from sim.study.run.protocol import STATUS_TOPIC, STOP_TOPIC, TOPIC_TYPES, TrialStatus, status_from_json
from sim.wire.contract import STAMP_TOLERANCE_S, STEP_S
from sim.wire.rosmsgs import JOINT_STATE, MessageError, decode_joint_state, deserialize, to_seconds

__all__ = ["COLOURS", "LiveView"]

# Distinct colours (RGB), so that a screenshot can tell the parts apart.
COLOURS = {
    "table": (150, 110, 70),
    "hand": (255, 150, 40),
    "path": (40, 110, 255),
    "trail": (20, 190, 60),
    "stop": (230, 20, 20),
}


def _wxyz(rotation: np.ndarray) -> tuple[float, float, float, float]:
    x, y, z, w = matrix_to_quat(rotation)
    return float(w), float(x), float(y), float(z)


class LiveView:
    def __init__(self, server: Any, robot: RobotSpec, scene: Scene, dt: float = STEP_S, rate: float = 20.0) -> None:
        import yourdfpy
        from viser.extras import ViserUrdf

        self.server, self.robot, self.scene, self.dt = server, robot, scene, dt
        self._chain = chain_for(robot)
        self._min_interval = 1.0 / rate
        self._lock = threading.Lock()
        self._status: TrialStatus | None = None
        self._trial = 0
        self._latest: tuple[float, np.ndarray] | None = None
        # (stamp, end effector in the world, joint positions) of the trial running
        self._trail: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.approaches = Approaches(robot, scene, dt)  # the runner's plans, and the robot's distance to the hand
        self._last_drawn = 0.0
        self._press_stamp: float | None = None  # a press stamped later than the joint states seen so far
        self.updates = 0
        urdf_dir = robot.urdf_path.parent
        urdf = yourdfpy.URDF.load(
            robot.urdf_path,
            build_scene_graph=True,
            load_meshes=True,
            build_collision_scene_graph=False,
            load_collision_meshes=False,
            filename_handler=lambda fname: str(resolve_filename(fname, urdf_dir, find_ros_package) or fname),
        )
        base = scene.base_pose
        server.scene.add_frame("/robot", show_axes=False, position=tuple(base[:3, 3]), wxyz=_wxyz(base[:3, :3]))
        self._urdf = ViserUrdf(server, urdf, root_node_name="/robot")
        self._joint_index = {name: k for k, name in enumerate(self._urdf.get_actuated_joint_names())}
        self._configuration = np.zeros(len(self._joint_index))
        self._add_box("/table", scene.table, COLOURS["table"])
        if scene.pedestal is not None:  # what the robot stands on, the table's colour
            self._add_box("/pedestal", scene.pedestal, COLOURS["table"])
        self._add_box("/hand", scene.hand, COLOURS["hand"])
        # from behind the participant's seat, looking at the space above the hand where the approaches end
        server.initial_camera.position = tuple(scene.seat + 0.3 * (scene.seat - scene.hand.top) + [0.0, 0.0, 0.2])
        server.initial_camera.look_at = tuple(scene.hand.top + np.array([-0.1, 0.0, 0.12]))
        self._draw_robot(robot.home)

    def _add_box(self, name: str, box: Box, colour: tuple[int, int, int]) -> None:
        self.server.scene.add_box(
            name, color=colour, dimensions=tuple(box.size), position=tuple(box.position), wxyz=_wxyz(box.rotation)
        )

    def attach(self, client: TcpClient) -> None:
        client.subscribe(self.robot.joint_states_topic, JOINT_STATE, self._on_joint_state)
        client.subscribe(STATUS_TOPIC, TOPIC_TYPES[STATUS_TOPIC], self._on_status)
        client.subscribe(STOP_TOPIC, TOPIC_TYPES[STOP_TOPIC], self._on_press)

    def end_effector(self, positions: np.ndarray) -> np.ndarray:
        return self.scene.end_effector(self._chain, positions)

    # --- drawing ------------------------------------------------------------------------------------------
    def _draw_robot(self, positions: np.ndarray) -> None:
        for name, value in zip(self.robot.joint_names, positions):
            if name in self._joint_index:
                self._configuration[self._joint_index[name]] = value
        self._urdf.update_cfg(self._configuration)

    def _draw(self, force: bool = False) -> None:
        now = time.monotonic()
        if self._latest is None or (not force and now - self._last_drawn < self._min_interval):
            return
        self._last_drawn = now
        self._draw_robot(self._latest[1])
        if len(self._trail) >= 2:
            points = np.array([point for _, point, _ in self._trail])
            segments = np.stack([points[:-1], points[1:]], axis=1)
            self.server.scene.add_line_segments("/trail", segments, COLOURS["trail"], thickness=0.005)
        self.updates += 1

    def _draw_plan(self, status: TrialStatus) -> None:
        try:
            path = self.approaches.plan((status.path, status.standoff, status.peak_speed)).path
        except StudyError:
            return  # a path this view cannot draw (another scene's); the robot and the trail still show
        points = path.positions[:: max(1, len(path.positions) // 60)]
        points = np.vstack([points, path.positions[-1]])
        self.server.scene.add_spline_catmull_rom("/plan", points, color=COLOURS["path"], thickness=0.01)

    # --- inputs -------------------------------------------------------------------------------------------
    def _on_joint_state(self, payload: bytes) -> None:
        try:
            sample = decode_joint_state(payload, self.robot.joint_names)
        except MessageError:
            return  # another robot's, or incomplete
        stamp, positions = sample.stamp_s, sample.positions
        with self._lock:
            self._latest = (stamp, positions)
            status = self._status
            if status is not None and status.phase in ("moving", "at_rest") and stamp >= status.motion_start:
                self._trail.append((stamp, self.end_effector(positions), positions))
                if self._press_stamp is not None and stamp >= self._press_stamp - STAMP_TOLERANCE_S:
                    self._mark_stop(self._trail[-1][2])
            self._draw()

    def _on_status(self, payload: bytes) -> None:
        message: Any = deserialize(payload, TOPIC_TYPES[STATUS_TOPIC])
        try:
            status = status_from_json(message.data)
        except StudyError:
            return
        with self._lock:
            self._status = status
            if status.phase == "to_start" and status.index != self._trial:
                self._trial = status.index
                self._trail.clear()
                self._press_stamp = None
                for name in ("/trail", "/stop", "/stop_distance"):
                    self.server.scene.remove_by_name(name)
                self._draw_plan(status)
            elif status.phase == "at_rest":
                self._draw(force=True)

    def _on_press(self, payload: bytes) -> None:

        message: Any = deserialize(payload, TOPIC_TYPES[STOP_TOPIC])
        stamp = to_seconds(message.stamp)
        with self._lock:
            if stamp > 0 and (not self._trail or self._trail[-1][0] < stamp):
                self._press_stamp = stamp  # marked when the joint state of that time comes
            elif self._trail:
                # where the end effector was at the press (a zero stamp: when it came)
                self._mark_stop(
                    min(self._trail, key=lambda entry: abs(entry[0] - stamp))[2] if stamp > 0 else self._trail[-1][2]
                )

    def _mark_stop(self, positions: np.ndarray) -> None:
        """The robot's point nearest the hand at the press, and its distance to the hand then (the scene's), drawn
        as a dimension line beside the robot (towards the participant's seat), where the gripper that stopped there
        does not hide it."""
        self._press_stamp = None
        point, nearest = self.approaches.world.nearest_points(positions)
        self.server.scene.add_icosphere("/stop", radius=0.01, color=COLOURS["stop"], position=tuple(point))
        towards_seat = (self.scene.seat - point) * np.array([1.0, 1.0, 0.0])
        offset = 0.05 * towards_seat / max(float(np.linalg.norm(towards_seat)), 1e-9)
        segments = np.array([[point, point + offset], [point + offset, nearest + offset], [nearest + offset, nearest]])
        self.server.scene.add_line_segments("/stop_distance", segments, COLOURS["stop"], thickness=0.005)
