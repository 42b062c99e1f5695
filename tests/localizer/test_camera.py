import math

import numpy as np
import pytest

from localizer import Camera


def test_thesis_camera_intrinsics():
    c = Camera.thesis(16.0)
    assert c.width == 512 and c.height == 480
    assert c.fx == pytest.approx(16 / 8.8 * 512)
    assert c.fy == pytest.approx(16 / 6.6 * 480)
    assert (c.cx, c.cy) == (256.0, 240.0)
    # thesis §3.3.1: 16 mm lens covers about 30.8 x 23.3 degrees
    assert math.degrees(2 * math.atan(256 / c.fx)) == pytest.approx(30.8, abs=0.2)
    assert math.degrees(2 * math.atan(240 / c.fy)) == pytest.approx(23.3, abs=0.2)
    np.testing.assert_allclose(c.K, [[c.fx, 0, 256], [0, c.fy, 240], [0, 0, 1]])


def test_project_pinhole_and_distortion_roundtrip():
    c = Camera.from_intrinsics(900, 910, 320, 240, 640, 480)
    np.testing.assert_allclose(c.project([0.3, -0.2, 1.5]), [320 + 900 * 0.2, 240 - 910 * 0.2 / 1.5])
    d = Camera.from_intrinsics(900, 910, 320, 240, 640, 480, dist=[-0.2, 0.05, 0.001, -0.001, 0.0])
    pts = np.array([[0.3, 0.2, 1.0], [-0.25, 0.1, 2.0], [0.0, 0.0, 3.0]])
    np.testing.assert_allclose(d.undistort_points(d.project(pts)), c.project(pts), atol=1e-6)
    with pytest.raises(ValueError, match="Z > 0"):
        c.project([0.0, 0.0, -1.0])


def test_camera_validation():
    with pytest.raises(ValueError, match="fx"):
        Camera(-1, 1, 0, 0, 10, 10)
    with pytest.raises(ValueError, match="width"):
        Camera(1, 1, 0, 0, 10.5, 10)
    with pytest.raises(ValueError, match="cx"):
        Camera(1, 1, float("nan"), 0, 10, 10)
    with pytest.raises(ValueError, match="dist"):
        Camera(1, 1, 0, 0, 10, 10, dist=(0.1, 0.2, 0.3))
    with pytest.raises(Exception):
        Camera.thesis().fx = 3  # frozen


def test_opencv_yaml_roundtrip_and_errors(tmp_path):
    c = Camera.from_intrinsics(812.5, 815.0, 330.2, 241.7, 640, 480, dist=[-0.1, 0.01, 0, 0, 0.001])
    path = tmp_path / "calib.yaml"
    c.to_opencv_yaml(path)
    assert Camera.from_opencv_yaml(path) == c
    bad = tmp_path / "bad.yaml"
    bad.write_text("%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n")
    with pytest.raises(ValueError, match=r"bad\.yaml.*camera_matrix"):
        Camera.from_opencv_yaml(bad)
    bad.write_text("%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                   "   data: [800., 0., 320., 0., 800., 240., 0., 0., 1.]\nimage_width: 640\n")
    with pytest.raises(ValueError, match="image_height"):
        Camera.from_opencv_yaml(bad)
    with pytest.raises(FileNotFoundError, match="nope.yaml"):
        Camera.from_opencv_yaml(tmp_path / "nope.yaml")


def test_cropped_is_the_checked_camera_of_the_crop():
    cams = (Camera.thesis(16.0), Camera(500.0, 510.0, 300.5, 250.25, 640, 480, (0.1, -0.05, 0.001, 0.002)))
    for cam in cams:
        for x0, y0, x1, y1 in ((0, 0, 640, 480), (10, 20, 90, 60), (3, 5, 11, 13), (np.int64(4), 2, 50, 40)):
            got = cam.cropped(x0, y0, x1, y1)
            want = Camera(cam.fx, cam.fy, cam.cx - x0, cam.cy - y0, x1 - x0, y1 - y0, cam.dist)
            assert got == want and type(got.cx) is float and type(got.width) is int
    with pytest.raises(ValueError, match="Camera.width"):
        cams[0].cropped(10, 10, 17, 40)  # 7 px: what the checks refuse is still refused


def test_kernel_records_hold_every_field_by_name():
    # as_record builds a record from the tuple at once: each field must land under its own name
    from localizer._kernels.records import (ExactSettings, Intrinsics, SearchSettings, TargetConstants,
                                            as_record)

    for cls in (Intrinsics, TargetConstants, ExactSettings, SearchSettings):
        kinds = {n: getattr(k, "__forward_arg__", k) for n, k in cls.__annotations__.items()}
        sample = {n: (True if "bool" in str(k) else 3 + i if "int" in str(k) else 0.5 + i)
                  for i, (n, k) in enumerate(kinds.items())}
        rec = as_record(cls(**sample))
        assert rec.shape == (1,) and rec.dtype.names == cls._fields
        assert {n: rec[0][n].item() for n in cls._fields} == sample


def test_cameras_of_the_same_intrinsics_share_one_record():
    a, b = Camera.thesis(16.0), Camera.thesis(16.0)
    assert a is not b and a.intrinsics_record is b.intrinsics_record
    assert a.intrinsics_record[0].tolist() == (a.fx, a.fy, a.cx, a.cy)
    crop = a.cropped(10, 20, 110, 120)
    assert crop.intrinsics_record[0].tolist() == (a.fx, a.fy, a.cx - 10, a.cy - 20)


@pytest.mark.parametrize("cut", [0.3, 0.6, 0.9])
@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_a_calibration_file_cut_off_is_one_clear_error(tmp_path, cut, suffix):
    """A calibration file copied half-way (cut inside a field, the matrix's data list left open)
    is a ValueError naming the file and what it expects, never OpenCV's SystemError."""
    whole = tmp_path / f"whole{suffix}"
    Camera.from_intrinsics(800.0, 805.0, 320.0, 240.0, 640, 480, (0.1, -0.05, 0.0, 0.0, 0.0)).to_opencv_yaml(whole)
    text = whole.read_text()
    part = tmp_path / f"part{suffix}"
    part.write_text(text[:int(cut * len(text))])
    try:
        camera = Camera.from_opencv_yaml(part)
    except ValueError as exc:
        assert str(exc).startswith(str(part)) and "camera_matrix" in str(exc), str(exc)
    else:  # a cut that leaves a well-formed file of other values would be read; none of these does
        pytest.fail(f"read a file cut at {cut:.0%}: {camera}")
