"""Laziness (no pyrender/OpenGL import, no GL context until the first frame), bad input,
and the procedural scene (deterministic, distractors away from targets, exact target quads)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from agvsim.sensors.render.scene import DISTRACTOR_CLEARANCE, build_scene
from agvsim.world import load_map


def test_importing_and_building_a_renderer_opens_no_gl():
    code = (
        "import sys, agvsim, agvsim.sensors.render, agvsim.sensors.render.renderer, agvsim.cli\n"
        "from agvsim.sensors.render import CameraRenderer, RenderConditions\n"
        "from agvsim.world import load_map\n"
        "r = CameraRenderer(load_map('corridor'), backend='pyrender')\n"
        "agvsim.cli.build_parser()\n"
        "bad = [m for m in ('pyrender', 'OpenGL') if m in sys.modules]\n"
        "assert not bad, bad\n"
        "assert not r.context.is_open and not r.gl_open\n"
        "print('lazy ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "lazy ok" in out.stdout


def test_bad_render_input_fails_before_any_gl():
    from agvsim.sensors.render.renderer import CameraRenderer, RenderConditions

    r = CameraRenderer(load_map("corridor"), backend="pyrender")
    for pose in ((1.0, 1.0, float("nan")), (1.0, 1.0), (float("inf"), 0.0, 0.0)):
        with pytest.raises(ValueError, match="pose"):
            r.render(pose, RenderConditions(noise=False))
    with pytest.raises(ValueError, match="rng"):
        r.render((2.0, 1.5, 0.0), RenderConditions(noise=True), rng=None)
    with pytest.raises(ValueError, match="RenderConditions"):
        r.render((2.0, 1.5, 0.0), {"lighting": "dim"})
    with pytest.raises(ValueError, match="supersample"):
        CameraRenderer(load_map("corridor"), supersample=0)
    assert not r.context.is_open


@pytest.mark.parametrize("name", ["plant_floor", "corridor"])
def test_scene_is_deterministic_and_distractors_avoid_targets(name):
    m = load_map(name)
    a, b = build_scene(m), build_scene(m)
    assert [p.texture for p in a.parts] == [p.texture for p in b.parts]
    for pa, pb in zip(a.parts, b.parts):
        assert np.array_equal(pa.positions, pb.positions)
    for k in a.textures:
        assert np.array_equal(a.textures[k], b.textures[k])
    assert len(a.distractors) >= 5
    assert {d.kind for d in a.distractors} >= {"striped_sign", "barcode"}
    for d in a.distractors:
        c = np.array(d.centre[:2])
        for t in m.targets:
            same_face = np.dot(t.normal, d.normal) > 0.9 and abs(np.dot(t.position - c, d.normal)) < 1e-6
            if same_face:
                assert np.linalg.norm(t.position - c) >= DISTRACTOR_CLEARANCE + d.size[0] / 2 - 1e-9


def test_target_quads_have_the_exact_geometry():
    m = load_map("plant_floor")
    scene = build_scene(m)
    quads = [p for p in scene.parts if p.texture.startswith("target:")]
    verts = np.concatenate([p.positions for p in quads]).astype(float)
    for t in m.targets:
        spec = t.spec
        u = np.array([-t.normal[1], t.normal[0]])
        for su, sv in ((-1, 1), (1, 1), (1, -1), (-1, -1)):
            corner = np.array([*(t.position + su * u * spec.outer_width / 2), t.height + sv * spec.outer_height / 2])
            assert np.min(np.linalg.norm(verts - corner, axis=1)) < 1e-5, t.id


def test_target_texture_edges_on_texels():
    from agvsim.sensors.render.textures import TARGET_TEXELS_PER_BAR, target_texture
    from localizer import TargetSpec

    tex = target_texture(TargetSpec(), "positive")
    n = TARGET_TEXELS_PER_BAR
    assert tex.shape == (3 * n, 4 * n)
    row = tex[tex.shape[0] // 2]
    dark = np.flatnonzero(row < 0.5)
    assert dark[0] == n // 2 and dark[-1] == 3 * n + n // 2 - 1  # bars span [b/2, 3.5 b)
    assert np.all(row[n + n // 2: 2 * n + n // 2] > 0.5)  # the gap
    neg = target_texture(TargetSpec(), "negative")
    assert np.allclose(neg + tex, tex.max() + tex.min())
    with pytest.raises(ValueError):
        target_texture(TargetSpec(), "neutral")


_FORK_SCRIPT = """
import os, sys
import numpy as np
from agvsim.sensors.render import CameraRenderer, RenderConditions
from agvsim.world import load_map
r = CameraRenderer(load_map('corridor'), backend='pyrender')          # built in the parent, no GL context yet
pids = []
for k in range(2):                                  # like AsyncVectorEnv's workers
    pid = os.fork()
    if pid == 0:
        img, truth = r.render((2.0, 1.5, 0.0), RenderConditions(), np.random.default_rng(k))
        os._exit(0 if img.shape == (480, 512) and img.std() > 1 else 3)
    pids.append(pid)
