import numpy as np
import pytest

from localizer import detect_targets
from localizer.tools.synthetic import adversarial_frames, equal_bar_frame, expose, real_photos


@pytest.mark.parametrize("method", ["thesis", "exact"])
def test_adversarial_patterns_rejected(cam16, method):
    frames = adversarial_frames(cam16, np.random.default_rng(3))
    # the fuzzed frame once reported as two targets sharing bars (more rows of equal bars: test_equal_bar_rows.py)
    frames["equal_bars"] = equal_bar_frame(cam16, 4, 5, 15, 16, 24, 172)
    assert {"chessboard", "barcode", "striped_sign", "door_frame", "noise", "black", "white"} <= set(frames)
    for name, img in frames.items():
        assert detect_targets(img, cam16, method=method) == [], name


def test_black_and_white_frames_find_nothing(cam16):
    # the time per call (floor 5 ms) is a benchmark, not a test: `agvsim bench localizer`, "blank_frames"
    frames = adversarial_frames(cam16, np.random.default_rng(4))
    for name in ("black", "white"):
        assert detect_targets(frames[name], cam16) == [], name


def test_real_photos_rejected(cam16):
    photos = real_photos(cam16)
    if not photos:
        pytest.skip("scikit-image not installed")
    rng = np.random.default_rng(5)
    for name, refl in photos.items():
        for lighting in ("dim", "normal", "saturated"):
            img = expose(refl, lighting, blur=0.5, noise=2.0, rng=rng)
            assert detect_targets(img, cam16) == [], (name, lighting)


def test_targets_on_real_photo_found(cam16):
    from localizer.tools.synthetic import pose_at_column, render_frame

    photos = real_photos(cam16)
    if not photos:
        pytest.skip("scikit-image not installed")
    rng = np.random.default_rng(6)
    for name in ("brick", "astronaut", "page"):
        pose = pose_at_column(cam16, 4.0, 0.5, 200, 0.1)
        img = render_frame(cam16, pose, background=photos[name], noise=2.0, blur=0.6, rng=rng)
        obs = detect_targets(img, cam16)
        assert len(obs) == 1, name
        assert obs[0].distance == pytest.approx(4.0, rel=0.01)
