"""Command-line arguments shared by the subcommands (choice lists read from where they are defined)."""
from __future__ import annotations

import argparse

__all__ = ["MOUNT_PRESETS", "add_mount_flag", "parse_mount"]

#: Named mounts for ``--camera-mount`` besides ``map`` and explicit fields.
MOUNT_PRESETS: tuple[str, ...] = ("map", "forward", "left", "right")


def parse_mount(text: str, height: float = 1.2):
    """``map`` (None: the map's recommended mount), ``forward``, ``left``, ``right`` or
    ``forward=F,lateral=L,height=H,yaw=Y`` (m, m, m, rad) -> a CameraMount or None.

    Raises:
        argparse.ArgumentTypeError: one line naming the bad part.
    """
    from localizer.mount import CameraMount

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
