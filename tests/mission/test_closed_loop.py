"""The closed loop: corridor mission on the estimate, determinism, false detections, dead reckoning, CLI."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agvsim.analysis.evaluate import FLOORS, run_metrics
from agvsim.loop.mission import MissionConfig, run_mission
from agvsim.sensors import GeometricNoise, GeometricSource, RenderedSource, SimObservation, VisionConfig, targets_from_map
from agvsim.world import load_map
from localizer.model.mount import CameraMount

# The corridor's own recommended mount (maps/corridor.yaml: right flank, looking 30° left).
CORRIDOR_VISION = VisionConfig()
OTHER_MOUNT = CameraMount(forward=0.4, lateral=0.3, height=1.2, yaw=-math.radians(30.0))


@pytest.fixture(scope="module")
def corridor():
    return load_map("corridor")


def _floor_ok(m: dict) -> None:
    assert m["position_rmse_m"] <= FLOORS["position_rmse_m"][1]
    assert m["position_max_m"] <= FLOORS["position_max_m"][1]
    assert m["heading_rmse_rad"] <= FLOORS["heading_rmse_rad"][1]
    assert m["lost"] == 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_corridor_loop_reaches_every_station_within_floor(corridor, seed):
    log = run_mission(corridor, GeometricSource(corridor, CORRIDOR_VISION), np.random.default_rng(seed),
                      MissionConfig(vision_config=CORRIDOR_VISION))
    m = run_metrics(log)
    assert log.completed and m["collisions"] == 0
    route = [s for s in corridor.routes["default"][1:]]
    assert [a[0] for a in log.arrivals] == route
    _floor_ok(m)
    assert m["wrong_associations"] == 0
    # steering on the estimate: the vehicle really passes each station close by
    assert max(a[2] for a in log.arrivals) < 0.45
    assert m["dead_reckoning_final_error_m"] > 3 * m["position_final_m"]


def test_deterministic(corridor):
    cfg = MissionConfig(vision_config=CORRIDOR_VISION, distance=25.0)
    src = GeometricSource(corridor, CORRIDOR_VISION, GeometricNoise(false_rate=0.3, detection_probability=0.9))
    a = run_mission(corridor, src, np.random.default_rng(4), cfg)
    b = run_mission(corridor, src, np.random.default_rng(4), cfg)
    for name in ("true_pose", "odometry_pose", "estimate", "covariance", "command"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert [f.observations for f in a.frames] == [f.observations for f in b.frames]
    c = run_mission(corridor, src, np.random.default_rng(5), cfg)
    assert not np.array_equal(a.estimate, c.estimate)


def test_false_detections_in_the_loop_are_rejected(corridor):
    src = GeometricSource(corridor, CORRIDOR_VISION, GeometricNoise(false_rate=1.0))
    log = run_mission(corridor, src, np.random.default_rng(1), MissionConfig(vision_config=CORRIDOR_VISION))
    m = run_metrics(log)
    false = [o for f in log.frames for o in f.observations if o.truth_id is None]
    assert len(false) > 200
    assert m["false_detections_accepted"] <= 0.01 * len(false)
    assert m["wrong_associations"] == 0
    _floor_ok(m)


def test_without_vision_the_filter_is_dead_reckoning(corridor):
    log = run_mission(corridor, None, np.random.default_rng(0), MissionConfig(vision=False, distance=30.0))
    # the same increments: the estimate is the dead-reckoned pose (up to integrating one arc per
    # control step instead of one per physics step)
    np.testing.assert_allclose(log.estimate[:, :2], log.odometry_pose[:, :2], atol=5e-3)
    assert not log.frames
    sig = np.sqrt(np.linalg.eigvalsh(log.covariance[:, :2, :2])[:, -1])
    assert sig[-1] > sig[0]


def test_latency_and_rate_are_honoured(corridor):
    cfg = MissionConfig(vision_config=CORRIDOR_VISION, distance=20.0, camera_rate=2.0, latency=0.5)
    log = run_mission(corridor, GeometricSource(corridor, CORRIDOR_VISION), np.random.default_rng(0), cfg)
    caps = np.array([f.capture_time for f in log.frames])
    assert np.allclose(np.diff(caps), 0.5, atol=0.11)
    assert all(f.fuse_time - f.capture_time >= 0.5 - 1e-9 for f in log.frames)
    with pytest.raises(ValueError):
        MissionConfig(camera_rate=0.0)
    with pytest.raises(ValueError):
        run_mission(corridor, None, np.random.default_rng(0), MissionConfig())


def test_mount_and_targets_are_plain_data(corridor):
    vision = VisionConfig().for_map(corridor)
    assert vision.mount == corridor.camera_mount  # the map's recommended mount when none is given
    assert VisionConfig(mount=OTHER_MOUNT).for_map(corridor).mount is OTHER_MOUNT
    tm = targets_from_map(corridor)
    assert len(tm) == len(corridor.targets)
    assert tm.ids[0] == corridor.targets[0].id


def test_drift_cli_json(tmp_path, capsys):
    from agvsim.cli import main

    rc = main(["drift", "--map", "corridor", "--observations", "geometric", "--distance", "30", "--seeds", "2",
               "--workers", "1", "--no-progress", "--out", str(tmp_path), "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("position_rmse_m", "position_p95_m", "position_max_m", "heading_rmse_rad", "nees_in_bounds",
                "dead_reckoning_final_error_m", "frames_with_accepted_observation", "lost", "rejections",
                "relocalizations", "arrival_error_mean_m", "dead_reckoning_drift_per_m", "floors", "per_seed"):
        assert key in out, key
    assert out["seeds"] == [0, 1] and out["observations"] == "geometric"
    assert (tmp_path / "trajectories.png").exists() and (tmp_path / "error_vs_distance.png").exists()
    rc = main(["drift", "--map", "corridor", "--no-vision", "--distance", "20", "--seeds", "1", "--workers", "1",
               "--no-progress", "--no-plots", "--out", str(tmp_path / "no_vision"), "--json"])
    assert rc == 0
    assert json.loads(capsys.readouterr().out)["vision"] is False
    with pytest.raises(SystemExit) as info:  # argparse: one line naming --seeds, exit status 2
        main(["drift", "--seeds", "0", "--out", str(tmp_path)])
    assert info.value.code == 2


def _renderer_works() -> bool:
    if not RenderedSource.available():
        return False
    try:
        from agvsim.sensors.render.gl import choose_platform

        choose_platform()
    except Exception:
        return False
    return True


@pytest.mark.render
@pytest.mark.skipif(not _renderer_works(), reason="camera renderer not available")
def test_short_rendered_loop(corridor):
    """The first 5 m of corridor (target C01 in view) with rendered frames and the real localizer."""
    cfg = MissionConfig(vision_config=CORRIDOR_VISION, distance=5.0)
    log = run_mission(corridor, RenderedSource(corridor, CORRIDOR_VISION), np.random.default_rng(0), cfg)
    m = run_metrics(log)
    assert m["accepted"] >= 3
    assert m["wrong_associations"] == 0
    assert m["position_max_m"] < 0.03


def test_turn_blur_noise_inflates_only_while_turning():
    from agvsim.loop.closed_loop import with_turn_blur as _with_turn_blur

    obs = SimObservation(3.0, 0.1, 0.5, np.diag([1e-6, 1e-8, 1e-6]), "positive", "T01")
    still = _with_turn_blur(obs, 0.0, (0.01, 0.0, 0.03))
    np.testing.assert_allclose(still.R, obs.covariance)
    turning = _with_turn_blur(obs, 0.5, (0.01, 0.0, 0.03))
    np.testing.assert_allclose(np.diag(turning.R), [1e-6 + (0.01 * 0.5 * 3.0) ** 2, 1e-8, 1e-6 + (0.03 * 0.5) ** 2])
    np.testing.assert_allclose(turning.z, [3.0, 0.1, 0.5])
    with pytest.raises(ValueError):
        MissionConfig(turn_blur_noise=(0.0, -1.0, 0.0))
