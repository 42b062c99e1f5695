"""The physically based frame set (``agvsim bench pbr``): its scenes, its sensor, the shipped set
on disk, and the benchmark that reads it. The renderer itself (Mitsuba) is checked where it is
installed: a frame it makes puts the target where the truth says."""
from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from agvsim.bench import pbr, pbr_dataset, pbr_scene, pbr_sensor
from agvsim.cli import main
from localizer.model.target import TargetSpec


def test_the_focus_gives_the_defocus_disc_asked_for():
    rng = np.random.default_rng(0)
    for _ in range(200):
        d, disc, aperture = rng.uniform(1.0, 20.0), rng.uniform(0.0, 13.0), rng.uniform(2.0, 20.0)
        s = pbr_scene.focus_for_disc(d, disc, aperture, bool(rng.random() < 0.5))
        assert s > 0
        assert aperture * abs(1.0 / s - 1.0 / d) == pytest.approx(disc, abs=1e-9)


@pytest.mark.parametrize("width,height,focal", [(512, 480, 16.0), (512, 480, 50.0), (1280, 1200, 16.0)])
def test_every_sampled_scene_shows_the_whole_face(width, height, focal):
    rng = np.random.default_rng(1)
    camera = pbr_scene.camera_for(width, height, focal)
    for _ in range(40):
        s = pbr_scene.sample_scene(rng, width, height, focal, True)
        assert pbr_scene.face_in_view(s.pose, camera, TargetSpec(), 0.0)
        assert abs(s.alpha) <= pbr_scene.ALPHA_MAX and s.polarity in ("positive", "negative")
        assert s.to_dict()["distance"] == s.distance


@pytest.mark.parametrize("polarity", ["positive", "negative"])
@pytest.mark.parametrize("cut", [False, True])
def test_the_printed_sheet_has_its_bars_where_its_centre_says(polarity, cut):
    rgb, (w, h), (cu, cv) = pbr_scene.sheet_texture(polarity, cut)
    t = TargetSpec()
    px = rgb.shape[1] / w
    assert rgb.shape[0] / h == pytest.approx(px, rel=1e-2)
    bar, gap = (0.04, 0.85) if polarity == "positive" else (0.85, 0.04)
    row = int(cv * px)
    for u, want in ((-t.bar_width, bar), (0.0, gap), (t.bar_width, bar)):
        assert rgb[row, int((cu + u) * px), 0] == pytest.approx(want, abs=0.02)


def test_the_sensor_noise_grows_as_the_full_well_shrinks_and_the_files_decode():
    radiance = np.full((48, 64, 3), 0.5, np.float32)
    radiance[:, 32:] = 0.1
    sds = []
    for well in (8000.0, 300.0):
        s = pbr_sensor.SensorSettings(0.8, well, 2.0, "linear", 0, (1.0, 1.0, 1.0))
        noisy, stored = pbr_sensor.expose(radiance, s, np.random.default_rng(0))
        clean, _ = pbr_sensor.expose(radiance, s, None)
        assert stored[:4] == b"\x89PNG" and noisy.dtype == np.uint8 and noisy.shape == (48, 64)
        sds.append(float(np.std(noisy[4:-4, 4:28].astype(float) - clean[4:-4, 4:28])))
    assert sds[1] > 3 * sds[0]
    s = pbr_sensor.SensorSettings(0.8, 2000.0, 2.0, "srgb", 80, (1.0, 1.0, 1.0))
    frame, stored = pbr_sensor.expose(radiance, s, np.random.default_rng(0))
    assert stored[:2] == b"\xff\xd8"  # a JPEG
    assert frame[:, :28].mean() > frame[:, 36:].mean()  # brighter where the radiance is
    with pytest.raises(ValueError, match="radiance"):
        pbr_sensor.expose(radiance[..., 0], s, None)


def test_the_response_curves_are_monotone_and_keep_the_ends():
    x = np.linspace(0.0, 1.0, 101)
    for r in pbr_sensor.RESPONSES:
        y = pbr_sensor.encode_response(x, r)
        assert np.all(np.diff(y) > 0) and y[0] == pytest.approx(0.0, abs=1e-9) and y[-1] == pytest.approx(1.0)


def test_the_shipped_set_is_whole_and_split():
    records = pbr_dataset.read_set(pbr_dataset.DEFAULT_DIR)
    meta = json.loads((pbr_dataset.DEFAULT_DIR / "dataset.json").read_text())
    assert meta["version"] == pbr_dataset.VERSION and meta["spp"] == pbr_dataset.SPP
    assert [r["index"] for r in records] == [i for i, _ in pbr_dataset.plan()]
    splits = [r["split"] for r in records]
    assert splits.count("tune") == sum(1 for i, _ in pbr_dataset.plan() if i % 3 == 0)
    for r in records:
        assert (pbr_dataset.DEFAULT_DIR / r["attributes"]["size"] / r["image"]).is_file()
        assert r["split"] == pbr_dataset.split_of(r["index"])
    assert sum(not r["scene"]["has_target"] for r in records) == sum(
        b.count for b in pbr_dataset.PLAN if not b.has_target)
    assert sum(r["attributes"]["in_spec"] for r in records) > 60


