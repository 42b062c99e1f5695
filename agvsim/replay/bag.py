"""A drive logged as a ROS 2 bag, read (:func:`read_bag`) and written (:class:`BagWriter`), through
``rosbags`` (pure Python, no ROS install; the ``rosbag`` extra).

Read: a bag folder (``metadata.yaml`` with MCAP or sqlite3 storage) or a single ``.mcap`` file.
Messages are stamped by their header (``header.stamp``), not by the time they were recorded:

* the image topic: ``sensor_msgs/msg/Image`` (``mono8``, ``8UC1``, ``bgr8``, ``rgb8``) or
  ``sensor_msgs/msg/CompressedImage`` (anything OpenCV decodes);
* the odometry topic: ``nav_msgs/msg/Odometry`` (its twist: ``linear.x`` m/s, ``angular.z``
  rad/s, over the interval ending at the stamp) or ``sensor_msgs/msg/JointState`` (the left and
  right wheel positions, cumulative, in the units the vehicle file's ``ticks_per_metre`` counts:
  for wheel angles in rad, ``ticks_per_metre = 1 / wheel radius``; joints named ``*left*`` and
  ``*right*``, else the first two);
* the truth topic (optional): ``nav_msgs/msg/Odometry`` whose pose is the true pose.

Written (:class:`BagWriter`, ``agvsim demo --export-bag drive.mcap``): one MCAP file with
``/camera/image_raw`` (mono8 Image), ``/odom`` (Odometry, twist) and ``/ground_truth``
(Odometry, pose).
"""
from __future__ import annotations

import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from agvsim.replay.drive import DriveLog, clean_times

__all__ = ["IMAGE_TOPIC", "ODOMETRY_TOPIC", "TRUTH_TOPIC", "BagWriter", "read_bag"]

