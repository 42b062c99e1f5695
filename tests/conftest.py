"""Suite-wide test settings.

Hypothesis: under CI (``CI`` set, as ``.ci/run`` is run) the property tests
are derandomized, so a run is reproducible and CI cannot fail on an example
no one can replay. Locally they explore new random examples each run (and
replay failures from ``.hypothesis/``), which is how misses are found.

Numba: the localizer's kernels are compiled with ``cache=True``; the first call
in a process still loads them from the on-disk cache (about a second; in a
fresh checkout it compiles them, much longer). :func:`numba_kernels` pays that
once per session, before the first test, so no test's duration includes it.
Tests that start a subprocess pay it again in the child.

Markers (``pyproject.toml``): ``slow`` -- over about 5 s warm;
``render`` -- opens an OpenGL context (deselect with ``-m "not render"`` on a
machine without EGL or OSMesa).
"""
import math
import os

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")


@pytest.fixture(scope="session", autouse=True)
def numba_kernels():
    """Load (or compile) the localizer's numba kernels once: one synthetic frame, both methods."""
    from localizer import Camera, detect_targets
    from localizer.tools.synthetic import pose_at_column, render_frame

    cam = Camera.thesis(16.0)
    img = render_frame(cam, pose_at_column(cam, 3.0, math.radians(20.0)))
    for method in ("exact", "thesis"):
        detect_targets(img, cam, method=method)
    detect_targets(img, cam, photometric="all")  # the photometric refinement's kernels


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler (KeyboardInterrupt) for the test, as in a terminal: an xdist
    worker ignores SIGINT, so a test that sends itself one would otherwise see nothing happen."""
    import signal

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)