def _small_set(tmp_path, indices):
    src = pbr_dataset.DEFAULT_DIR
    shutil.copy(src / "dataset.json", tmp_path / "dataset.json")
    for r in pbr_dataset.read_set(src):
        if r["index"] in indices:
            d = tmp_path / r["attributes"]["size"]
            d.mkdir(exist_ok=True)
            shutil.copy(r["path"], d / r["image"])
            shutil.copy(src / r["attributes"]["size"] / f"{r['index']:04d}.json", d)
    return tmp_path


def test_the_bench_reads_a_set_and_reports_every_condition_it_holds(tmp_path, capsys):
    records = pbr_dataset.read_set(pbr_dataset.DEFAULT_DIR)
    spec = [r["index"] for r in records if r["attributes"]["in_spec"] and r["attributes"]["size"] == "512x480"][:4]
    free = [r["index"] for r in records if not r["scene"]["has_target"]][:2]
    folder = _small_set(tmp_path, set(spec + free))
    assert main(["bench", "pbr", "--dataset", str(folder), "--split", "all", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    rows = {c["name"]: c for c in out["conditions"]}
    assert rows["all"]["frames"] == len(spec)
    assert out["target_free"]["512x480"]["frames"] == len(free)
    for c in out["conditions"]:
        assert c["frames"] == sum(1 for r in records if r["index"] in spec
                                  and pbr.CONDITIONS[pbr.NAMES.index(c["name"])].test(r))
        assert 0 <= c["found"] <= c["frames"]
    assert "floors" in out and "detection_pct" in out["floors"]


def test_a_folder_without_a_set_is_one_line(tmp_path, capsys):
    assert main(["bench", "pbr", "--dataset", str(tmp_path)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "dataset.json" in err[0] and str(tmp_path) in err[0]


@pytest.mark.slow
def test_a_mitsuba_frame_puts_the_target_where_its_truth_says():
    pytest.importorskip("mitsuba")
    import dataclasses

    from agvsim.bench.pbr_render import render_radiance
    from localizer import detect_targets

    scene = pbr_scene.sample_scene(np.random.default_rng(3), 512, 480, 16.0, True)
    scene = dataclasses.replace(scene, distance=3.0, beta=math.radians(5.0), alpha=math.radians(30.0),
                                target_height=0.2, f_number=16.0, focus=3.0, cut=True, ambient=1.0,
                                lamp_power=0.0, panel_radiance=0.0)  # even light, sharp: the geometry alone
    grey = render_radiance(scene, 8, 0).mean(axis=2)
    image = np.round(255 * np.clip(0.9 * grey / np.percentile(grey, 99.5), 0, 1)).astype(np.uint8)
    (obs,) = detect_targets(image, pbr_scene.camera_for(512, 480, 16.0))
    assert obs.distance == pytest.approx(3.0, rel=2e-3)
    assert obs.beta == pytest.approx(math.radians(5.0), abs=math.radians(0.02))
    assert obs.alpha == pytest.approx(math.radians(30.0), abs=math.radians(0.5))
    assert obs.height == pytest.approx(0.2, abs=2e-3)


def test_the_records_attributes_follow_from_the_frames_and_their_scenes():
    import cv2

    for r in pbr_dataset.read_set(pbr_dataset.DEFAULT_DIR)[::7]:
        frame = cv2.imread(r["path"], cv2.IMREAD_GRAYSCALE)
        scene = pbr_scene.PbrScene.from_dict(r["scene"])
        assert json.loads(json.dumps(scene.to_dict())) == r["scene"]
        assert pbr_dataset.attributes(scene, r["attributes"]["noise_grey"], frame) == r["attributes"]
    dark = next(r for r in pbr_dataset.read_set(pbr_dataset.DEFAULT_DIR) if r["index"] == 63)
    assert dark["attributes"]["contrast_grey"] < pbr_dataset.SPEC_CONTRAST and not dark["attributes"]["in_spec"]


@pytest.mark.slow
def test_generate_makes_what_a_folder_lacks_and_resumes(tmp_path, monkeypatch):
    pytest.importorskip("mitsuba")
    monkeypatch.setattr(pbr_dataset, "PLAN", (pbr_dataset.Batch(128, 120, 16.0, True, 2),))
    monkeypatch.setattr(pbr_dataset, "SPP", 4)
    assert pbr_dataset.generate(tmp_path, seed=7) == 2
    records = pbr_dataset.read_set(tmp_path)
    assert [r["index"] for r in records] == [0, 1] and [r["split"] for r in records] == ["tune", "held-out"]
    first = (tmp_path / "128x120" / records[0]["image"]).read_bytes()
    assert pbr_dataset.generate(tmp_path, seed=7) == 0  # nothing redone
    (tmp_path / "128x120" / "0001.json").unlink()  # as if stopped between a frame's image and its record
    assert pbr_dataset.generate(tmp_path, seed=7) == 1
    assert (tmp_path / "128x120" / records[0]["image"]).read_bytes() == first
    assert pbr_dataset.read_set(tmp_path)[1]["scene"] == records[1]["scene"]  # the same frame again
    with pytest.raises(ValueError, match="different set"):
        pbr_dataset.generate(tmp_path, seed=8)
