"""``annotate``: labels in the tool's units (d in m, α and β in degrees), drawn at the final size."""
import math

import numpy as np

from localizer import Camera, detect_targets
from localizer.tools.annotation import annotate, draw_text, glyph_height, observation_label, text_box
from localizer.tools.synthetic import pose_at_column, render_frame


def _frame():
    cam = Camera.thesis(16)
    img = render_frame(cam, pose_at_column(cam, 3.2, math.radians(25), 300, 0.05), noise=0.0)
    obs = detect_targets(img, cam)
    assert len(obs) == 1
    return img, obs


def test_label_is_in_metres_and_degrees_with_beta():
    _, obs = _frame()
    label = observation_label(1, obs[0])
    assert "d=3.2" in label and " m " in label and "mm" not in label
    assert "α=25." in label and "β=" in label and label.count("°") == 2


def test_labels_are_drawn_at_the_final_size():
    img, obs = _frame()
    for scale in (1.0, 0.5):
        out = annotate(img, obs, scale=scale)
        assert out.shape == (round(480 * scale), round(512 * scale), 3)
        yellow = (out[..., 2] > 200) & (out[..., 1] > 200) & (out[..., 0] < 80)  # BGR (0, 255, 255) text
        rows = np.nonzero(yellow.any(axis=1))[0]
        assert len(rows) and rows.max() - rows.min() + 1 >= 10  # the glyphs, not shrunk with the frame
    assert glyph_height("d=3.20 m α β", 14) >= 10


def test_draw_text_clips_and_reports_its_box():
    img = np.zeros((30, 40, 3), np.uint8)
    x0, y0, x1, y1 = draw_text(img, "far too long a label", (30, 20), 14)
    assert (x0, y0) == (30, 20) and x1 == 40 and y1 == 30
    assert text_box("a", 14)[1] > 10 and img.any()
