"""Whether measured edges still make a target (the last test before a pose is computed)."""
from __future__ import annotations

from localizer._jit import jit


@jit
def makes_target(e0, e1, e2, e3, h1, h2, width_tolerance, width_slack, min_rows):
    """Whether measured edges ``e0..e3`` and bar heights ``h1``, ``h2`` (px) still make a
    target: three near-equal runs (§4.5.1's tolerances, without the allowance for a common
    edge shift: subpixel edges are far better than the thresholded runs) and two bars at
    least half the minimum height."""
    w0, w1, w2 = e1 - e0, e2 - e1, e3 - e2
    hi = max(w0, w1, w2)
    lo = min(w0, w1, w2)
    return lo > 0 and hi - lo <= width_tolerance * hi + width_slack and min(h1, h2) >= 0.5 * min_rows
