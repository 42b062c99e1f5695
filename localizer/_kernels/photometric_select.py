"""The pixels of the photometric refinement's fit (:func:`select`): those of the printed target
near its edges, at most a few dozen lines along each (:mod:`localizer._kernels.photometric`)."""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import jit
from localizer._kernels.projection import bar_edge_u, edge_x
from localizer._kernels.records import Selection


@jit
def select(p, shape, cam, target, share, reach, max_lines):
    """The pixels of an ``shape = (h, w)`` image in the fit at pose ``p`` (X, Z, alpha, Y, ...;
    m, rad): inside the printed target (the bars and the gap,
    plus ``share`` of the ``margin`` (m) around them, trimmed by one pixel so that the
    background behind the target stays out) and within ``reach`` px of an edge; along
    each edge at most ``max_lines`` evenly spread rows (vertical edges) or columns (tops
    and bottoms), which bounds the work on large targets. ``margin`` is ``target.margin``.
    Returns a :class:`~localizer._kernels.records.Selection` ``(ucols (m,), pci (n,),
    pr (n,))``: the columns used, and each pixel's index into them and its row."""
    h, w = shape
    fx, fy, cx, cy = cam.fx, cam.fy, cam.cx, cam.cy
    b, H, margin = target.bar_width, target.bar_height, target.margin
    X, Z, a, Y = p[0], p[1], p[2], p[3]
    c, s = math.cos(a), math.sin(a)
    uo = 1.5 * b + share * margin
    xl = edge_x(X, Z, c, s, -uo, cam)
    xr = edge_x(X, Z, c, s, uo, cam)
    c0 = max(int(math.ceil(xl + 0.5)), 0)
    c1 = min(int(math.floor(xr - 0.5)), w - 1)
    ncol = max(c1 - c0 + 1, 0)
    xe = np.empty(4)
    for k in range(4):
        xe[k] = edge_x(X, Z, c, s, bar_edge_u(k, b), cam)
    D = Z * c + X * s
    vo = 0.5 * H + share * margin
    cstride = max(1, int(math.ceil(ncol / max_lines)))
    ucols = np.empty(ncol, np.int64)
    cap = 64
    pci = np.empty(cap, np.int64)
    pr = np.empty(cap, np.int64)
    n = 0
    m = 0
    for i in range(ncol):
        j = c0 + i
        t = (j - cx) / fx
        z = D / (c + t * s)
        rlo = max(int(math.ceil(cy + fy * (Y - vo) / z + 0.5)), 0)
        rhi = min(int(math.floor(cy + fy * (Y + vo) / z - 0.5)), h - 1)
        ytop = cy + fy * (Y - 0.5 * H) / z
        ybot = cy + fy * (Y + 0.5 * H) / z
        near_v = False
        for k in range(4):
            if abs(j - xe[k]) <= reach:
                near_v = True
        on_h = (i % cstride) == 0
        if not (on_h or near_v):
            continue
        rstride = max(1, int(math.ceil((ybot - ytop) / max_lines)))
        used = False
        # away from the vertical edges only the rows near the top and the bottom can be in
        last = rlo - 1
        for seg in range(1 if near_v else 2):
            if near_v:
                lo, hi = rlo, rhi
            else:
                yl = ytop if seg == 0 else ybot
                lo = max(rlo, int(math.floor(yl - reach)), last + 1)
                hi = min(rhi, int(math.ceil(yl + reach)))
            for r in range(lo, hi + 1):
                near_h = abs(r - ytop) <= reach or abs(r - ybot) <= reach
                if (near_h and (on_h or near_v)) or (near_v and (r - rlo) % rstride == 0):
                    if n == cap:
                        cap *= 2
                        a1 = np.empty(cap, np.int64)
                        a2 = np.empty(cap, np.int64)
                        a1[:n] = pci[:n]
                        a2[:n] = pr[:n]
                        pci = a1
                        pr = a2
                    pci[n] = m
                    pr[n] = r
                    n += 1
                    used = True
            last = max(last, hi)
        if used:
            ucols[m] = j
            m += 1
    return Selection(ucols[:m].copy(), pci[:n].copy(), pr[:n].copy())
