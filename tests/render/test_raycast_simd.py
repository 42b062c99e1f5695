"""The raycaster's explicit vector code agrees with its scalar loop.

* :func:`agvsim.sensors.render._simd.pair_sums8` gives the sums of the interpolated samples
  that NumPy gives, steps up and down, up to the largest step it takes; and so does the form it
  compiles to on a processor without AVX-512 (built here by compiling it with that flag off);
* a face's plain rows (:func:`agvsim.sensors.render._raycast_rows.plain_rows`) come out the
  same, to float32 rounding, by the vector path and the fixed-point loop, over random spans,
  steps, offsets, mip weights and irradiance tables.
"""
from __future__ import annotations

import numba
import numpy as np
import pytest

from agvsim.sensors.render._raycast_rows import plain_rows
from agvsim.sensors.render._simd import PERMUTE, PERMUTE_MAX_STEP, pair_sums8
from localizer._jit import fast_jit


@fast_jit
def _sums(buf, base, offset, step, out, at):
    pair_sums8(buf, base, offset, step, out, at)


def _reference(buf, base, offset, step):
    pos = (np.float32(offset) + np.arange(16, dtype=np.float32) * np.float32(step)).astype(np.float32)
    q = pos.astype(np.int64)
    f = pos - q
    window = buf[base:base + 32]
    s = window[q] + (window[q + 1] - window[q]) * f
    return s[0::2] + s[1::2]


def _cases(rng, n=300):
    for _ in range(n):
        step = rng.uniform(-PERMUTE_MAX_STEP, PERMUTE_MAX_STEP)
        reach = 15 * abs(step)
        offset = rng.uniform(0.0, 30.999 - reach) + (reach if step < 0 else 0.0)
        yield int(rng.integers(0, 20)), offset, step


@pytest.mark.parametrize("vector", [True, False], ids=["host", "without-avx512"])
def test_pair_sums_match_numpy(vector, monkeypatch):
    if vector and not PERMUTE:
        pytest.skip("this processor has no AVX-512")
    kernel = _sums
    if not vector:  # the same intrinsic lowered as on a processor without AVX-512
        monkeypatch.setattr("agvsim.sensors.render._simd.PERMUTE", False)
        kernel = numba.njit(_sums.py_func)
    rng = np.random.default_rng(3)
    buf = rng.uniform(0.0, 2.0, 64).astype(np.float32)
    out = np.zeros(16, np.float32)
    for base, offset, step in _cases(rng):
        kernel(buf, base, offset, step, out, 4)
        np.testing.assert_allclose(out[4:12], _reference(buf, base, offset, step), rtol=1e-5, atol=1e-5)


@fast_jit
def _rows(lo, hi, g, buf, b0, t0a, t0b, b1, t1a, t1b, two, irr, y0, step, n_l, acc, val, permute):
    plain_rows(lo, hi, g, buf, b0, t0a, t0b, b1, t1a, t1b, two, irr, y0, step, n_l, acc, val, permute)


@pytest.mark.skipif(not PERMUTE, reason="this processor has no AVX-512")
def test_plain_rows_vector_path_matches_fixed_point_loop():
    rng = np.random.default_rng(11)
    h = 480
    checked = 0
    for _ in range(200):
        lo = int(rng.integers(0, h - 1))
        hi = int(rng.integers(lo, h))
        two = bool(rng.integers(0, 2))
        t0b = rng.uniform(-3.9, 3.9)  # texels per row: within the vector path's reach
        t1b = 0.5 * t0b
        n_tex = int(abs(t0b) * h) + 64
        buf = np.zeros(2 * n_tex + 64, np.float32)
        buf[:2 * n_tex] = rng.uniform(0.0, 1.0, 2 * n_tex)
        # a column reaching a row beyond the span: its coordinate at rows lo - 1 .. hi + 1 is >= 0
        t0a = 2.0 + (-t0b * (hi + 1) if t0b < 0 else -t0b * (lo - 1)) + rng.uniform(0, 1)
        t1a = 2.0 + (-t1b * (hi + 1) if t1b < 0 else -t1b * (lo - 1)) + rng.uniform(0, 1)
        y0 = lo - rng.uniform(0.0, 40.0)
        step = 32.0
        n_l = int(np.ceil((hi + 2 - y0) / step)) + 1
        irr = rng.uniform(0.2, 3.0, n_l)
        out = []
        for permute in (True, False):
            acc = np.zeros(h)
            _rows(lo, hi, 0.7, buf, 0, t0a, t0b, n_tex, t1a, t1b, two, irr, y0, step, n_l, acc,
                  np.zeros(2 * (h + 8), np.float32), permute)
            out.append(acc)
        assert np.all(out[0][:lo] == 0) and np.all(out[0][hi + 1:] == 0)
        assert np.all(out[0][lo:hi + 1] > 0)
        np.testing.assert_allclose(out[0], out[1], rtol=1e-5, atol=1e-9)
        checked += hi + 1 - lo
    assert checked > 10_000