IMAGE_TOPIC = "/camera/image_raw"
ODOMETRY_TOPIC = "/odom"
TRUTH_TOPIC = "/ground_truth"
#: message types read, by role
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
ODOMETRY_TYPES = ("nav_msgs/msg/Odometry", "sensor_msgs/msg/JointState")


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _yaw(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def decode_image(msg) -> np.ndarray:
    """The pixels of an Image or CompressedImage message ((H, W) or (H, W, 3) uint8, BGR);
    ``ValueError`` for an encoding it does not read."""
    import cv2

    if msg.__msgtype__ == "sensor_msgs/msg/CompressedImage":
        image = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise ValueError(f"a {msg.format!r} CompressedImage OpenCV cannot decode")
        return image
    channels = {"mono8": 1, "8UC1": 1, "bgr8": 3, "rgb8": 3}.get(msg.encoding)
    if channels is None:
        raise ValueError(f"an Image of encoding {msg.encoding!r}; expected mono8, 8UC1, bgr8 or rgb8")
    data = np.asarray(msg.data, dtype=np.uint8)
    if data.size < msg.step * msg.height or msg.step < msg.width * channels:
        raise ValueError(f"an Image whose data ({data.size} bytes) is shorter than its {msg.width} x {msg.height} "
                         f"{msg.encoding} pixels")
    rows = data[:msg.step * msg.height].reshape(msg.height, msg.step)[:, :msg.width * channels]
    image = rows.reshape(msg.height, msg.width, channels) if channels == 3 else rows.reshape(msg.height, msg.width)
    return np.ascontiguousarray(image[:, :, ::-1] if msg.encoding == "rgb8" else image)


def _wheels(msg) -> tuple[float, float]:
    names = [n.lower() for n in msg.name]
    left = next((i for i, n in enumerate(names) if "left" in n), 0)
    right = next((i for i, n in enumerate(names) if "right" in n), 1)
    if len(msg.position) < 2:
        raise ValueError("a JointState with fewer than two positions")
    return float(msg.position[left]), float(msg.position[right])


def _topics(reader, source: str, image_topic: str, odometry_topic: str) -> dict:
    by_topic = {c.topic: c for c in reader.connections}
    for topic, types, flag in ((image_topic, IMAGE_TYPES, "--image-topic"),
                               (odometry_topic, ODOMETRY_TYPES, "--odometry-topic")):
        if topic not in by_topic:
            raise ValueError(f"{source}: no topic {topic!r} ({flag}); the bag has "
                             + (", ".join(f"{t} ({c.msgtype})" for t, c in sorted(by_topic.items())) or "no topics"))
        if by_topic[topic].msgtype not in types:
            raise ValueError(f"{source}: {flag} {topic!r} holds {by_topic[topic].msgtype}; expected "
                             + " or ".join(types))
    return by_topic


def read_bag(path: str | os.PathLike, image_topic: str = IMAGE_TOPIC, odometry_topic: str = ODOMETRY_TOPIC,
             truth_topic: str = TRUTH_TOPIC) -> DriveLog:
    """The drive in the bag at ``path`` (the module docstring). Raises ``ValueError`` in one line
    naming the bag for one that cannot be opened, a missing topic or one of another type."""
    from rosbags.highlevel import AnyReader

    source = str(path)
    try:
        reader = AnyReader([Path(path)], default_typestore=_typestore())
        reader.open()
    except Exception as exc:  # rosbags raises its own types for a bag it cannot read
        raise ValueError(f"{source}: cannot be read as a ROS 2 bag ({type(exc).__name__}: {exc})") from None
    try:
        by_topic = _topics(reader, source, image_topic, odometry_topic)
        wanted = [by_topic[t] for t in (image_topic, odometry_topic, truth_topic) if t in by_topic]
        frames, odo, truth = [], [], []
        kind = "ticks" if by_topic[odometry_topic].msgtype == "sensor_msgs/msg/JointState" else "twist"
        for con, _, raw in reader.messages(connections=wanted):
            msg = reader.deserialize(raw, con.msgtype)
            if con.topic == image_topic:
                frames.append((_stamp(msg), msg))
            elif con.topic == odometry_topic:
                odo.append((_stamp(msg), *(_wheels(msg) if kind == "ticks" else
                                           (msg.twist.twist.linear.x, msg.twist.twist.angular.z))))
            elif con.msgtype == "nav_msgs/msg/Odometry":
                p = msg.pose.pose
                truth.append((_stamp(msg), p.position.x, p.position.y, _yaw(p.orientation)))
    except Exception as exc:
        if isinstance(exc, ValueError):
            raise
        raise ValueError(f"{source}: cut off or not readable ({type(exc).__name__}: {exc})") from None
    finally:
        reader.close()
    notes = []
    order, n = clean_times([f[0] for f in frames], "frames", source)
    notes += n
    frames = [frames[i] for i in order]
    odo = np.array(odo, dtype=float).reshape(-1, 3)
    o_order, n = clean_times(odo[:, 0], "odometry messages", source)
    notes += n
    odo = odo[o_order]
    truth_rows = None
    if truth:
        truth_rows = np.array(truth, dtype=float)
        truth_rows = truth_rows[clean_times(truth_rows[:, 0], "truth messages", source)[0]]

    def read_frame(k: int) -> np.ndarray:
        try:
            return decode_image(frames[k][1])
        except ValueError as exc:
            raise ValueError(f"{source}: frame {k} on {image_topic}: {exc}") from None

    return DriveLog(source, np.array([f[0] for f in frames], dtype=float), read_frame, odo[:, 0], odo[:, 1:],
                    kind, truth_rows, tuple(notes))


class BagWriter:
    """Writes a drive as one MCAP file (a ROS 2 bag's storage; the module docstring), as it is
    driven. The bag is written in a temporary folder and its file moved to ``path`` by
    :meth:`close` (an interrupted export leaves no half-written file under ``path``)."""

    def __init__(self, path: str | os.PathLike) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=".tmp-bag-", dir=self.path.parent))
        self.ts = _typestore()
        self.writer = Writer(self._tmp / "bag", version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        types = self.ts.types
        self._types = {k: types[k] for k in ("sensor_msgs/msg/Image", "nav_msgs/msg/Odometry",
                                             "std_msgs/msg/Header", "builtin_interfaces/msg/Time")}
        self._con = {topic: self.writer.add_connection(topic, msgtype, typestore=self.ts) for topic, msgtype in
                     ((IMAGE_TOPIC, "sensor_msgs/msg/Image"), (ODOMETRY_TOPIC, "nav_msgs/msg/Odometry"),
                      (TRUTH_TOPIC, "nav_msgs/msg/Odometry"))}
        self.open = True

    def _header(self, t: float, frame_id: str):
        ns = int(round(t * 1e9))
        Time, Header = self._types["builtin_interfaces/msg/Time"], self._types["std_msgs/msg/Header"]
        return Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame_id), ns

    def _write(self, topic: str, msg, ns: int) -> None:
        self.writer.write(self._con[topic], ns, self.ts.serialize_cdr(msg, msg.__msgtype__))

    def _odometry(self, t: float, pose, twist, frame_id: str):
        from rosbags.typesys.stores.ros2_humble import (geometry_msgs__msg__Point as Point,
                                                        geometry_msgs__msg__Pose as Pose,
                                                        geometry_msgs__msg__PoseWithCovariance as PoseCov,
                                                        geometry_msgs__msg__Quaternion as Quaternion,
                                                        geometry_msgs__msg__Twist as Twist,
                                                        geometry_msgs__msg__TwistWithCovariance as TwistCov,
                                                        geometry_msgs__msg__Vector3 as Vector3)

        header, ns = self._header(t, frame_id)
        x, y, th = pose
        q = Quaternion(x=0.0, y=0.0, z=math.sin(0.5 * th), w=math.cos(0.5 * th))
        msg = self._types["nav_msgs/msg/Odometry"](
            header=header, child_frame_id="base_link",
            pose=PoseCov(pose=Pose(position=Point(x=float(x), y=float(y), z=0.0), orientation=q),
                         covariance=np.zeros(36)),
            twist=TwistCov(twist=Twist(linear=Vector3(x=float(twist[0]), y=0.0, z=0.0),
                                       angular=Vector3(x=0.0, y=0.0, z=float(twist[1]))), covariance=np.zeros(36)))
        return msg, ns

    def describe(self, vehicle, camera) -> None:
        """The vehicle (:class:`~agvsim.replay.drive.VehicleFile`) and the camera: a bag carries
        neither, so they are written beside the bag file as ``vehicle.yaml`` and ``camera.yaml``
        (where ``agvsim track`` looks for them), unless files of those names are there."""
        folder = self.path.parent
        if not (folder / "vehicle.yaml").exists():
            vehicle.to_yaml(folder / "vehicle.yaml")
        if not (folder / "camera.yaml").exists():
            camera.to_opencv_yaml(folder / "camera.yaml")

    def odometry(self, t: float, v: float, omega: float) -> None:
        msg, ns = self._odometry(t, (0.0, 0.0, 0.0), (v, omega), "odom")
        self._write(ODOMETRY_TOPIC, msg, ns)

    def truth(self, t: float, pose) -> None:
        msg, ns = self._odometry(t, pose, (0.0, 0.0), "map")
        self._write(TRUTH_TOPIC, msg, ns)

    def frame(self, t: float, image: np.ndarray) -> None:
        header, ns = self._header(t, "camera")
        h, w = image.shape[:2]
        encoding = "mono8" if image.ndim == 2 else "bgr8"
        msg = self._types["sensor_msgs/msg/Image"](header=header, height=h, width=w, encoding=encoding, is_bigendian=0,
                                                   step=w * (1 if image.ndim == 2 else 3),
                                                   data=np.ascontiguousarray(image).reshape(-1))
        self._write(IMAGE_TOPIC, msg, ns)

    def close(self, keep: bool = True) -> None:
        """Finish the bag and move its MCAP file to ``path`` (``keep``), or remove it."""
        if not self.open:
            return
        self.open = False
        self.writer.close()
        if keep:
            os.replace(self._tmp / "bag" / "bag.mcap", self.path)
        shutil.rmtree(self._tmp, ignore_errors=True)
