"""Validated configuration of the agvsim Gymnasium environments."""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, fields

from agvsim.episode import LOCALIZATION_MODES

TASKS: tuple[str, ...] = ("goto", "localize")


@dataclass(frozen=True)
class EnvConfig:
    """Everything ``gymnasium.make(id, **kwargs)`` may set.

    Attributes:
        map: map name or YAML path.
        route: route whose stations are the start and goal candidates.
        task: ``goto`` (drive to a goal station) or ``localize`` (stay
            localized: reward for a small estimate error).
        odometry: odometry error preset (``ideal``, ``typical``, ``worn``).
        localization: pose the agent observes: ``ekf``, ``odometry`` or ``truth``.
        camera_rate: camera frames per second (Hz).
        camera_latency: delay from capture to fusion (s).
        observations: what the camera reports: ``rendered`` (pyrender frames
            and the localizer, the real thing), ``synthetic`` (warped targets
            on a plain background and the localizer) or ``geometric`` (true
            target geometry plus noise; fast, for experiments).
        lens: focal length of the thesis camera (mm): 16 or 50.
        lighting_randomization: per-episode exposure factor exp(N(0, σ²)) of
            rendered frames, σ this value (dimensionless; 0 disables it).
        observe_image: add the latest camera frame to the observation.
        policy_rate: actions per second (Hz); a whole divisor of the physics rate.
        goal_radius: the goal is reached within this distance (m).
        terminate_on_collision: end the episode at the first contact.
        collision_penalty: reward subtracted per contact begin.
        time_cost: reward subtracted per policy step.
        error_scale: ``localize`` task: error (m) at which the per-step reward halves.
    """

    map: str = "plant_floor"
    route: str = "default"
    task: str = "goto"
    odometry: str = "typical"
    localization: str = "ekf"
    camera_rate: float = 4.0  # Hz
    camera_latency: float = 0.25  # s
    observations: str = "rendered"
    lens: float = 16.0  # mm
    lighting_randomization: float = 0.0  # dimensionless
    observe_image: bool = False
    policy_rate: float = 10.0  # Hz
    goal_radius: float = 0.5  # m
    terminate_on_collision: bool = False
    collision_penalty: float = 1.0  # reward units per contact
    time_cost: float = 0.01  # reward units per step
    error_scale: float = 0.1  # m

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise ValueError(f"task must be one of {TASKS}, got {self.task!r}")
        if self.localization not in LOCALIZATION_MODES:
            raise ValueError(f"localization must be one of {LOCALIZATION_MODES}, got {self.localization!r}")
        if self.odometry not in ("ideal", "typical", "worn"):
            raise ValueError(f"odometry must be 'ideal', 'typical' or 'worn', got {self.odometry!r}")
        if self.observations not in ("rendered", "synthetic", "geometric"):
            raise ValueError(f"observations must be 'rendered', 'synthetic' or 'geometric', got {self.observations!r}")
        if self.observe_image and self.observations != "rendered":
            raise ValueError("observe_image=True needs observations='rendered' (the other sources draw no scene)")
        if not isinstance(self.camera_latency, (int, float)) or not math.isfinite(self.camera_latency) \
                or self.camera_latency < 0:
            raise ValueError(f"camera_latency must be a finite number >= 0 (s), got {self.camera_latency!r}")
        if self.lens not in (16.0, 50.0):
            raise ValueError(f"lens must be 16 or 50 (mm), got {self.lens!r}")
        for name in ("camera_rate", "policy_rate", "goal_radius", "error_scale"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        for name in ("lighting_randomization", "collision_penalty", "time_cost"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")

    @classmethod
    def from_kwargs(cls, **kwargs) -> "EnvConfig":
        """Build from ``gymnasium.make`` keyword arguments; unknown keys are errors."""
        known = [f.name for f in fields(cls)]
        for key in kwargs:
            if key not in known:
                close = difflib.get_close_matches(key, known, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise ValueError(f"unknown environment option {key!r}{hint} (known: {', '.join(known)})")
        return cls(**kwargs)
