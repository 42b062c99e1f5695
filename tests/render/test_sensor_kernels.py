"""The raycast backend's compiled sensor stages against their models (no rendering).

* the noise generator: its draws are standard normal (Kolmogorov-Smirnov distance to the
  normal CDF on 4M draws, tail frequencies beyond 3 and 4 sigma, kurtosis), the two normals of a pair are
  independent, and every draw is within 1e-6 sigma of the exact Box-Muller transform of
  the same bits (a float64 NumPy reimplementation);
* ``expose`` adds exactly those normals at the model's sigma; same seed same frame, other
  seed other frame; no noise gives the rounded exposure;
* ``expose_columns`` (a column-major frame into a row-major one) gives each column the normals
  of a one-column frame, the counter advanced past the columns before it (every pixel its own
  draws), the 8 x 8 block stores and the odd sizes included; without noise it is ``expose`` of
  the row-major frame;
* ``blur_columns`` (motion blur of the raycaster's column-major frames) equals a float64 NumPy
  evaluation of its model (path ends by projection, exact horizontal integral, rows blended at
  the path's midpoint) on textured scenes with yaw, sideways and forward motion, far pixels,
  paths clipped at the image sides, paths within one pixel, and long vertical smears (a fast
  roll); its frame exposed as it is blurred is ``expose_columns`` of the blurred radiance bit
  for bit;
* ``nearest_depth`` is the smallest positive depth; ``transpose_into`` gives the row-major
  frame of a column-major one (whole 8 x 8 blocks and the rows and columns past them).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from agvsim.sensors.render import sensor as sn
from agvsim.sensors.render._motion_blur_kernels import blur_columns, transpose_into
from agvsim.sensors.render._sensor_kernels import (
    expose,
    expose_columns,
    expose_scratch,
    nearest_depth,
    standard_normals,
)
from agvsim.sensors.render.ray_records import (
    BlurScratch,
    MotionBlurParams,
    SensorParams,
)
from localizer import Camera

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


def _leading_zeros(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(number of leading zero bits, x shifted left by it) of uint64 ``x`` (``x > 0``)."""
    e = np.zeros(x.shape, np.uint64)
    y = x.copy()
    for s in (32, 16, 8, 4, 2, 1):
        m = (y >> np.uint64(64 - s)) == 0
        e[m] += np.uint64(s)
        y[m] <<= np.uint64(s)
    return e, y


def exact_normals(seed: int, n: int, first_pair: int = 0) -> np.ndarray:
    """The Box-Muller transform, in float64 with NumPy's log / cos / sin, of the bits the kernels
    use for a frame of ``n`` pixels (module docstring of ``_sensor_kernels``), the counter
    advanced by ``first_pair`` pairs (a column of ``expose_columns``)."""
    m = n // 2
    k = np.arange(m + 1, dtype=np.uint64) + np.uint64(first_pair)
    with np.errstate(over="ignore"):
        bits = _splitmix64(np.uint64(seed) + (k + np.uint64(1)) * _GOLDEN)
    bits_r = (bits & np.uint64(0xFFFFFFFF00000000)) | np.uint64(1 << 31)  # the radius: high 32 bits
    bits_a = bits << np.uint64(32)  # the angle: low 32 bits
    e, y = _leading_zeros(bits_r)
    u = (y >> np.uint64(40)).astype(float) * 2.0 ** -23 * 2.0 ** -(e.astype(float) + 1.0)
    r = np.sqrt(-2.0 * np.log(u))
    x = (((bits_a << np.uint64(2)) >> np.uint64(42)).astype(float) + 0.5) * 2.0 ** -22 * (math.pi / 2) - math.pi / 4
    cos = np.where((bits_a >> np.uint64(63)) == 1, -np.cos(x), np.cos(x))
    sin = np.sin(x)
    swap = (bits_a & np.uint64(1 << 62)) != 0
    a, b = r * np.where(swap, sin, cos), r * np.where(swap, cos, sin)
    out = np.empty(n)
    out[:m], out[n - m:] = a[:m], b[:m]
    if n % 2:
        out[m] = a[m]
    return out


@pytest.fixture(scope="module")
def draws() -> np.ndarray:
    z = np.empty(1 << 22, np.float32)
    standard_normals(20240611, z)
    return z.astype(float)


