"""Validated configuration of the agvsim Gymnasium environments."""
from __future__ import annotations

import difflib
from dataclasses import dataclass, fields

from agvsim.loop.modes import LOCALIZATION_MODES
from agvsim.sensors.registry import SOURCES, source_class
from agvsim.sensors.backends import check_backend
from agvsim.sensors.vision import LENSES_MM
from agvsim.vehicle.encoders import PRESETS
from envs.tasks import TASK_NAMES
from localizer.filter import FilterConfig
from localizer.model.mount import CameraMount
from localizer.numeric import check_choice, check_number

#: the forms of the ``covariance`` observation: the 3 x 3 matrix, or its 6 unique entries
#: (upper triangle, row by row: xx, xy, xθ, yy, yθ, θθ), the flat vector SB3 and RLlib expect
COVARIANCE_FORMS = ("matrix", "flat")


@dataclass(frozen=True)
class EnvConfig:
    """Everything ``gymnasium.make(id, **kwargs)`` may set.

    Attributes:
        map: map name or YAML path.
        route: route whose stations are the start and goal candidates.
        task: one of :data:`envs.tasks.TASK_NAMES`: ``goto`` (drive to a goal station) or
            ``localize`` (stay localized: reward for a small estimate error).
        odometry: odometry error preset, one of :data:`agvsim.vehicle.encoders.PRESETS`.
        localization: pose the agent observes, one of :data:`agvsim.loop.modes.LOCALIZATION_MODES`.
        camera_rate: camera frames per second (Hz).
        camera_latency: delay from capture to fusion (s).
        observations: what the camera reports, one of :data:`agvsim.sensors.registry.SOURCES`:
            ``rendered`` (pyrender frames and the localizer, the real thing), ``synthetic``
            (warped targets on a plain background and the localizer) or ``geometric`` (true
            target geometry plus noise; fast, for experiments).
        render_backend: how ``rendered`` frames are drawn, one of
            :data:`agvsim.sensors.backends.BACKENDS`: ``raycast`` (compiled, the default)
            or ``pyrender`` (OpenGL, the reference).
        camera_mount: where the camera sits on the vehicle, a :class:`localizer.model.mount.CameraMount`
            or a dict of its fields (m, rad); None: the map's recommended mount (its YAML's
            ``camera_mount``).
        lens: focal length of the thesis camera (mm), one of :data:`agvsim.sensors.vision.LENSES_MM`.
        lighting_randomization: per-episode exposure factor exp(N(0, σ²)) of
            rendered frames, σ this value (dimensionless; 0 disables it).
        observe_image: add the latest camera frame to the observation.
        observe_status: add the localization status to the observation (``status``: its index
            in :data:`localizer.filter.STATUSES`); the ``-v1`` and ``-v2`` environments set it.
        covariance: the form of the ``covariance`` observation, one of :data:`COVARIANCE_FORMS`:
            ``matrix`` (3 x 3; ``-v0``, ``-v1``) or ``flat`` (its 6 unique entries, upper
            triangle row by row: xx, xy, xθ, yy, yθ, θθ; ``-v2``).
        policy_rate: actions per second (Hz); a whole divisor of the physics rate.
        goal_radius: the goal is reached within this distance (m).
        terminate_on_collision: end the episode at the first contact.
        collision_penalty: reward subtracted per contact begin.
        time_cost: reward subtracted per policy step.
        error_scale: ``localize`` task: error (m) at which the per-step reward halves.
        filter_config: the pose filter's settings (``localization="ekf"`` only). None: the env's
            own, :func:`agvsim.loop.closed_loop.filter_config_for` its odometry and camera; a dict
            of :class:`localizer.filter.FilterConfig` fields set over those, e.g.
            ``{"wide": localizer.filter.wide.WideConfig()}`` for the opt-in wide belief; or a
            whole FilterConfig, used as it is (its motion noise and gate included).
    """

    map: str = "plant_floor"
    route: str = "default"
    task: str = "goto"
    odometry: str = "typical"
    localization: str = "ekf"
    camera_rate: float = 4.0  # Hz
    camera_latency: float = 0.25  # s
    observations: str = "rendered"
    render_backend: str = "raycast"
    camera_mount: CameraMount | None = None
    lens: float = 16.0  # mm
    lighting_randomization: float = 0.0  # dimensionless
    observe_image: bool = False
    observe_status: bool = False
    covariance: str = "matrix"
    policy_rate: float = 10.0  # Hz
    goal_radius: float = 0.5  # m
    terminate_on_collision: bool = False
    collision_penalty: float = 1.0  # reward units per contact
    time_cost: float = 0.01  # reward units per step
    error_scale: float = 0.1  # m
    filter_config: FilterConfig | dict | None = None

    def __post_init__(self) -> None:
        check_choice("EnvConfig.task", self.task, TASK_NAMES)
        check_choice("EnvConfig.localization", self.localization, LOCALIZATION_MODES)
        check_choice("EnvConfig.odometry", self.odometry, PRESETS)
        check_choice("EnvConfig.observations", self.observations, SOURCES)
        check_choice("EnvConfig.covariance", self.covariance, COVARIANCE_FORMS)
        check_backend(self.render_backend, "EnvConfig.render_backend")
        if isinstance(self.camera_mount, dict):
            known = [f.name for f in fields(CameraMount)]
            unknown = sorted(set(self.camera_mount) - set(known))
            if unknown:
                raise ValueError(f"EnvConfig.camera_mount: unknown field(s) {', '.join(unknown)}; "
                                 f"expected some of {', '.join(known)}")
            object.__setattr__(self, "camera_mount", CameraMount(**self.camera_mount))
        if self.camera_mount is not None and not isinstance(self.camera_mount, CameraMount):
            raise ValueError("EnvConfig.camera_mount must be None, a localizer.model.mount.CameraMount or a dict "
                             f"of its fields, got {self.camera_mount!r}")
        if self.observe_image and not source_class(self.observations).draws_frames:
            raise ValueError(f"EnvConfig.observe_image=True needs a source that draws frames; "
                             f"observations={self.observations!r} draws none")
        if self.lighting_randomization > 0 and not source_class(self.observations).has_exposure:
            raise ValueError(f"EnvConfig.lighting_randomization={self.lighting_randomization!r} needs a source "
                             f"with an exposure; observations={self.observations!r} has none")
        self._check_filter_config()
        check_number("EnvConfig.camera_latency", self.camera_latency, low=0.0, unit="s")
        if check_number("EnvConfig.lens", self.lens, unit="mm") not in LENSES_MM:
            raise ValueError(f"EnvConfig.lens must be one of {', '.join(f'{v:g}' for v in LENSES_MM)} (mm), "
                             f"got {self.lens!r}")
        units = {"camera_rate": "Hz", "policy_rate": "Hz", "goal_radius": "m", "error_scale": "m"}
        for name, unit in units.items():
            check_number(f"EnvConfig.{name}", getattr(self, name), low=0.0, low_open=True, unit=unit)
        for name in ("lighting_randomization", "collision_penalty", "time_cost"):
            check_number(f"EnvConfig.{name}", getattr(self, name), low=0.0)
        for name in ("observe_image", "observe_status", "terminate_on_collision"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"EnvConfig.{name} must be True or False, got {getattr(self, name)!r}")

    def _check_filter_config(self) -> None:
        """``filter_config``: None, a FilterConfig or a dict of its fields (checked now, by
        building one, not at the first reset); a copy of a dict is kept."""
        fc = self.filter_config
        if fc is None:
            return
        if self.localization != "ekf":
            raise ValueError(f"EnvConfig.filter_config needs localization='ekf' (this env observes "
                             f"{self.localization!r})")
        if isinstance(fc, dict):
            known = [f.name for f in fields(FilterConfig)]
            unknown = sorted(str(k) for k in set(fc) - set(known))
            if unknown:
                raise ValueError(f"EnvConfig.filter_config: unknown field(s) {', '.join(unknown)}; "
                                 f"expected some of {', '.join(known)}")
            FilterConfig(**fc)
            object.__setattr__(self, "filter_config", dict(fc))
        elif not isinstance(fc, FilterConfig):
            raise ValueError("EnvConfig.filter_config must be None, a localizer.filter.FilterConfig or a dict of "
                             f"its fields, got {fc!r}")

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
