"""Fixtures for the rendering tests: one shared GL context per test session (one per process,
as pyrender needs), a test hall with targets at camera height, and renderers built once."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from localizer import Camera

CAMERA_HEIGHT = 1.2  # m; the hall's targets hang at camera height, as in the thesis's tests


def hall_dict() -> dict:
    """A 44 x 30 m hall. South wall (drawn west -> east, floor on its left) carries:
    P (positive, x = 15), N (negative, x = 29) and O (positive, x = 40) behind a 2 m crate."""
    return copy.deepcopy({
        "name": "test_hall",
        "walls": [
            {"id": "south", "points": [[0, 0], [44, 0]], "thickness": 0.2, "surface": "concrete"},
            {"id": "east", "points": [[44, 0], [44, 30]], "thickness": 0.2, "surface": "brick"},
            {"id": "north", "points": [[44, 30], [0, 30]], "thickness": 0.2, "surface": "panel"},
            {"id": "west", "points": [[0, 30], [0, 0]], "thickness": 0.2},
        ],
        "obstacles": [
            {"id": "crate", "kind": "machine", "box": {"center": [40, 2.0], "size": [1.2, 0.6]}, "height": 2.0},
        ],
        "lighting": {"default": 1.0, "zones": [
            {"id": "dim_corner", "box": {"center": [3, 25], "size": [6, 10]}, "level": 0.3}]},
        "targets": [
            {"id": "P", "wall": "south", "at": 15.0, "side": "left", "height": CAMERA_HEIGHT, "polarity": "positive"},
            {"id": "N", "wall": "south", "at": 29.0, "side": "left", "height": CAMERA_HEIGHT, "polarity": "negative"},
            {"id": "O", "wall": "south", "at": 40.0, "side": "left", "height": CAMERA_HEIGHT, "polarity": "positive"},
        ],
    })


@pytest.fixture(scope="session")
def gl_context():
    from agvsim.sensors.render.gl import GLContext

    ctx = GLContext()
    yield ctx
    ctx.close()


@pytest.fixture(scope="session")
def hall():
    from agvsim.world import map_from_dict

    return map_from_dict(hall_dict(), name="test_hall")


@pytest.fixture(scope="session")
def mount():
    from agvsim.sensors.render.mount import CameraMount

    return CameraMount(forward=0.4, lateral=0.0, height=CAMERA_HEIGHT, yaw=0.0)


@pytest.fixture(scope="session")
def hall_renderers(hall, mount, gl_context):
    """``{16: renderer, 50: renderer}`` over the hall, sharing the session's GL context."""
    from agvsim.sensors.render.renderer import CameraRenderer

    return {lens: CameraRenderer(hall, Camera.thesis(lens), mount, context=gl_context, backend="pyrender") for lens in (16, 50)}


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


def deg(x: float) -> float:
    return math.radians(x)
