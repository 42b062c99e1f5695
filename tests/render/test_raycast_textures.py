"""The raycaster's decal tables: what the kernels integrate is the scene's texture, held compactly.

A decal's summed-area table is of its texels at their information content (blocks of equal
texels are one texel) and decals with the same texels share one table, yet every box integral
is that of the scene's full-resolution texture; the plant floor's tables stay small (memory
per env process).
"""
from __future__ import annotations

import numpy as np
import pytest

from agvsim.sensors.render._raycast_decals import box_average
from agvsim.sensors.render.lighting import Illumination
from agvsim.sensors.render.raycast import FLOOR_KEY, RaycastBackend
from agvsim.sensors.render.scene import build_scene
from agvsim.world import load_map


@pytest.fixture(scope="module")
def plant():
    world = load_map("plant_floor")
    scene = build_scene(world)
    return scene, RaycastBackend(scene, Illumination.from_map(world), world.lighting_default)


def _box_mean(texture: np.ndarray, u0: float, u1: float, v0: float, v1: float) -> float:
    """The mean of ``texture`` (row 0 at the top, ``v`` up) over a box in texture units, from
    its full-resolution summed-area table (float64, bilinear: exact for constant texels)."""
    h, w = texture.shape
    sat = np.zeros((h + 1, w + 1))
    sat[1:, 1:] = np.asarray(texture, np.float64)[::-1].cumsum(axis=0).cumsum(axis=1)

    def at(r: float, c: float) -> float:
        i, j = min(int(r), h - 1), min(int(c), w - 1)
        fi, fj = r - i, c - j
        return ((1 - fi) * (1 - fj) * sat[i, j] + (1 - fi) * fj * sat[i, j + 1] + fi * (1 - fj) * sat[i + 1, j]
                + fi * fj * sat[i + 1, j + 1])

    a, b, c, d = u0 * w, u1 * w, v0 * h, v1 * h
    return (at(d, b) - at(d, a) - at(c, b) + at(c, a)) / ((b - a) * (d - c))


def test_box_integrals_are_those_of_the_full_resolution_textures(plant):
    scene, backend = plant
    rng = np.random.default_rng(3)
    decal_keys = {d.texture for d in scene.decals}
    checked = 0
    for k, key in enumerate(backend.texture_keys):
        if key not in decal_keys:
            continue
        texture = scene.textures[key]
        for _ in range(20):
            u0, u1 = np.sort(rng.uniform(0.0, 1.0, 2))
            v0, v1 = np.sort(rng.uniform(0.0, 1.0, 2))
            if min(u1 - u0, v1 - v0) < 0.01:
                continue
            got = box_average(backend.textures, k, u0, u1, v0, v1)
            assert got == pytest.approx(_box_mean(texture, u0, u1, v0, v1), rel=1e-12, abs=1e-12), key
            checked += 1
    assert checked > 500


def test_decal_tables_are_compact_and_shared(plant):
    scene, backend = plant
    tex = backend.textures
    index = {key: k for k, key in enumerate(backend.texture_keys)}
    targets = [k for key, k in index.items() if key.startswith("target:")]
    assert targets and all(tex.width[k] * tex.height[k] <= 64 for k in targets)  # bars and margins: 6 x 8 blocks
    hazard = [k for key, k in index.items() if key.endswith(":hazard_sign")]
    assert len(hazard) > 1 and len({int(tex.offset[k]) for k in hazard}) == 1  # alike: one table
    full = sum((t.shape[0] + 1) * (t.shape[1] + 1) for key, t in scene.textures.items()
               if key.startswith(("target:", "distractor:")))
    assert tex.sat.size < 0.3 * full
    assert tex.sat.nbytes < 12e6  # bytes; 40 MB before the tables were compacted


def test_surface_mip_levels_are_opencvs_area_halving(plant):
    cv2 = pytest.importorskip("cv2")
    scene, backend = plant
    tex = backend.textures
    for k, key in enumerate(backend.texture_keys):
        if key.startswith(("target:", "distractor:")):
            continue
        scene_key = "surface:floor" if key == FLOOR_KEY else key
        level = np.ascontiguousarray(np.asarray(scene.textures[scene_key], np.float32)[::-1])
        for lvl in range(int(tex.mip_levels[k])):
            h, w = int(tex.mip_height[k, lvl]), int(tex.mip_width[k, lvl])
            flat = tex.mip[tex.mip_offset[k, lvl]:tex.mip_offset[k, lvl] + h * w]
            # the faces' levels are stored column by column, the floor's row by row
            got = flat.reshape(w, h).T if tex.column_major[k] else flat.reshape(h, w)
            assert bool(tex.column_major[k]) == (key != FLOOR_KEY)
            assert got.shape == level.shape
            # the same box means; OpenCV sums the last columns of a row in another order (last bit)
            np.testing.assert_allclose(got, level, rtol=0, atol=2e-7, err_msg=f"{key} level {lvl}")
            level = cv2.resize(level, (max(1, (w + 1) // 2), max(1, (h + 1) // 2)), interpolation=cv2.INTER_AREA)


def test_cubic_resize_is_opencvs_inter_cubic():
    cv2 = pytest.importorskip("cv2")
    from agvsim.sensors.render.textures import cubic_resize

    rng = np.random.default_rng(5)
    for small, shape in (((8, 8), (256, 256)), ((64, 64), (256, 256)), ((2, 2), (256, 256)), ((5, 7), (100, 40))):
        img = rng.normal(0.0, 1.0, small).astype(np.float32)
        got = cubic_resize(img, shape)
        ref = cv2.resize(img, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)
        assert got.dtype == np.float32 and got.shape == ref.shape
        # the same weights and taps; the sums' rounding is OpenCV's kernels' own
        np.testing.assert_allclose(got, ref, rtol=0, atol=3e-6 * float(np.max(np.abs(ref))))


def test_rotation_from_vector_is_cv2_rodrigues_to_the_bit():
    cv2 = pytest.importorskip("cv2")
    from agvsim.sensors.render.mount import rotation_from_vector

    rng = np.random.default_rng(7)
    vectors = [np.zeros(3), np.array([0.0, 0.0, 1e-17]), np.array([np.pi, 0.0, 0.0])]
    vectors += [rng.normal(0.0, 1.0, 3) * 10.0 ** rng.uniform(-9, 1) for _ in range(2000)]
    for r in vectors:
        assert np.array_equal(rotation_from_vector(r), cv2.Rodrigues(r.reshape(3, 1))[0]), r
