"""Ctrl-C during a frame's rendering is raised after the frame (localizer.interrupts)."""
import signal

import pytest

from agvsim.sensors.render.renderer import CameraRenderer, RenderConditions
from localizer import Camera


def test_a_sigint_during_rendering_is_raised_after_the_frame(hall, mount, monkeypatch):
    r = CameraRenderer(hall, Camera.thesis(16), mount, backend="raycast")
    pose, cond = (15.0, 4.0, -1.5708), RenderConditions(noise=False, jitter=False)
    inner, frames = r._render, []

    def interrupted(*args):
        signal.raise_signal(signal.SIGINT)
        frames.append(inner(*args))
        return frames[-1]

    monkeypatch.setattr(r, "_render", interrupted)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            r.render(pose, cond)
        assert len(frames) == 1 and frames[0][0].shape == (r.camera.height, r.camera.width)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, before)
