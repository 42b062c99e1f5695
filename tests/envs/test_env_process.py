"""An env process with rendered observations on the raycast backend imports only what it uses.

Peak memory per env process. OpenGL and pyrender are the other backend's; OpenCV is
not needed by the raycaster's default frame (its texture noise, mip levels and motion-blur
rotations are numpy). filterpy's EKF and scipy's chi-squared gate are the filter's own, so
``filterpy.kalman`` and ``scipy.stats`` are imported, as they should be. Run in a fresh
interpreter: this process has imported them all.
"""
from __future__ import annotations

import subprocess
import sys

#: modules an env process must not import (top-level packages, or exact dotted names)
NOT_IMPORTED = ("pyrender", "OpenGL", "trimesh", "cv2", "matplotlib", "pandas", "ray")

SCRIPT = f"""
import sys
import numpy as np, gymnasium as gym, envs
env = gym.make("agvsim/PlantFloor-v2", observe_image=True)
obs, _ = env.reset(seed=0)
for _ in range(12):
    obs, *_ = env.step(np.array([0.6, 0.2], np.float32))
source = env.unwrapped.loop.source
assert source.name == "rendered" and source.backend == "raycast", (source.name, source.backend)
assert source.last_frame is not None and obs["image"].any(), "no frame was rendered"
loaded = sorted(m for m in sys.modules if m in {NOT_IMPORTED!r} or m.split(".")[0] in {NOT_IMPORTED!r})
print("loaded:", loaded)
"""


def test_a_rendered_env_process_imports_no_gl_or_opencv():
    out = subprocess.run([sys.executable, "-c", SCRIPT], check=False, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "loaded: []", out.stdout