codes = [os.waitpid(p, 0)[1] for p in pids]
img, _ = r.render((2.0, 1.5, 0.0), RenderConditions(), np.random.default_rng(0))
print('fork ok', codes, img.shape)
"""


@pytest.mark.render
@pytest.mark.slow
def test_renderer_built_before_fork_renders_in_children():
    out = subprocess.run([sys.executable, "-c", _FORK_SCRIPT], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "fork ok [0, 0] (480, 512)" in out.stdout


_HASH_SCRIPT = """
import hashlib, numpy as np
from agvsim.sensors.render import CameraRenderer, RenderConditions
from agvsim.world import load_map
r = CameraRenderer(load_map('plant_floor'), backend='pyrender')
h = hashlib.sha1()
for p in [(47.0, 4.0, -1.2), (4.0, 8.5, -1.57), (35.0, 20.0, 0.0)]:
    img, _ = r.render(p, RenderConditions(defocus_px=0.5), np.random.default_rng(5))
    h.update(img.tobytes())
print(h.hexdigest())
"""


@pytest.mark.render
@pytest.mark.slow
def test_same_seed_same_frame_across_processes_and_contexts(gl_context):
    """Bit-identical frames in a fresh process and in this one (its shared context has rendered
    other scenes before): no dependence on draw order, uninitialised memory or context history."""
    import hashlib

    from agvsim.sensors.render import CameraRenderer, RenderConditions

    out = subprocess.run([sys.executable, "-c", _HASH_SCRIPT], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    r = CameraRenderer(load_map("plant_floor"), context=gl_context, backend="pyrender")
    h = hashlib.sha1()
    for p in [(47.0, 4.0, -1.2), (4.0, 8.5, -1.57), (35.0, 20.0, 0.0)]:
        img, _ = r.render(p, RenderConditions(defocus_px=0.5), np.random.default_rng(5))
        h.update(img.tobytes())
    assert h.hexdigest() == out.stdout.strip()


@pytest.mark.render
def test_closing_one_context_leaves_another_working():
    code = (
        "import numpy as np\n"
        "from agvsim.sensors.render import CameraRenderer, RenderConditions\n"
        "from agvsim.world import load_map\n"
        "m = load_map('corridor')\n"
        "a, b = CameraRenderer(m, backend='pyrender'), CameraRenderer(m, backend='pyrender')\n"
        "ia, _ = a.render((2, 1.5, 0), RenderConditions.ideal())\n"
        "ib, _ = b.render((2, 1.5, 0), RenderConditions.ideal())\n"
        "b.context.close(); del b\n"
        "ia2, _ = a.render((2, 1.5, 0), RenderConditions.ideal())\n"
        "assert np.array_equal(ia, ib) and np.array_equal(ia, ia2)\n"
        "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr


def test_platform_choice_and_the_install_hint(monkeypatch):
    from agvsim.sensors.render import gl

    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)
    monkeypatch.setattr(gl, "egl_works", lambda: False)
    monkeypatch.setattr(gl, "osmesa_works", lambda: True)
    assert gl.choose_platform() == "osmesa"
    monkeypatch.setattr(gl, "osmesa_works", lambda: False)
    with pytest.raises(gl.RenderUnavailable) as err:
        gl.choose_platform()
    msg = str(err.value)
    assert "libegl1" in msg and "libosmesa6" in msg and "PyOpenGL" in msg
    monkeypatch.setattr(gl, "egl_works", lambda: True)
    assert gl.choose_platform() == "egl"
    monkeypatch.setenv("PYOPENGL_PLATFORM", "osmesa")
    assert gl.choose_platform() == "osmesa"  # the user's choice wins
    monkeypatch.setenv("PYOPENGL_PLATFORM", "glx")
    with pytest.raises(ValueError, match="headless"):
        gl.choose_platform()
