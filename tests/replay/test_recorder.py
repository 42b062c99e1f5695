"""An agent's episodes recorded by the Gymnasium wrapper."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401 (registers the environments)

pytest.importorskip("rerun")


def _paths(path) -> tuple[set, str]:
    from rerun.chunk import RrdReader

    reader = RrdReader(str(path))
    (entry,) = reader.recordings()
    return {str(c.entity_path).lstrip("/") for c in reader.stream()}, entry.recording_id


@pytest.mark.slow
def test_each_episode_is_its_own_recording_and_the_steps_pass_through(tmp_path):
    from agvsim.record import RerunRecorder

    plain = gym.make("agvsim/Corridor-v2")
    env = RerunRecorder(gym.make("agvsim/Corridor-v2"), tmp_path / "episode.rrd")
    rng = np.random.default_rng(0)
    for episode in range(2):
        a, _ = plain.reset(seed=episode)
        b, _ = env.reset(seed=episode)
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
        for _ in range(30):
            action = rng.uniform(-1, 1, size=plain.action_space.shape).astype(plain.action_space.dtype)
            ra = plain.step(action)
            rb = env.step(action)
            assert ra[1:4] == rb[1:4]
            for key in ra[0]:
                np.testing.assert_array_equal(ra[0][key], rb[0][key])
    env.close()
    plain.close()
    first, rid0 = _paths(tmp_path / "episode.rrd")
    second, rid1 = _paths(tmp_path / "episode-1.rrd")
    assert (rid0, rid1) == ("episode-0", "episode-1")
    for paths in (first, second):
        assert {"world/map/walls", "world/map/targets", "world/truth", "world/estimate", "world/dead_reckoning",
                "world/estimate/covariance", "camera/image", "filter/status", "metrics/position_error"} <= paths, paths


def test_a_recording_that_cannot_be_written_says_so_at_close(tmp_path):
    from agvsim.record import RunRecording

    (tmp_path / "file").write_text("not a folder")
    rec = RunRecording(tmp_path / "file" / "run.rrd", "seed-0")
    rec.poses(0.0, {"truth": (0.0, 0.0, 0.0)})
    with pytest.raises(ValueError, match="the recording failed: .*run.rrd"):
        rec.close()


@pytest.mark.slow
def test_drift_on_a_pool_of_workers_records_each_seed(tmp_path):
    # a pool's workers are daemonic and may not start the recording's process: written there instead
    from agvsim.cli import main

    rc = main(["drift", "--map", "corridor", "--distance", "20", "--seeds", "2", "--workers", "2", "--no-progress",
               "--no-plots", "--out", str(tmp_path / "drift"), "--record", str(tmp_path / "drift.rrd")])
    assert rc == 0
    for seed in (0, 1):
        paths, rid = _paths(tmp_path / f"drift-seed{seed:03d}.rrd")
        assert rid == f"seed-{seed}"
        assert {"world/truth", "world/estimate", "camera/image", "metrics/position_error"} <= paths, paths
