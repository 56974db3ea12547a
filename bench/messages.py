"""The benchmarks' ROS messages: the test messages, their stamp/sequence fields, and pacing.

The messages are serialized ROS 1 messages of the kinds in MESSAGE_KINDS, among them a 7-joint
sensor_msgs/JointState (small control traffic), a 1280x720 RGB sensor_msgs/Image (2.7 MB, a camera) and a 1 MiB
sensor_msgs/PointCloud2 (a depth sensor). The first 12 bytes of a ROS 1 serialized message with a Header are
`u32 seq, u32 secs, u32 nsecs`; the benchmark writes a sequence number and a CLOCK_MONOTONIC time stamp there
(monotonic time is shared by all processes of one Linux machine), so any process can compute one-way latency or a
round-trip time from the bytes alone, without deserializing.
"""

from __future__ import annotations

import io
import struct
import time
from collections.abc import Callable, Iterator

MESSAGE_NAME = "sensor_msgs/JointState"
JOINTS = 7
IMAGE_WIDTH, IMAGE_HEIGHT = 1280, 720  # rgb8: 2,764,800 bytes of pixels
CLOUD_POINTS = 65536  # x, y, z, intensity as float32: 1 MiB of points
_SEQ_STAMP = struct.Struct("<III")
_NS_PER_S = 1_000_000_000


def joint_state_payload() -> bytes:
    """One serialized 7-joint JointState (names, positions, velocities, efforts), as a robot arm sends it."""
    from sensor_msgs.msg import JointState  # generated ROS 1 class; imported late so --help needs no ROS

    message = JointState()
    message.header.frame_id = "base_link"
    message.name = [f"panda_joint{i + 1}" for i in range(JOINTS)]
    message.position = [0.1 * i for i in range(JOINTS)]
    message.velocity = [0.01 * i for i in range(JOINTS)]
    message.effort = [1.0 * i for i in range(JOINTS)]
    return _serialized(message)


def image_payload() -> bytes:
    """One serialized 1280x720 rgb8 Image (a camera frame)."""
    from sensor_msgs.msg import Image

    message = Image(height=IMAGE_HEIGHT, width=IMAGE_WIDTH, encoding="rgb8", step=IMAGE_WIDTH * 3)
    message.header.frame_id = "camera_color_optical_frame"
    message.data = bytes(range(256)) * (IMAGE_WIDTH * IMAGE_HEIGHT * 3 // 256)
    return _serialized(message)


def cloud_payload() -> bytes:
    """One serialized PointCloud2 of CLOUD_POINTS points (x, y, z, intensity; 1 MiB of point data)."""
    from sensor_msgs.msg import PointCloud2, PointField

    fields = [
        PointField(name=name, offset=4 * index, datatype=PointField.FLOAT32, count=1)
        for index, name in enumerate(("x", "y", "z", "intensity"))
    ]
    message = PointCloud2(
        height=1,
        width=CLOUD_POINTS,
        fields=fields,
        is_bigendian=False,
        point_step=16,
        row_step=16 * CLOUD_POINTS,
        is_dense=True,
    )
    message.header.frame_id = "camera_depth_optical_frame"
    message.data = bytes(range(256)) * (16 * CLOUD_POINTS // 256)
    return _serialized(message)


def vga_image_payload() -> bytes:
    """One serialized 640x480 rgb8 Image (921,600 bytes of pixels: a headset's or a webcam's camera stream)."""
    from sensor_msgs.msg import Image

    message = Image(height=480, width=640, encoding="rgb8", step=640 * 3)
    message.header.frame_id = "camera_color_optical_frame"
    message.data = bytes(range(256)) * (640 * 480 * 3 // 256)
    return _serialized(message)


def tf_payload() -> bytes:
    """One serialized tf2_msgs/TFMessage of a 7-joint arm's link transforms (header stamps inside each)."""
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    transforms = []
    for index in range(JOINTS + 1):
        transform = TransformStamped()
        transform.header.frame_id = f"panda_link{index}"
        transform.child_frame_id = f"panda_link{index + 1}"
        transform.transform.translation.z = 0.1
        transform.transform.rotation.w = 1.0
        transforms.append(transform)
    return _serialized(TFMessage(transforms=transforms))


def pose_payload() -> bytes:
    """One serialized geometry_msgs/PoseStamped (a tracked controller or headset)."""
    from geometry_msgs.msg import PoseStamped

    message = PoseStamped()
    message.header.frame_id = "world"
    message.pose.position.x, message.pose.orientation.w = 0.5, 1.0
    return _serialized(message)


def _serialized(message: object) -> bytes:
    buffer = io.BytesIO()
    message.serialize(buffer)  # type: ignore[attr-defined]
    return buffer.getvalue()


# kind -> (ROS message type, maker of one serialized message)
MESSAGE_KINDS: dict[str, tuple[str, Callable[[], bytes]]] = {
    "joint_state": (MESSAGE_NAME, joint_state_payload),
    "image": ("sensor_msgs/Image", image_payload),
    "cloud": ("sensor_msgs/PointCloud2", cloud_payload),
    "vga_image": ("sensor_msgs/Image", vga_image_payload),
    "tf": ("tf2_msgs/TFMessage", tf_payload),
    "pose": ("geometry_msgs/PoseStamped", pose_payload),
}
# Where a kind's (first) header is: after the transforms' array length for TF, at the start for the others.
HEADER_OFFSETS = {"tf": 4}


def stamped(template: bytes | bytearray, seq: int, now_ns: int | None = None, offset: int = 0) -> bytes:
    """`template` with header.seq = seq and header.stamp = now (monotonic), the header being at `offset`."""
    buffer = bytearray(template)
    stamp_ns = time.monotonic_ns() if now_ns is None else now_ns
    _SEQ_STAMP.pack_into(buffer, offset, seq & 0xFFFFFFFF, stamp_ns // _NS_PER_S, stamp_ns % _NS_PER_S)
    return bytes(buffer)


def read_stamp(payload: bytes, offset: int = 0) -> tuple[int, int]:
    """(seq, monotonic stamp in ns) written by `stamped`."""
    seq, secs, nsecs = _SEQ_STAMP.unpack_from(payload, offset)
    return seq, secs * _NS_PER_S + nsecs


def paced(rate_hz: float, count: int, max_seconds: float) -> Iterator[int]:
    """Yield 0..count-1 on a fixed schedule of `rate_hz` (no catch-up bursts), stopping after `max_seconds`."""
    period = 1.0 / rate_hz
    start = time.monotonic()
    deadline = start + max_seconds
    for index in range(count):
        now = time.monotonic()
        if now > deadline:
            return
        target = start + index * period
        if target > now:
            time.sleep(target - now)
        yield index
