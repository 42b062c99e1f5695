"""Coarse-scan building blocks (§4.4-4.5.1): thresholding, run-length code, triple search."""
import numpy as np

from localizer import Camera, detect_targets
from localizer.model.params import DetectorParams
from localizer.search.scan import find_triples, near_equal, run_length_code, threshold_lines, triple_levels
from localizer.tools.synthetic import pose_at_column, render_frame


def _naive_runs(binary):
    out = []
    for r, line in enumerate(binary):
        start = 0
        for x in range(1, line.size + 1):
            if x == line.size or line[x] != line[start]:
                out.append((bool(line[start]), x - start, r, start))
                start = x
    return out


def test_run_length_code_matches_naive():
    rng = np.random.default_rng(1)
    for width, p_white in ((40, 0.4), (13, 0.5), (1, 0.5), (70, 0.02), (517, 0.5)):
        binary = rng.random((7, width)) < p_white
        binary[3] = True  # one run over a whole line
        runs = run_length_code(binary, np.arange(7) * 10)
        got = list(zip(runs.g.tolist(), runs.l.tolist(), (runs.y // 10).tolist(), runs.x.tolist()))
        assert got == _naive_runs(binary)


def test_near_equal_allows_a_common_dark_side_shift_only():
    p = DetectorParams()
    # 5 px bars seen through blur + clipping: bars shrink, the gap grows by the same amount
    assert near_equal(np.array([3]), np.array([7]), np.array([4]), p)[0]
    assert near_equal(np.array([9]), np.array([9]), np.array([10]), p)[0]
    # unequal bars are not explained by a common shift
    assert not near_equal(np.array([3]), np.array([5]), np.array([9]), p)[0]
    assert not near_equal(np.array([4]), np.array([14]), np.array([4]), p)[0]


def test_triples_found_and_gratings_flagged():
    p = DetectorParams().resolved(480, 512)
    line = np.full((1, 120), 220, np.uint8)
    line[0, 20:30] = 20  # bar, gap, bar of 10 px with blank margins: a target
    line[0, 40:50] = 20
    tri = find_triples(run_length_code(threshold_lines(line, p, 33), np.array([0])), p)
    assert len(tri) == 1 and tri.positive[0] and tri.x[0].tolist() == [20, 30, 40, 50]
    lv = triple_levels(line, tri)
    assert abs(lv[0, 1] - 20) < 1 and abs(lv[0, 2] - 220) < 1 and np.isnan(lv[0, 5:]).all()
    # a grating: every triple has a bar-shaded run beyond a margin as long as the bars
    grating = np.where((np.arange(120) // 10) % 2 == 0, 20, 220).astype(np.uint8)[None, :]
    tri = find_triples(run_length_code(threshold_lines(grating, p, 33), np.array([0])), p)
    lv = triple_levels(grating, tri)
    bar_like = np.abs(lv[:, 5:] - lv[:, 1:2]) < 30  # same shade as the triple's own bars
    assert len(tri) > 0 and np.all(bar_like.any(axis=1))


def test_dim_target_next_to_bright_clutter():
    """Per-pixel local thresholds: a dim target on a line whose brightest pixels are elsewhere."""
    cam = Camera.thesis(16.0)
    bg = np.full(cam.shape, 0.3)
    bg[:, 400:] = 0.95  # a bright wall on the right
    bg[:, :60] = 0.0  # a black one on the left
    pose = pose_at_column(cam, 4.0, 0.3, 230)
    img = render_frame(cam, pose, lighting="dim", blur=0.6, noise=1.0, background=bg,
                       rng=np.random.default_rng(2))
    obs = detect_targets(img, cam)
    assert len(obs) == 1 and abs(obs[0].distance - 4.0) < 0.02


def test_line_extrema_match_opencv_dilate_and_erode():
    """The compiled running max / min against OpenCV's 1-D dilation / erosion (edges
    replicated): odd and even windows, windows longer than the line, strided lines."""
    import cv2

    from localizer.search.scan import line_extrema

    rng = np.random.default_rng(3)
    for window in (3, 4, 5, 32, 33, 65):
        for width in (1, 7, 40, 512):
            lines = rng.integers(0, 256, (6, width)).astype(np.uint8)
            lines[2] = np.sort(lines[2])  # long monotone stretches
            kernel = np.ones((1, window), np.uint8)
            for view in (lines, lines[::2]):
                hi, lo = line_extrema(view, window)
                assert np.array_equal(hi, cv2.dilate(np.ascontiguousarray(view), kernel,
                                                      borderType=cv2.BORDER_REPLICATE))
                assert np.array_equal(lo, cv2.erode(np.ascontiguousarray(view), kernel,
                                                     borderType=cv2.BORDER_REPLICATE))
