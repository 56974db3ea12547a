"""control_msgs' types for a trajectory controller, generated at run time from the definitions this package carries.

Debian packages no control_msgs, so its definitions that a ros_control trajectory controller speaks are carried in
sim/wire/interfaces/control_msgs: FollowJointTrajectory.action, JointTolerance.msg,
JointTrajectoryControllerState.msg and QueryTrajectoryState.srv. ROS's own tools make the classes: genmsg parses the
definitions (the .action expanded into its seven messages, as actionlib_msgs' genaction does) and computes the
md5sums and full texts, and genpy.dynamic generates the classes in memory, as rostopic does for types it never saw.
The types they use (std_msgs/Header, actionlib_msgs/GoalID and GoalStatus, trajectory_msgs) come from the installed
Python messages' own full texts. Imports genmsg and genpy, never rospy: only the nodes that serve or call the
controller import this module.

`joint_trajectory` builds the trajectory_msgs/JointTrajectory that every client of the controller sends (the study's
link, the braking bench, the tests) from planned samples: one builder, so that they all send the same message.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import actionlib_msgs.msg
import genmsg
import genmsg.msg_loader
import genpy
import genpy.dynamic
import numpy as np
import std_msgs.msg
import trajectory_msgs.msg

from sim.errors import SimError

__all__ = [
    "PACKAGE",
    "DEFINITIONS",
    "ControlTypesError",
    "ControlTypes",
    "action_messages",
    "control_types",
    "joint_trajectory",
]

PACKAGE = "control_msgs"
DEFINITIONS = Path(__file__).resolve().parent / "interfaces" / PACKAGE
ACTION = "FollowJointTrajectory"
_SEPARATOR = "=" * 80


class ControlTypesError(SimError, ValueError):
    """A carried definition that does not parse or does not have the shape it must."""


def action_messages(action: str, text: str) -> dict[str, str]:
    """The seven message definitions of an action (`text` is its .action file): Goal, Result, Feedback and the
    ActionGoal, ActionResult, ActionFeedback and Action that actionlib sends, by type name within the package."""
    sections = [section.strip("\n") for section in _split_action(text)]
    if len(sections) != 3:
        raise ControlTypesError(f"{action}.action has {len(sections)} sections, not goal, result and feedback")
    goal, result, feedback = sections
    return {
        f"{action}Goal": goal,
        f"{action}Result": result,
        f"{action}Feedback": feedback,
        f"{action}ActionGoal": f"Header header\nactionlib_msgs/GoalID goal_id\n{action}Goal goal\n",
        f"{action}ActionResult": f"Header header\nactionlib_msgs/GoalStatus status\n{action}Result result\n",
        f"{action}ActionFeedback": f"Header header\nactionlib_msgs/GoalStatus status\n{action}Feedback feedback\n",
        f"{action}Action": (
            f"{action}ActionGoal action_goal\n{action}ActionResult action_result\n"
            f"{action}ActionFeedback action_feedback\n"
        ),
    }


def _split_action(text: str) -> list[str]:
    sections: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.strip() == "---":
            sections.append([])
        else:
            sections[-1].append(line)
    return ["\n".join(lines) + "\n" for lines in sections]


def _register_full_text(context: Any, full_text: str, name: str) -> None:
    """Register `name` and every type its full text (as generated Python carries it in `_full_text`) defines."""
    sections = full_text.split("\n" + _SEPARATOR + "\n")
    definitions = [(name, sections[0])]
    for section in sections[1:]:
        first, _, rest = section.partition("\n")
        definitions.append((first[len("MSG: ") :].strip(), rest))
    for type_name, text in definitions:
        if not context.is_registered(type_name):
            context.register(type_name, genmsg.msg_loader.load_msg_from_string(context, text, type_name))


@dataclass(frozen=True)
class ControlTypes:
    """The generated classes, by what a trajectory controller and its clients need of them."""

    action: Any  # control_msgs/FollowJointTrajectoryAction: what actionlib's servers and clients take
    goal: Any
    result: Any
    feedback: Any
    action_goal: Any
    action_result: Any
    action_feedback: Any
    joint_tolerance: Any
    controller_state: Any  # control_msgs/JointTrajectoryControllerState
    query_state: Any  # control_msgs/QueryTrajectoryState (a service class: _type, _md5sum, request and response)
    query_state_request: Any
    query_state_response: Any
    md5sums: dict[str, str]  # every generated type's md5sum by its name, the service's too


def _message(context: Any, name: str) -> tuple[Any, str]:
    spec = context.get_registered(name)
    try:
        genmsg.msg_loader.load_depends(context, spec, {})
        full_text = genmsg.compute_full_text(context, spec)
        md5 = genmsg.compute_md5(context, spec)
    except (genmsg.InvalidMsgSpec, genmsg.MsgNotFound, KeyError) as error:
        raise ControlTypesError(f"{name}: {error}") from None
    cls = genpy.dynamic.generate_dynamic(name, full_text)[name]
    if cls._md5sum != md5:
        raise ControlTypesError(f"{name}: genpy's md5sum {cls._md5sum} is not genmsg's {md5}")
    return cls, md5


@functools.lru_cache(maxsize=1)
def control_types() -> ControlTypes:
    """The classes, generated once per process."""
    context = genmsg.MsgContext.create_default()
    for cls in (std_msgs.msg.Header, actionlib_msgs.msg.GoalID, actionlib_msgs.msg.GoalStatus):
        _register_full_text(context, cls._full_text, cls._type)
    _register_full_text(
        context, trajectory_msgs.msg.JointTrajectory._full_text, trajectory_msgs.msg.JointTrajectory._type
    )
    texts = action_messages(ACTION, (DEFINITIONS / "action" / f"{ACTION}.action").read_text())
    for path in sorted((DEFINITIONS / "msg").glob("*.msg")):
        texts[path.stem] = path.read_text()
    try:
        for type_name, text in texts.items():
            name = f"{PACKAGE}/{type_name}"
            context.register(name, genmsg.msg_loader.load_msg_from_string(context, text, name))
        srv_name = f"{PACKAGE}/QueryTrajectoryState"
        srv = genmsg.msg_loader.load_srv_from_string(
            context, (DEFINITIONS / "srv" / "QueryTrajectoryState.srv").read_text(), srv_name
        )
        genmsg.msg_loader.load_depends(context, srv, {})
    except (genmsg.InvalidMsgSpec, genmsg.MsgNotFound) as error:
        raise ControlTypesError(f"the carried control_msgs definitions do not parse: {error}") from None
    classes: dict[str, Any] = {}
    md5sums: dict[str, str] = {}
    for type_name in texts:
        name = f"{PACKAGE}/{type_name}"
        classes[type_name], md5sums[name] = _message(context, name)
    request = genpy.dynamic.generate_dynamic(f"{srv_name}Request", genmsg.compute_full_text(context, srv.request))[
        f"{srv_name}Request"
    ]
    response = genpy.dynamic.generate_dynamic(f"{srv_name}Response", genmsg.compute_full_text(context, srv.response))[
        f"{srv_name}Response"
    ]
    md5sums[srv_name] = genmsg.compute_md5(context, srv)
    md5sums[f"{srv_name}Request"] = request._md5sum
    md5sums[f"{srv_name}Response"] = response._md5sum
    service = type(
        "QueryTrajectoryState",
        (),
        {"_type": srv_name, "_md5sum": md5sums[srv_name], "_request_class": request, "_response_class": response},
    )
    return ControlTypes(
        action=classes[f"{ACTION}Action"],
        goal=classes[f"{ACTION}Goal"],
        result=classes[f"{ACTION}Result"],
        feedback=classes[f"{ACTION}Feedback"],
        action_goal=classes[f"{ACTION}ActionGoal"],
        action_result=classes[f"{ACTION}ActionResult"],
        action_feedback=classes[f"{ACTION}ActionFeedback"],
        joint_tolerance=classes["JointTolerance"],
        controller_state=classes["JointTrajectoryControllerState"],
        query_state=service,
        query_state_request=request,
        query_state_response=response,
        md5sums=md5sums,
    )


def joint_trajectory(
    joint_names: Sequence[str],
    times: Any,
    positions: Any,
    velocities: Any = None,
    accelerations: Any = None,
    stamp: float = 0.0,
) -> trajectory_msgs.msg.JointTrajectory:
    """A JointTrajectory of the samples: `times` (M,) s from the start, each point's `positions` (M, dof) and, when
    given, `velocities` and `accelerations` alike (a controller then interpolates with cubics or quintics, without
    steps). `stamp` s of ROS time is when it starts; 0: at the controller's next update. M may be 0 (an empty
    trajectory: "hold"). ControlTypesError names a sample array of the wrong shape or a value that is not finite."""
    names = list(joint_names)
    t = np.asarray(times, dtype=float).reshape(-1)
    arrays = {"positions": positions, "velocities": velocities, "accelerations": accelerations}
    given: dict[str, np.ndarray] = {}
    for what, values in arrays.items():
        if values is None:
            continue
        array = np.asarray(values, dtype=float)
        if array.shape != (len(t), len(names)):
            raise ControlTypesError(
                f"a trajectory's {what} must be {len(t)} points of {len(names)} joints, got shape {array.shape}"
            )
        given[what] = array
    if "positions" not in given:
        raise ControlTypesError("a trajectory's points need positions")
    if not (all(np.all(np.isfinite(array)) for array in (t, *given.values())) and math.isfinite(stamp) and stamp >= 0):
        raise ControlTypesError(f"a trajectory's times, samples and stamp must be finite (stamp >= 0), got {stamp!r}")
    message = trajectory_msgs.msg.JointTrajectory()
    message.header.stamp = genpy.Time.from_sec(stamp) if stamp > 0 else genpy.Time(0)
    message.joint_names = names
    for k in range(len(t)):
        point = trajectory_msgs.msg.JointTrajectoryPoint()
        for what, array in given.items():
            setattr(point, what, array[k].tolist())
        point.time_from_start = genpy.Duration.from_sec(float(t[k]))
        message.points.append(point)
    return message