def test_draws_are_standard_normal(draws):
    n = draws.size
    z = np.sort(draws)
    cdf = ndtr(z)
    ks = max(np.max(np.arange(1, n + 1) / n - cdf), np.max(cdf - np.arange(n) / n))
    assert ks < 1.95 / math.sqrt(n)  # Kolmogorov's 0.1 % level, about 0.00095 (12 uniforms: 0.0026)
    assert abs(draws.mean()) < 5.0 / math.sqrt(n) and abs(draws.var() - 1.0) < 5.0 * math.sqrt(2.0 / n)
    kurtosis = np.mean(draws ** 4) / draws.var() ** 2
    assert abs(kurtosis - 3.0) < 5.0 * math.sqrt(24.0 / n)
    for t in (3.0, 4.0):  # two-sided tail frequencies within 5 binomial sigma of the normal's
        p = 2.0 * ndtr(-t)
        assert abs(np.mean(np.abs(draws) > t) - p) < 5.0 * math.sqrt(p / n)
    assert np.abs(draws).max() > 4.5  # 4M normals reach past 4.5 sigma (all but surely)


def test_the_two_normals_of_a_pair_are_independent(draws):
    m = draws.size // 2
    a, b = draws[:m], draws[m:]
    for x, y in ((a, b), (a * a, b * b), (np.abs(a), np.abs(b))):
        assert abs(np.corrcoef(x, y)[0, 1]) < 5.0 / math.sqrt(m)
    # and the two halves are not the same stream shifted (a reused pattern)
    assert abs(np.corrcoef(a[1:], b[:-1])[0, 1]) < 5.0 / math.sqrt(m)


@pytest.mark.parametrize("n", [1 << 20, 12345])
def test_draws_are_the_exact_box_muller_transform_within_1e6_sigma(n):
    z = np.empty(n, np.float32)
    standard_normals(987654321, z)
    assert np.max(np.abs(z - exact_normals(987654321, n))) < 1e-6


def test_expose_adds_the_generators_normals_at_the_models_sigma():
    h, w = 301, 257  # odd: one pixel takes a pair of its own
    radiance = np.full((h, w), 0.4, np.float32)
    params = SensorParams(200.0, 5.0, 20000.0 / 255.0, 0.8, 3.0, 4242)
    out = np.empty((h, w), np.uint8)
    expose(radiance, params, out)
    grey = 0.4 * 200.0 + 5.0
    sigma = 3.0 * math.sqrt(grey / (20000.0 / 255.0) + 0.64)
    expected = np.floor(grey + exact_normals(4242, h * w) * sigma + 0.5).reshape(h, w)
    # equal but where the noisy value falls within float32 rounding of a half grey level
    frac = (grey + exact_normals(4242, h * w) * sigma).reshape(h, w) % 1.0
    sure = np.abs(frac - 0.5) > 1e-3
    assert np.array_equal(out[sure], np.clip(expected, 0, 255)[sure]) and sure.mean() > 0.99


@pytest.mark.parametrize("h, w", [(480, 512), (301, 256), (480, 257), (9, 8)])
def test_expose_columns_gives_every_column_its_own_draws(h, w):
    rng = np.random.default_rng(h + w)
    radiance_t = rng.uniform(0.0, 1.2, (w, h)).astype(np.float32)  # column j at radiance_t[j]
    params = SensorParams(200.0, 5.0, 20000.0 / 255.0, 0.8, 3.0, 4242)
    out = np.empty((h, w), np.uint8)
    expose_columns(radiance_t, params, out, expose_scratch(h))
    grey = radiance_t.T.astype(np.float64) * 200.0 + 5.0
    sigma = 3.0 * np.sqrt(grey / (20000.0 / 255.0) + 0.64)
    pairs = h - h // 2
    z = np.stack([exact_normals(4242, h, j * pairs) for j in range(w)], axis=1)  # (h, w)
    noisy = grey + z * sigma
    sure = np.abs(noisy % 1.0 - 0.5) > 1e-3  # not within float32 rounding of a half grey level
    assert np.array_equal(out[sure], np.clip(np.floor(noisy + 0.5), 0, 255)[sure]) and sure.mean() > 0.99
    # neighbouring columns draw independently (no pattern repeated down the frame)
    assert abs(np.corrcoef(z[:, :-1].ravel(), z[:, 1:].ravel())[0, 1]) < 5.0 / math.sqrt(z.size)
    quiet = np.empty((h, w), np.uint8)
    expose_columns(radiance_t, params._replace(noise_scale=0.0), quiet, expose_scratch(h))
    row_major = np.empty((h, w), np.uint8)
    expose(np.ascontiguousarray(radiance_t.T), params._replace(noise_scale=0.0), row_major)
    assert np.array_equal(quiet, row_major)


