"""The demo's camera strip says what each tile shows: captions and labels drawn at the final size
(not shrunk with the frame), a legend, and decoy signs outlined and named (raycast: no GL)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from localizer.tools.annotation import glyph_height


@pytest.fixture(scope="module")
def strip(tmp_path_factory):
    from agvsim.sensors import VisionConfig
    from agvsim.sensors.render.strip import route_poses, save_camera_strip
    from agvsim.world import load_map

    m = load_map("plant_floor")
    mount = VisionConfig().for_map(m).mount
    poses = route_poses(m, 8, mount=mount)
    # #2: a target close up; #5: a two-bar look-alike decoy and no target
    path = tmp_path_factory.mktemp("strip") / "strip.png"
    res = save_camera_strip(m, [poses[1], poses[4]], path, mount=mount, rng=np.random.default_rng(0), columns=2)
    return res, cv2.imread(res["path"])


def _row_runs(mask_rows):
    """Lengths of the runs of consecutive True rows."""
    runs, n = [], 0
    for v in mask_rows:
        if v:
            n += 1
        elif n:
            runs.append(n)
            n = 0
    return runs + ([n] if n else [])


def test_decoys_are_named_and_outlined(strip):
    res, img = strip
    target, decoy = res["frames"]
    assert target["visible"] and target["decoys"] == [] and len(target["found"]) == 1
    assert decoy["visible"] == [] and decoy["decoys"] == ["bars_sign"] and decoy["found"] == []
    magenta = (img[..., 0] > 200) & (img[..., 2] > 200) & (img[..., 1] < 80)
    assert magenta[:, img.shape[1] // 2:].sum() > 200  # the box, "decoy" and the caption line
    assert magenta[:, :img.shape[1] // 2].sum() < 20


def test_captions_and_labels_are_drawn_at_the_final_size(strip):
    res, img = strip
    assert img.shape[1] == 512 and img.shape[0] > 240 + 3 * 14  # two 256 px tiles, captions below them
    # the text lines (legend on top, captions below the tiles): rows of the dark bands (the
    # background grey 32 at the left edge), runs of rows holding light glyph pixels
    band = np.all(img[:, :4] == 32, axis=(1, 2))
    light = (img[:, :250].max(axis=2) > 110).sum(axis=1) >= 2
    runs = [r for r in _row_runs(band & light) if r > 2]  # a line's glyphs, not a stray dot
    assert len(runs) >= 5 and min(runs) >= 10, runs  # 2 legend lines, 3 caption lines
    # the localizer's label on tile #2 (yellow, BGR (0, 255, 255))
    yellow = (img[..., 2] > 200) & (img[..., 1] > 200) & (img[..., 0] < 80)
    assert max(_row_runs(yellow[:, :256].any(axis=1))) >= 10
    assert glyph_height("#1  x=4.0 m", 14) >= 10
