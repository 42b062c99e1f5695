import json
import math

import cv2
import numpy as np

from agvsim.cli import main
from localizer import Camera
from localizer.tools.synthetic import pose_at_column, render_frame


def test_localize_png_json_and_annotate(tmp_path, capsys):
    cam = Camera.thesis(16)
    pose = pose_at_column(cam, 3.2, math.radians(25), 300, 0.05)
    img = render_frame(cam, pose, noise=1.0, rng=np.random.default_rng(0))
    png = tmp_path / "frame.png"
    cv2.imwrite(str(png), img)
    out = tmp_path / "ann.png"
    assert main(["localize", str(png), "--lens", "16", "--json", "--annotate", str(out)]) == 0
    data = json.loads(capsys.readouterr().out)
    t = data["results"][0]["targets"]
    assert len(t) == 1
    assert abs(t[0]["distance_m"] - 3.2) < 0.02 and abs(t[0]["alpha_deg"] - 25) < 1
    ann = cv2.imread(str(out))
    assert ann.shape == (480, 512, 3) and (ann != img[:, :, None]).any()
    # the human table, thesis method
    assert main(["localize", str(png), "--method", "thesis"]) == 0
    text = capsys.readouterr().out
    assert "positive" in text and " 3.1" in text or " 3.2" in text


def test_localize_with_calibration_file(tmp_path, capsys):
    cam = Camera.from_intrinsics(700.0, 700.0, 319.5, 239.5, 640, 480)
    cam.to_opencv_yaml(tmp_path / "c.yaml")
    img = render_frame(cam, pose_at_column(cam, 2.0, 0.0), noise=0.0)
    cv2.imwrite(str(tmp_path / "f.png"), img)
    assert main(["localize", str(tmp_path / "f.png"), "--camera", str(tmp_path / "c.yaml"), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert abs(data["results"][0]["targets"][0]["distance_m"] - 2.0) < 0.01
    assert main(["localize", str(tmp_path / "missing.png")]) == 2


def test_reproduce_json(capsys):
    assert main(["reproduce", "thesis", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["points"]) == 18
    assert data["means"]["exact_method_16mm"]["n"] == 9
