import numpy as np
import pytest

from localizer import detect_targets


def test_bad_inputs(cam16):
    good = np.zeros(cam16.shape, np.uint8)
    with pytest.raises(ValueError, match="uint8"):
        detect_targets(good.astype(np.float32), cam16)
    with pytest.raises(ValueError, match="non-finite"):
        detect_targets(np.full(cam16.shape, np.nan), cam16)
    with pytest.raises(ValueError, match=r"\(480, 512\)"):
        detect_targets(np.zeros((240, 256), np.uint8), cam16)
    with pytest.raises(ValueError, match="non-empty"):
        detect_targets(np.zeros((0, 0), np.uint8), cam16)
    with pytest.raises(ValueError, match="numpy"):
        detect_targets(good.tolist(), cam16)
    with pytest.raises(ValueError, match="method"):
        detect_targets(good, cam16, method="magic")
    with pytest.raises(ValueError, match="unknown detector parameter"):
        detect_targets(good, cam16, threshold=3)
    with pytest.raises(ValueError, match="2-D"):
        detect_targets(np.zeros((480, 512, 2), np.uint8), cam16)


def test_colour_image_converted(cam16, rng):
    from localizer.tools.synthetic import pose_at_column, render_frame

    img = render_frame(cam16, pose_at_column(cam16, 3.0, 0.3), noise=1.0, rng=rng)
    bgr = np.repeat(img[:, :, None], 3, axis=2)
    a, b = detect_targets(img, cam16), detect_targets(bgr, cam16)
    assert len(a) == len(b) == 1 and a[0].distance == b[0].distance
