"""A logged drive, whatever it was read from: :class:`DriveLog` and the vehicle it was driven by,
:class:`VehicleFile`.

A drive is three streams on one clock (seconds): the camera's frames (``frame_times`` and a way
to read each frame), the wheel odometry (cumulative left and right encoder ticks, or measured
speed v and yaw rate ω, at ``odometry_times``) and, when the log has it, the true pose. A real log
is messy: :func:`clean_times` sorts out duplicated and out-of-order stamps and says what it did.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from localizer.model.mount import CameraMount
from localizer.numeric import check_choice, check_number

__all__ = ["ODOMETRY_KINDS", "DriveLog", "VehicleFile", "clean_times", "increments", "load_vehicle"]

#: how a log gives the odometry: ``ticks`` (cumulative left, right encoder counts) or ``twist``
#: (measured v m/s, ω rad/s over the interval that ends at each stamp)
ODOMETRY_KINDS = ("ticks", "twist")


@dataclass(frozen=True)
class VehicleFile:
    """The vehicle a drive was logged on (a ``vehicle.yaml``).

    Attributes:
        track_width: distance between the drive wheels' contact points (m).
        ticks_per_metre: encoder counts per metre of wheel travel (ticks odometry; 0: not given).
        mount: where the camera sits (:class:`~localizer.model.mount.CameraMount`; yaw in rad).
        odometry: the odometry error preset the filter assumes (one of
            :data:`agvsim.vehicle.encoders.PRESETS`).
    """

    track_width: float = 0.6  # m
    ticks_per_metre: float = 0.0  # counts / m
    mount: CameraMount = field(default_factory=CameraMount)
    odometry: str = "typical"

    def __post_init__(self) -> None:
        from agvsim.vehicle.encoders import PRESETS

        check_number("vehicle track_width", self.track_width, low=0.0, low_open=True, unit="m")
        check_number("vehicle ticks_per_metre", self.ticks_per_metre, low=0.0, unit="counts per metre")
        check_choice("vehicle odometry", self.odometry, PRESETS)

    def to_yaml(self, path: str | os.PathLike) -> None:
        """Write this as a ``vehicle.yaml`` :func:`load_vehicle` reads back."""
        import yaml

        m = self.mount
        data = {"track_width": self.track_width, "ticks_per_metre": self.ticks_per_metre, "odometry": self.odometry,
                "camera_mount": {"forward": m.forward, "lateral": m.lateral, "height": m.height, "yaw": m.yaw}}
        Path(path).write_text("# agvsim vehicle file: SI units (m, rad)\n" + yaml.safe_dump(data, sort_keys=False))


#: the keys of a vehicle file, and of its camera_mount
VEHICLE_KEYS = ("track_width", "ticks_per_metre", "odometry", "camera_mount")
MOUNT_KEYS = ("forward", "lateral", "height", "yaw")


def load_vehicle(path: str | os.PathLike) -> VehicleFile:
    """Read a ``vehicle.yaml`` (:meth:`VehicleFile.to_yaml`). Raises ``ValueError`` in one line
    naming the file and the field: unreadable, cut off, an unknown key, a bad value."""
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise ValueError(f"{path}: not a complete YAML file{where}; expected a vehicle file "
                         f"({', '.join(VEHICLE_KEYS)})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: cut off or not a vehicle file; expected a mapping of {', '.join(VEHICLE_KEYS)}, "
                         f"got {type(data).__name__}")
    unknown = sorted(set(data) - set(VEHICLE_KEYS))
    if unknown:
        raise ValueError(f"{path}: unknown field {unknown[0]!r}; expected {', '.join(VEHICLE_KEYS)}")
    mount = data.get("camera_mount", {})
    if not isinstance(mount, dict) or set(mount) - set(MOUNT_KEYS):
        raise ValueError(f"{path}: camera_mount must be a mapping of {', '.join(MOUNT_KEYS)} (m, rad); got {mount!r}")
    try:
        return VehicleFile(track_width=data.get("track_width", 0.6), ticks_per_metre=data.get("ticks_per_metre", 0.0),
                           mount=CameraMount(**mount), odometry=data.get("odometry", "typical"))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path}: {exc}") from None


@dataclass(frozen=True)
class DriveLog:
    """A logged drive (the module docstring).

    Attributes:
        source: where it was read from (for messages).
        frame_times: (F,) capture stamps of the frames (s), increasing.
        read_frame: ``read_frame(k)`` -> the k-th frame ((H, W) or (H, W, 3) uint8); raises
            ``ValueError`` for a frame that cannot be read.
        odometry_times: (N,) stamps of the odometry (s), increasing.
        odometry: (N, 2): cumulative (left, right) ticks, or (v m/s, ω rad/s) over the interval
            ending at each stamp, as ``odometry_kind`` says.
        odometry_kind: one of :data:`ODOMETRY_KINDS`.
        truth: (M, 4) rows (t s, x m, y m, θ rad) of the true pose, or None.
        notes: what reading the log skipped or repaired, one line each.
    """

    source: str
    frame_times: np.ndarray
    read_frame: Callable[[int], np.ndarray]
    odometry_times: np.ndarray
    odometry: np.ndarray
    odometry_kind: str
    truth: np.ndarray | None = None
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check_choice("odometry kind", self.odometry_kind, ODOMETRY_KINDS)
        if len(self.odometry_times) < 2:
            raise ValueError(f"{self.source}: {len(self.odometry_times)} odometry record(s); expected at least 2")


def clean_times(times: Sequence[float], what: str, source: str) -> tuple[np.ndarray, list[str]]:
    """The order in which to take records stamped ``times`` (s): sorted by stamp, a duplicated
    stamp kept once (the first), non-finite stamps dropped. Returns ``(indices, notes)``, a note
    (one line naming ``source`` and ``what``) for each kind of repair made."""
    t = np.asarray(times, dtype=float)
    notes = []
    finite = np.isfinite(t)
    if not finite.all():
        notes.append(f"{source}: {int((~finite).sum())} {what} with a stamp that is not a number: skipped")
    idx = np.nonzero(finite)[0]
    if np.any(np.diff(t[idx]) < 0):
        notes.append(f"{source}: {what} stamps out of order: taken in time order")
        idx = idx[np.argsort(t[idx], kind="stable")]
    dup = np.concatenate([[False], np.diff(t[idx]) == 0]) if len(idx) else np.zeros(0, bool)
    if dup.any():
        notes.append(f"{source}: {int(dup.sum())} {what} with a duplicated stamp: the first kept")
        idx = idx[~dup]
    return idx, notes


def increments(log: DriveLog, vehicle: VehicleFile) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The odometry as the filter takes it: ``(t, ds, dθ)``, (N - 1,) each: the stamp ending each
    interval (s), the distance (m) and heading change (rad) over it (ticks through
    ``vehicle.ticks_per_metre`` and ``track_width``; a twist times the interval)."""
    t = np.asarray(log.odometry_times, dtype=float)
    o = np.asarray(log.odometry, dtype=float)
    dt = np.diff(t)
    if log.odometry_kind == "ticks":
        if vehicle.ticks_per_metre <= 0:
            raise ValueError(f"{log.source}: odometry in wheel ticks, but the vehicle file gives no ticks_per_metre")
        dl, dr = (np.diff(o[:, k]) / vehicle.ticks_per_metre for k in (0, 1))
        return t[1:], 0.5 * (dl + dr), (dr - dl) / vehicle.track_width
    return t[1:], o[1:, 0] * dt, o[1:, 1] * dt


def gaps(times: np.ndarray, longest: float) -> int:
    """How many intervals between consecutive ``times`` (s) are longer than ``longest`` (s)."""
    return int(np.sum(np.diff(np.asarray(times, dtype=float)) > longest)) if len(times) > 1 else 0