def test_expose_same_seed_same_frame_other_seed_other_frame():
    rng = np.random.default_rng(5)
    radiance = rng.random((120, 160), dtype=np.float32)
    params = SensorParams(235.0, 5.0, 20000.0 / 255.0, 0.8, 1.0, 77)
    a, b, c = (np.empty((120, 160), np.uint8) for _ in range(3))
    expose(radiance, params, a)
    expose(radiance, params, b)
    expose(radiance, params._replace(seed=78), c)
    assert np.array_equal(a, b) and np.mean(a != c) > 0.5


def test_expose_without_noise_rounds_and_saturates():
    radiance = np.array([[0.0, 0.5, 1.0, 2.0, -0.1, 0.0236, 0.0232]], np.float32)
    out = np.empty(radiance.shape, np.uint8)
    expose(radiance, SensorParams(235.0, 5.0, 20000.0 / 255.0, 0.8, 0.0, 1), out)
    assert out.tolist() == [[5, 123, 240, 255, 0, 11, 10]]  # 10.546 and 10.452 grey levels


@pytest.mark.parametrize("w, h", [(512, 480), (257, 301), (5, 3)])
def test_transpose_into_gives_the_row_major_frame(w, h):
    src = np.random.default_rng(w).random((w, h), dtype=np.float32)  # column-major: column j at src[j]
    dst = np.full((h, w), np.nan, np.float32)
    transpose_into(src, dst)
    assert np.array_equal(dst, src.T)


def test_nearest_depth():
    assert nearest_depth(np.array([[0.0, 3.5], [-1.0, 2.25]], np.float32)) == 2.25
    assert nearest_depth(np.zeros((3, 4), np.float32)) == 1e3


# ------------------------------------------------------------------ motion blur
def blur_model(radiance: np.ndarray, depth: np.ndarray, p: MotionBlurParams) -> np.ndarray:
    """The model of ``blur_columns`` in float64 NumPy (``(H, W)`` frames)."""
    h, w = radiance.shape
    jj, ii = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    z = np.where(depth > 0, depth, 1e3).astype(float)
    point = np.stack([(jj - p.cx) / p.fx * z, (ii - p.cy) / p.fy * z, z])
    ends = []
    for rot, tr in ((p.rot_a, p.tr_a), (p.rot_b, p.tr_b)):
        q = np.tensordot(rot, point, 1) + np.asarray(tr, float)[:, None, None]
        qz = np.maximum(q[2], 1e-3)
        ends.append((p.cx + p.fx * q[0] / qz + 0.5, p.cy + p.fy * q[1] / qz))
    (ax, ay), (bx, by) = ends
    k0 = np.clip(np.minimum(ax, bx), 0.0, w - 1e-3)
    k1 = np.minimum(np.maximum(np.maximum(ax, bx), k0 + 1e-3), w)
    ym = np.clip(0.5 * (ay + by), 0.0, h - 1.0)
    r0 = np.minimum(ym.astype(int), h - 2)
    x = radiance.astype(float)
    prefix = np.concatenate([np.zeros((h, 1)), np.cumsum(x, axis=1)], axis=1)

    def integral(r, k):  # sum of row r over [0, k), pixels piecewise constant
        a = np.minimum(k.astype(int), w - 1)
        return prefix[r, a] + (k - a) * x[r, a]

    s0 = integral(r0, k1) - integral(r0, k0)
    s1 = integral(r0 + 1, k1) - integral(r0 + 1, k0)
    return (s0 + (s1 - s0) * (ym - r0)) / (k1 - k0)


