"""Command-line arguments shared by the subcommands (choice lists read from where they are defined)."""
from __future__ import annotations

import argparse

__all__ = ["MOUNT_PRESETS", "add_mount_flag", "check_pose_on_map", "check_route", "image_writer", "number",
           "parse_mount", "write_image"]

#: Named mounts for ``--camera-mount`` besides ``map`` and explicit fields.
MOUNT_PRESETS: tuple[str, ...] = ("map", "forward", "left", "right")


def parse_mount(text: str, height: float = 1.2):
    """``map`` (None: the map's recommended mount), ``forward``, ``left``, ``right`` or
    ``forward=F,lateral=L,height=H,yaw=Y`` (m, m, m, rad) -> a CameraMount or None.

    Raises:
        argparse.ArgumentTypeError: one line naming the bad part.
    """
    from localizer.model.mount import CameraMount

    text = text.strip()
    if text == "map":
        return None
    if text == "forward":
        return CameraMount.forward_looking(height=height)
    if text in ("left", "right"):
        return CameraMount.side_looking(text, height=height)
    fields = {}
    known = ("forward", "lateral", "height", "yaw", "pitch_sigma", "roll_sigma")
    for part in text.split(","):
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep or key not in known:
            raise argparse.ArgumentTypeError(
                f"{part!r}: expected one of {', '.join(MOUNT_PRESETS)} or "
                f"KEY=VALUE pairs with keys {', '.join(known)} (m, rad)")
        try:
            fields[key] = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{key}={value!r}: expected a number") from None
    try:
        return CameraMount(**fields)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_mount_flag(parser, default: str = "map", flag: str = "--camera-mount") -> None:
    """Add ``--camera-mount`` (parsed by :func:`parse_mount`; the result is None for ``map``)."""
    parser.add_argument(flag, dest="camera_mount", type=parse_mount, default=parse_mount(default),
                        metavar="MOUNT",
                        help="where the camera sits: map (the map's recommended mount), forward, left, right, "
                             "or forward=F,lateral=L,height=H,yaw=Y in m and rad "
                             f"(default: {default})")


def add_backend_flag(parser) -> None:
    """``--backend`` for the renderer of ``rendered`` frames (choices and help from the one list)."""
    from agvsim.sensors.backends import BACKENDS, DEFAULT_BACKEND

    parser.add_argument("--backend", default=DEFAULT_BACKEND, choices=tuple(BACKENDS),
                        help="renderer of rendered frames: " + "; ".join(f"{k}: {v}" for k, v in BACKENDS.items())
                        + " (default: %(default)s)")


def number(low: float | None = None, high: float | None = None, *, low_open: bool = False, integer: bool = False,
           unit: str = ""):
    """An argparse ``type=`` for a number within bounds (checked by
    :func:`localizer.numeric.check_number`): a bad value is one line, ``argument --lens: expected a
    finite number > 0 (mm), got '0'``."""
    from localizer.numeric import check_number

    def parse(text: str):
        try:
            value = float(text)
        except ValueError:
            value = text
        try:
            return check_number("value", value, low=low, high=high, low_open=low_open, integer=integer, unit=unit)
        except ValueError as exc:
            expected = str(exc).split(" must be ", 1)[1].rsplit(", got ", 1)[0]
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None

    parse.__name__ = "whole number" if integer else "number"  # (argparse names the type in some messages)
    return parse


def check_route(world_map, name: str, flag: str = "--route") -> str:
    """``name`` if ``world_map`` has that route, else one ``ValueError`` naming the flag, the map's
    routes and the nearest."""
    from localizer.numeric import check_choice

    if not world_map.routes:
        raise ValueError(f"{flag} {name}: map {world_map.name!r} has no routes; expected a map with a 'routes' "
                         "section (maps/README.md)")
    return check_choice(f"{flag} (map {world_map.name!r})", name, world_map.routes)


def check_pose_on_map(world_map, pose, flag: str = "--pose") -> tuple[float, float, float]:
    """``(x, y, theta)`` if ``(x, y)`` lies inside ``world_map``'s bounds, else one ``ValueError``."""
    x, y, theta = (float(v) for v in pose)
    xmin, ymin, xmax, ymax = world_map.bounds
    if not (xmin <= x <= xmax and ymin <= y <= ymax):
        raise ValueError(f"{flag} {x:g} {y:g} {theta:g}: the point ({x:g}, {y:g}) m is outside map "
                         f"{world_map.name!r}; expected x in {xmin:g}..{xmax:g} m and y in {ymin:g}..{ymax:g} m")
    return x, y, theta


def image_writer(path, flag: str):
    """``path`` (a :class:`pathlib.Path`) ready for ``cv2.imwrite``: its folder created, and a
    ``ValueError`` naming the flag unless OpenCV has a writer for its extension."""
    from pathlib import Path

    import cv2

    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{flag} {str(path)!r}: a folder, expected an image file name")
    if not cv2.haveImageWriter(str(path)):
        raise ValueError(f"{flag} {str(path)!r}: no image format for {path.suffix or 'a name without an extension'}; "
                         "expected a .png, .jpg, .bmp or .tif name")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def write_image(path, image, flag: str):
    """Write ``image`` to ``path`` (checked by :func:`image_writer`); an ``OSError`` if OpenCV
    reports a failure (nothing is said to be written that was not)."""
    import cv2

    path = image_writer(path, flag)
    if not cv2.imwrite(str(path), image):
        raise OSError(f"{flag} {str(path)!r}: OpenCV could not write the image")
    return path
