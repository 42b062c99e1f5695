"""An agent's episodes as Rerun recordings: :class:`RerunRecorder`, a Gymnasium wrapper."""
from __future__ import annotations

import os
from pathlib import Path

import gymnasium as gym

from agvsim.record.process import RunRecording

__all__ = ["RerunRecorder"]


class RerunRecorder(gym.Wrapper):
    """Record every episode of an agvsim environment to ``path`` (one ``.rrd`` file per
    episode: ``path`` itself for the first, ``<stem>-<n>.rrd`` beside it for the n-th after it;
    one recording process for all of them, the map of the first episode),
    with the entity paths of :data:`agvsim.record.ENTITY_PATHS` on ``sim_time``.

    Each step logs the true, dead-reckoned and estimated poses and the estimate's covariance
    (from the step's ``info`` and the environment's closed loop), the filter's status when it
    changes, and each new camera frame with what the localizer found in it. ``every``: record
    every ``every``-th camera frame. Observations, rewards and actions pass through unchanged::

        env = RerunRecorder(gymnasium.make("agvsim/PlantFloor-v2"), "out/episode.rrd")
    """

    def __init__(self, env: gym.Env, path: str | os.PathLike, every: int = 1) -> None:
        super().__init__(env)
        self.path = Path(path)
        self.every = every
        self.episodes = 0
        self.recording: RunRecording | None = None
        self._frame = None
        self._status: str | None = None

    def _episode_path(self) -> Path:
        if self.episodes == 0:
            return self.path
        return self.path.with_name(f"{self.path.stem}-{self.episodes}{self.path.suffix or '.rrd'}")

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        loop = self.env.unwrapped.loop
        if self.recording is None:
            self.recording = RunRecording(self._episode_path(), f"episode-{self.episodes}", loop.map, self.every)
        else:
            self.recording.restart(self._episode_path(), f"episode-{self.episodes}")
        self.episodes += 1
        self._frame, self._status = None, None
        self._log(loop, info)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self.recording is not None:
            self._log(self.env.unwrapped.loop, info)
        return obs, reward, terminated, truncated, info

    def _log(self, loop, info: dict) -> None:
        rec = self.recording
        t = loop.sim.time
        status = info["localization"]["status"]
        rec.poses(t, {"truth": info.get("true_pose", loop.true_pose), "dead_reckoning": loop.odometry_pose,
                      "estimate": loop.estimated_pose}, loop.covariance, status if status != self._status else None)
        self._status = status
        source = loop.source
        frame = loop.last_frame
        if frame is not None and frame is not self._frame:
            self._frame = frame
            rec.frame(t, frame, getattr(source, "last_detections", ()))

    def _close(self) -> None:
        if self.recording is not None:
            self.recording.close()
            self.recording = None

    def close(self):
        self._close()
        return super().close()