def _scene(h: int, w: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Blocky texture with fine noise; depth 1.5 .. 12 m in patches, some far (0)."""
    rng = np.random.default_rng(seed)
    radiance = (np.kron(rng.random((h // 6 + 1, w // 6 + 1)), np.ones((6, 6)))[:h, :w]
                + 0.1 * rng.random((h, w))).astype(np.float32)
    depth = np.kron(rng.uniform(1.5, 12.0, (h // 15 + 1, w // 15 + 1)), np.ones((15, 15)))[:h, :w]
    depth[rng.random((h, w)) < 0.03] = 0.0
    return radiance, depth.astype(np.float32)


def _params(camera: Camera, radiance, depth, v, omega, t) -> MotionBlurParams:
    motion = sn.exposure_motion(camera, radiance, depth, (np.asarray(v, float), np.asarray(omega, float)), t)
    assert motion is not None
    return MotionBlurParams(camera.fx, camera.fy, camera.cx, camera.cy, *motion[:4])


#: (camera v m/s, camera omega rad/s, exposure s): yaw; yaw and sideways; forward (vertical smear);
#: a small twist (paths within one pixel for the far points); a fast roll (rows tilt across the ring)
MOTIONS = [
    ((0.0, 0.0, 0.0), (0.0, -0.8, 0.0), 0.02),
    ((0.6, 0.0, 0.3), (0.0, 0.5, 0.0), 0.02),
    ((0.0, 0.0, 2.5), (0.0, 0.1, 0.0), 0.03),
    ((0.0, 0.0, 0.0), (0.0, 0.02, 0.0), 0.01),
    ((0.1, 0.0, 0.0), (0.0, 0.0, 3.0), 0.05),
]


@pytest.mark.parametrize("v,omega,t", MOTIONS)
def test_motion_blur_equals_its_model_and_is_exposed_as_expose_columns(v, omega, t):
    """``blur_columns`` of the column-major frame: its model (float32 prefix sums), and exposed as
    it is blurred, bit for bit ``expose_columns`` of the blurred radiance it stores (with noise:
    the same counter per column)."""
    camera = Camera(300.0, 310.0, 80.3, 59.6, 161, 121)
    radiance, depth = _scene(121, 161, 11)
    params = _params(camera, radiance, depth, v, omega, t)
    expected = blur_model(radiance, depth, params)
    rt, dt = np.ascontiguousarray(radiance.T), np.ascontiguousarray(depth.T)
    scratch = BlurScratch.of(121, 161)
    out_t = np.full((161, 121), np.nan, np.float32)
    sensor = SensorParams(200.0, 5.0, 20000.0 / 255.0, 0.8, 1.0, 12345)
    blur_columns(rt, dt, params, out_t, scratch, sensor, np.zeros((0, 0), np.uint8))
    assert np.max(np.abs(out_t.T - expected)) < 2e-5 * radiance.max()
    image = np.empty((121, 161), np.uint8)
    untouched = out_t.copy()
    blur_columns(rt, dt, params, out_t, scratch, sensor, image)
    assert np.array_equal(out_t, untouched)  # exposed: the radiance is not stored
    reference = np.empty_like(image)
    expose_columns(untouched, sensor, reference, expose_scratch(121))
    assert np.array_equal(image, reference)


def test_motion_blur_keeps_a_uniform_scene_uniform():
    camera = Camera(300.0, 300.0, 80.0, 60.0, 160, 120)
    _, depth = _scene(120, 160, 3)
    radiance = np.full((120, 160), 0.7, np.float32)
    out_t = np.empty((160, 120), np.float32)
    blur_columns(radiance.T.copy(), depth.T.copy(), _params(camera, radiance, depth, (0.3, 0.0, 1.0),
                                                            (0.0, 0.6, 0.1), 0.02),
                 out_t, BlurScratch.of(120, 160), SensorParams(1.0, 0.0, 1.0, 0.0, 0.0, 0),
                 np.zeros((0, 0), np.uint8))
    assert np.max(np.abs(out_t - 0.7)) < 1e-5 * 0.7  # float32 prefix sums of the rows


def test_blur_scratch_checks_its_sizes():
    with pytest.raises(ValueError, match="height >= 2"):
        BlurScratch.of(1, 10)
    with pytest.raises(ValueError, match="width >= 1"):
        BlurScratch.of(10, 0)
