"""Message and service classes for types whose generated Python was never built or sourced, from their definitions.

The ROS tools' own sources of a definition: the .msg/.srv files of packages on ROS_PACKAGE_PATH (found with
rospkg; genmsg loads them with everything they depend on and computes the md5sum), or, for a topic, the full
definition a publisher sends in its connection header. genpy.dynamic then generates the classes in memory, as
rostopic does. Imports neither socket nor rospy.
"""

from __future__ import annotations

import importlib.util
import os
import threading
from typing import Any, Dict, List

import genmsg
import genmsg.msg_loader
import genpy
import genpy.dynamic
import rospkg

from bridge.errors import BridgeError

__all__ = [
    "DefinitionError",
    "split_type_name",
    "RosPackages",
    "message_class_from_files",
    "message_class_from_text",
    "service_class_from_files",
]


class DefinitionError(BridgeError, LookupError):
    """No definition of the type could be found or read; the text says where it was looked for."""


class _PackageDirs(Dict[str, List[str]]):
    """genmsg's search path (package -> directories of its .msg and .srv files), filled in from ROS_PACKAGE_PATH as
    genmsg asks for packages, so only the packages a type depends on are looked up."""

    def __init__(self) -> None:
        super().__init__()
        self._rospack = rospkg.RosPack()

    def __contains__(self, package: object) -> bool:
        if not isinstance(package, str):
            return False
        if not super().__contains__(package):
            try:
                path = self._rospack.get_path(package)
            except rospkg.ResourceNotFound:
                return False
            self[package] = [os.path.join(path, "msg"), os.path.join(path, "srv")]
        return True


class RosPackages:
    """Which packages are ROS packages: those rospack finds (ROS_PACKAGE_PATH, or the install's share directory),
    and those whose Python holds generated message or service modules (Debian's python3-*-msgs ship only those).
    Found from the files alone, so deciding never imports anything: a client's type name may only ever import the
    `<package>.msg` or `.srv` module genpy generated (importing a module runs its code)."""

    def __init__(self) -> None:
        self._rospack = rospkg.RosPack()
        self._lock = threading.Lock()  # RosPack's first look-up crawls the package path; once

    def exists(self, package: str) -> bool:
        with self._lock:
            try:
                self._rospack.get_path(package)
            except rospkg.ResourceNotFound:
                return False
        return True

    @staticmethod
    def has_generated(package: str, kind: str, type_name: str) -> bool:
        """Whether `package`'s Python (found, not imported) has the generated module of `type_name` in its `kind`
        ("msg" or "srv") subpackage, as genpy writes it: <package>/<kind>/_<Type>.py."""
        try:
            spec = importlib.util.find_spec(package)  # a top-level name: finding it runs nothing
        except (ImportError, ValueError):
            return False
        if spec is None or not spec.submodule_search_locations:
            return False
        return any(
            os.path.isfile(os.path.join(directory, kind, f"_{type_name}.py"))
            for directory in spec.submodule_search_locations
        )


def split_type_name(name: str) -> tuple[str, str]:
    """('package', 'Type') of 'package/Type'; DefinitionError for anything else."""
    package, _, type_name = name.partition("/")
    if not package or not type_name or "/" in type_name:
        raise DefinitionError(f"type name {name!r} is not of the form 'package/Type'")
    return package, type_name


def _where(package: str, kind: str, type_name: str) -> str:
    return (
        f"no {package}/{kind}/{type_name}.{kind} in the packages on ROS_PACKAGE_PATH "
        f"({os.environ.get('ROS_PACKAGE_PATH') or 'not set'})"
    )


def message_class_from_text(message_name: str, full_text: str) -> Any:
    """The class of `message_name` generated from its full definition (the .msg text followed by those of the
    types it uses, as `_full_text` and connection headers carry it)."""
    try:
        classes = genpy.dynamic.generate_dynamic(message_name, full_text)
    except (genmsg.InvalidMsgSpec, genmsg.MsgGenerationException, genpy.MessageException, ValueError) as error:
        raise DefinitionError(f"the definition of {message_name} does not parse: {error}") from None
    if message_name not in classes:
        raise DefinitionError(f"the definition given for {message_name} does not define it")
    return classes[message_name]


def _load(name: str, kind: str) -> tuple[Any, Any]:
    """(genmsg context, spec) of the message (kind "msg") or service ("srv") `name`, with everything it uses
    loaded, from the files on ROS_PACKAGE_PATH."""
    package, type_name = split_type_name(name)
    context = genmsg.MsgContext.create_default()
    search_path = _PackageDirs()
    load = genmsg.msg_loader.load_msg_by_type if kind == "msg" else genmsg.msg_loader.load_srv_by_type
    try:
        spec = load(context, name, search_path)
        genmsg.msg_loader.load_depends(context, spec, search_path)
    except genmsg.MsgNotFound:
        raise DefinitionError(_where(package, kind, type_name)) from None
    except (genmsg.InvalidMsgSpec, OSError) as error:
        raise DefinitionError(f"{name}: {error}") from None
    return context, spec


def message_class_from_files(message_name: str) -> Any:
    """The class of `message_name` from its .msg file and those of its dependencies, on ROS_PACKAGE_PATH."""
    context, spec = _load(message_name, "msg")
    return message_class_from_text(message_name, genmsg.compute_full_text(context, spec))


def service_class_from_files(service_type: str) -> Any:
    """A service class of `service_type` (its type, md5sum, request and response classes) from its .srv file and
    the .msg files it depends on, on ROS_PACKAGE_PATH."""
    context, spec = _load(service_type, "srv")
    request = message_class_from_text(f"{service_type}Request", genmsg.compute_full_text(context, spec.request))
    response = message_class_from_text(f"{service_type}Response", genmsg.compute_full_text(context, spec.response))
    type_name = split_type_name(service_type)[1]
    return type(
        type_name,
        (),
        {
            "_type": service_type,
            "_md5sum": genmsg.compute_md5(context, spec),
            "_request_class": request,
            "_response_class": response,
        },
    )
