"""The agvsim Gymnasium environment: a thin adapter over :class:`agvsim.loop.closed_loop.ClosedLoop`."""
from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from envs.config import EnvConfig
from envs.tasks import TASKS
from localizer.filter import STATUSES
from localizer.numeric import check_numbers, wrap_angle

#: the keys ``reset(options=...)`` accepts
RESET_OPTIONS = ("start_pose", "believed_pose")
#: (row, column) of each entry of the flat ``covariance`` observation: the upper triangle, row
#: by row (xx, xy, xθ, yy, yθ, θθ)
COVARIANCE_FLAT_INDEX = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
_FLAT_ROWS, _FLAT_COLS = (np.array(ix) for ix in zip(*COVARIANCE_FLAT_INDEX))


class AGVEnv(gym.Env):
    """Drive a vision-guided AGV on a plant floor.

    ## Description
    A 1.0 x 0.7 m differential-drive AGV (pymunk dynamics at 100 Hz) drives on
    a plant-floor map. Its wheel encoders drift (``odometry`` preset); a
    camera sees two-bar wall targets at ``camera_rate`` and, with
    ``localization="ekf"``, each target recognized corrects the pose through
    an EKF. The agent sees only what the vehicle believes, never the true
    pose (unless ``localization="truth"``).

    Tasks (``task=``, :data:`envs.tasks.TASKS`):
{tasks}

    ## Action space
    ``Box(-1, 1, (2,), float32)``: (forward speed, yaw rate) as fractions of
    the vehicle's limits (1.5 m/s, 1.5 rad/s). Out-of-range actions are
    clipped; NaN raises ``ValueError``.

    ## Observation space
    ``Dict``:
    - ``pose``: ``Box((3,), float32)`` believed (x m, y m, θ rad), θ in [-π, π).
    - ``covariance``: its covariance (m², m·rad, rad²). ``covariance="flat"`` (``-v2``):
      ``Box((6,), float32)``, the matrix's unique entries (it is symmetric), upper
      triangle row by row: (xx, xy, xθ, yy, yθ, θθ) (:data:`COVARIANCE_FLAT_INDEX`), the
      flat vector Stable-Baselines3 and RLlib expect; ``covariance="matrix"`` (``-v0``,
      ``-v1``): ``Box((3, 3), float32)``, the matrix itself.
    - ``goal``: ``Box((3,), float32)`` the goal in the believed vehicle frame:
      (forward m, left m, heading difference rad). Zeros for ``localize``.
    - ``wheel_speeds``: ``Box((2,), float32)`` measured (left, right) rim speeds (m/s).
    - ``image`` (with ``observe_image=True``): ``Box(0, 255, (480, 512, 1), uint8)``,
      the latest camera frame.
    - ``status`` (``-v1``, or ``observe_status=True``): ``Discrete({n_statuses})``, the
      localization status as its index in :data:`localizer.filter.STATUSES`
      ({status_codes}). While not ``tracking``, ``pose`` and
      ``covariance`` are the filter's last guess: not to be trusted.

    ## Rewards
    ``goto``: progress towards the goal measured on the *true* pose (m closer
    this step), minus ``collision_penalty`` per contact begun, minus
    ``time_cost`` per step. ``localize``: ``1 / (1 + (e / error_scale)²)``
    per step for a true position error e (m), minus the same penalties.

    ## Starting state
    The vehicle starts at a station of ``route`` drawn from the env's
    ``np_random`` (``goto`` also draws a different goal station). The
    estimate starts at the true start pose.

    ``reset(options=...)`` (keys {reset_options}; without options, or with
    ``{}``, the same seed gives the same episode):
    - ``start_pose``: (x m, y m, θ rad) where the vehicle really starts, in place of
      the drawn station (which is still drawn, so the goal is the same as without
      the option; ``info["start_station"]`` is then None); the chassis must fit
      there: inside the map and clear of every wall and obstacle.
    - ``believed_pose``: what the filter is told (``localization="ekf"`` only): a pose
      (x m, y m, θ rad), or ``"unknown"``: the filter starts ``lost`` and localizes
      from the targets it sees.
    Unknown keys or bad values raise ``ValueError``.

    ## Kidnapping
    ``env.unwrapped.kidnap((x, y, θ))`` carries the vehicle to a pose mid-episode
    without telling the filter (m, m, rad; the wheels do not turn, dead reckoning
    and the estimate carry on from where they were): the kidnapped-robot
    experiment. ``ValueError`` if the chassis would overlap a wall or obstacle
    there, or the pose is off the map.

    ## Episode end
    ``terminated``: ``goto`` when the true pose is within ``goal_radius`` of
    the goal; with ``terminate_on_collision``, at the first contact.
    ``truncated``: after ``max_episode_steps`` policy steps (gymnasium's
    ``TimeLimit``; registered defaults: PlantFloor 3000, Corridor 1500,
    ActiveLocalization 1000; override with ``gymnasium.make(...,
    max_episode_steps=N)``).

    ## Arguments
    ``gymnasium.make("agvsim/PlantFloor-v2", map=..., route=..., task=...,
    odometry={odometry}, localization={localization},
    camera_rate=4.0, camera_latency=0.25, observations={observations},
    camera_mount=None | CameraMount | dict (None: the map's recommended mount),
    lens={lenses}, lighting_randomization=0.0, observe_image=False,
    observe_status=False (True in -v1, -v2), covariance="matrix" ("flat" in -v2), policy_rate=10.0, goal_radius=0.5,
    terminate_on_collision=False, collision_penalty=1.0, time_cost=0.01,
    error_scale=0.1, filter_config=None | dict | FilterConfig, render_mode=None | "rgb_array")``.
    ``filter_config``: the pose filter's settings, a dict of
    :class:`localizer.filter.FilterConfig` fields set over the env's own (``{"wide":
    WideConfig()}``: the opt-in wide belief) or a whole FilterConfig. Unknown keys raise
    ``ValueError``. See :class:`envs.config.EnvConfig` for units.

    ## Info
    ``reset`` adds ``start_station`` and ``goal_station`` (ids). Every step:
    ``true_pose``, ``estimated_pose``, ``odometry_pose`` (each (3,) float64,
    map frame), ``position_error`` (m), ``observations`` ({"accepted": n,
    "rejected": m} this step), ``collision`` (bool), and ``localization`` (also
    at ``reset``; a fresh dict each time): ``status`` ({statuses}),
    ``position_sigma`` (m, the largest standard deviation of the believed
    position), ``since_fix`` (s since the last accepted target observation or
    re-localization), ``since_tracking`` (s since the status was last
    ``tracking``; 0 while it is), ``hypotheses`` (poses the belief holds: 1,
    the components of a wide belief after a long turn unseen, or the
    re-localization hypotheses while lost), ``reason`` (why lost; None while tracking),
    ``lost_events`` and ``relocalizations`` (counts this episode). With
    ``localization="truth"`` or ``"odometry"`` the status is always ``tracking``.

    ## Rendering
    ``render_mode="rgb_array"``: the top-down view with the true,
    dead-reckoned and estimated trajectories, the 2σ covariance ellipse, the
    camera's field of view, and, in a panel beside the map, the key (what each
    colour means, a scale bar) and the latest camera frame. No OpenGL is
    touched until a camera frame is needed, so ``gymnasium.make_vec(...,
    vectorization_mode="async")`` works with forked workers. A process that
    has already rendered camera frames itself must not fork renderers: pass
    ``vector_kwargs={"context": "spawn"}`` there.

    ## Version history
    - v2: the ``covariance`` observation is flat (``covariance="flat"``, 6 entries); else as v1.
    - v1: the observation gains ``status`` (``observe_status=True``); every version's
      info gains ``localization``, ``reset`` its ``start_pose`` / ``believed_pose``
      options, the env its ``kidnap``.
    - v0: initial release (kept: the same observation space).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self._kwargs = dict(kwargs)
        self.config = EnvConfig.from_kwargs(**kwargs)
        import agvsim
        from agvsim.loop.closed_loop import LoopConfig
        from agvsim.sensors import VisionConfig, make_source
        from agvsim.vehicle.encoders import OdometryErrorModel
        from agvsim.vehicle.simulation import SimConfig

        self.map = agvsim.load_map(self.config.map)
        self.stations = self.map.route(self.config.route)
        if len({s.id for s in self.stations}) < 2:
            raise ValueError(f"route {self.config.route!r} needs at least two distinct stations")
        self.sim_config = SimConfig(control_rate=self.config.policy_rate,
                                    odometry=OdometryErrorModel.preset(self.config.odometry))
        self.metadata = {**self.metadata, "render_fps": int(round(self.config.policy_rate))}
        vp = self.sim_config.vehicle
        self._limits = np.array([vp.max_speed, vp.max_yaw_rate])  # examples/ read it
        self._v_limit, self._w_limit = float(vp.max_speed), float(vp.max_yaw_rate)
        xmin, ymin, xmax, ymax = self.map.bounds
        span = max(xmax - xmin, ymax - ymin)
        big = np.float32(1e6)
        obs = {
            "pose": spaces.Box(np.array([xmin - span, ymin - span, -math.pi], np.float32),
                               np.array([xmax + span, ymax + span, math.pi], np.float32), dtype=np.float32),
            "covariance": spaces.Box(-big, big, (6,) if self.config.covariance == "flat" else (3, 3),
                                     np.float32),
            "goal": spaces.Box(np.array([-3 * span, -3 * span, -math.pi], np.float32),
                               np.array([3 * span, 3 * span, math.pi], np.float32), dtype=np.float32),
            "wheel_speeds": spaces.Box(-2 * vp.max_speed, 2 * vp.max_speed, (2,), np.float32),
        }
        if self.config.observe_image:
            obs["image"] = spaces.Box(0, 255, (480, 512, 1), np.uint8)
        if self.config.observe_status:
            obs["status"] = spaces.Discrete(len(STATUSES))
        self.observation_space = spaces.Dict(obs)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.vision = VisionConfig(mount=self.config.camera_mount, focal_mm=float(self.config.lens)).for_map(self.map)
        self._loop_config = LoopConfig(sim=self.sim_config, vision_config=self.vision,
                                       camera_rate=self.config.camera_rate, latency=self.config.camera_latency,
                                       filter=self._filter_config())
        needs_camera = self.config.localization == "ekf" or self.config.observe_image
        # one observation source per env, reused across episodes: a rendered
        # source owns the (lazily created) GL context
        options = {"backend": self.config.render_backend} if self.config.observations == "rendered" else {}
        self._source = make_source(self.config.observations, self.map, self.vision, **options) if needs_camera else None
        self.task = TASKS[self.config.task](self.config)
        self._episode = None
        self._view = None
        self._frame = None
        self._steps = 0
        self._paths: dict[str, list[np.ndarray]] = {}

    @property
    def loop(self):
        """The current episode's :class:`~agvsim.loop.closed_loop.ClosedLoop` (None before
        :meth:`reset`): ground truth and internals for evaluation, never for the agent."""
        return self._episode

    # -- Gymnasium API -------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        start_pose, believed_pose = self._reset_options(options)  # checked before anything is drawn
        super().reset(seed=seed)
        from agvsim.loop.closed_loop import ClosedLoop

        rng = self.np_random
        ids = list(dict.fromkeys(s.id for s in self.stations))
        start_id = ids[int(rng.integers(len(ids)))]
        start = self.map.station(start_id)
        goal = self.task.draw_goal(self.map, ids, start_id, rng)
        spread = self.config.lighting_randomization
        if self._source is not None and spread > 0:
            self._source.set_exposure(float(np.exp(rng.normal(0.0, spread))))
        if start_pose is not None:
            start_id = None
        self._episode = ClosedLoop(self.map, start.pose if start_pose is None else start_pose, rng,
                                   self._loop_config, self._source, localization=self.config.localization,
                                   believed_pose=believed_pose)
        self.task.reset(self._episode)
        self._steps = 0
        self._frame = None
        ep = self._episode
        self._paths = {"true": [ep.true_pose], "odometry": [ep.odometry_pose], "estimate": [ep.believed_pose]}
        cov = ep.covariance
        localization = ep.localization_info(cov)
        obs = self._observation(ep.believed_pose, cov, np.zeros(2), localization["status"])
        info = self._info(accepted=0, rejected=0, collision=False)
        info["localization"] = localization
        info["start_station"] = start_id
        info["goal_station"] = goal.id if goal is not None else None
        return obs, info

    def step(self, action):
        if self._episode is None:
            raise RuntimeError("call reset() before step()")
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        if action.shape != (2,):
            raise ValueError(f"action must have shape (2,), got {np.shape(action)}")
        a_v, a_w = action.tolist()
        if not (math.isfinite(a_v) and math.isfinite(a_w)):
            raise ValueError(f"action must be finite, got {action}")
        # np.clip(action, -1, 1) * limits, on floats
        v = min(max(a_v, -1.0), 1.0) * self._v_limit
        w = min(max(a_w, -1.0), 1.0) * self._w_limit
        ep = self._episode
        step = ep.step(v, w)
        self._steps += 1
        if step.captured and ep.last_frame is not None:
            self._frame = ep.last_frame
        true_pose, odometry_pose, believed = ep.true_pose, ep.odometry_pose, ep.believed_pose
        paths = self._paths
        paths["true"].append(true_pose)
        paths["odometry"].append(odometry_pose)
        paths["estimate"].append(believed)
        cfg = self.config
        collided = step.sim.collided
        reward = -cfg.time_cost - cfg.collision_penalty * float(collided) + self.task.reward(ep, step)
        terminated = self.task.is_terminal(ep) or (cfg.terminate_on_collision and collided)
        truncated = False  # the step limit is gymnasium's TimeLimit (max_episode_steps)
        cov = ep.covariance
        localization = ep.localization_info(cov)
        obs = self._observation(believed, cov, step.wheel_speeds, localization["status"])
        info = self._info(step.accepted, step.rejected, collided, true_pose, believed, odometry_pose)
        info["localization"] = localization
        return obs, float(reward), bool(terminated), bool(truncated), info

    def kidnap(self, pose) -> None:
        """Carry the vehicle to ``pose`` (x m, y m, θ rad) mid-episode without telling the
        filter (the kidnapped robot; see the class docstring). ``ValueError`` if the chassis
        would overlap a wall or obstacle there, or the pose is off the map."""
        if self._episode is None:
            raise RuntimeError("call reset() before kidnap()")
        self._episode.kidnap(pose)

    def render(self):
        if self.render_mode != "rgb_array" or self._episode is None:
            return None
        from agvsim.analysis.topdown import TopDownView, Trajectory

        if self._view is None:
            cam = self.vision.camera
            self._view = TopDownView(self.map, pixels_per_metre=12.0, max_size=800, key="right",
                                     camera_size=(cam.width, cam.height))
        ep = self._episode
        trajectories = (Trajectory(np.array(self._paths["true"]), (30, 150, 40), "true"),
                        Trajectory(np.array(self._paths["odometry"]), (210, 40, 40), "dead reckoning"),
                        Trajectory(np.array(self._paths["estimate"]), (40, 90, 220), "estimate"))
        cov = ep.covariance[:2, :2]
        img = self._view.render(trajectories, vehicle_pose=tuple(ep.true_pose),
                                ellipses=((ep.believed_pose[:2], cov, (40, 90, 220)),),
                                fov=self._camera_fov(ep.true_pose), camera_frame=self._frame)
        return img

    def _camera_fov(self, pose: np.ndarray):
        """((x, y, yaw) of the camera in the map, half horizontal FOV rad, range m) for drawing."""
        lens, heading = self.vision.mount.camera_pose(pose)
        return (float(lens[0]), float(lens[1]), heading), self.vision.half_fov, self.vision.max_range

    def close(self) -> None:
        self._episode = None
        self._view = None

    # -- pickling: rebuild from the constructor arguments ---------------------
    def __getstate__(self):
        return {"render_mode": self.render_mode, "kwargs": self._kwargs}

    def __setstate__(self, state):
        self.__init__(render_mode=state["render_mode"], **state["kwargs"])

    # -- helpers ---------------------------------------------------------------
    def _filter_config(self):
        """The filter's settings from ``filter_config`` (None: the loop's own default)."""
        fc = self.config.filter_config
        if not isinstance(fc, dict):
            return fc
        from agvsim.loop.closed_loop import filter_config_for

        return filter_config_for(self.sim_config, self.vision, **fc)

    def _reset_options(self, options) -> tuple:
        """(start pose or None, believed pose, "unknown" or None) from ``reset``'s ``options``;
        one ``ValueError`` naming the option, its value and what was expected."""
        if options is None:
            return None, None
        if not isinstance(options, dict):
            raise ValueError(f"reset options must be a dict with some of the keys {', '.join(RESET_OPTIONS)}, "
                             f"got {options!r}")
        unknown = [k for k in options if k not in RESET_OPTIONS]
        if unknown:
            raise ValueError(f"unknown reset option {unknown[0]!r}; expected some of {', '.join(RESET_OPTIONS)}")
        start = options.get("start_pose")
        if start is not None:
            start = check_numbers("reset option 'start_pose'", start, 3)
            x, y = start[0], start[1]
            vp = self.sim_config.vehicle
            needed = 0.5 * math.hypot(vp.length, vp.width)  # the chassis' half diagonal (m)
            if not self.map.is_free(x, y, needed):
                xmin, ymin, xmax, ymax = self.map.bounds
                where = (f"outside the map (x in [{xmin:g}, {xmax:g}], y in [{ymin:g}, {ymax:g}] m)"
                         if not (xmin <= x <= xmax and ymin <= y <= ymax) else
                         f"{self.map.clearance(x, y):.2f} m from the nearest wall or obstacle")
                raise ValueError(f"reset option 'start_pose'={options['start_pose']!r} is {where}; expected a pose "
                                 f"inside the map with at least {needed:.2f} m clearance for the chassis")
        believed = options.get("believed_pose")
        if believed is not None:
            if self.config.localization != "ekf":
                raise ValueError(f"reset option 'believed_pose'={believed!r} needs localization='ekf' "
                                 f"(this env observes {self.config.localization!r})")
            if isinstance(believed, str):
                if believed != "unknown":
                    raise ValueError(f"reset option 'believed_pose' must be a pose (x m, y m, theta rad) or "
                                     f"'unknown', got {believed!r}")
            else:
                believed = check_numbers("reset option 'believed_pose'", believed, 3)
        return start, believed

    def _observation(self, pose: np.ndarray, cov: np.ndarray, wheels, status: str) -> dict:
        """Fresh arrays every call (the agent may keep or modify them)."""
        px, py, pth = pose.tolist()
        if self.task.goal is not None:
            gx, gy, gth = self.task.goal.pose
            c, s = math.cos(pth), math.sin(pth)
            dx, dy = gx - px, gy - py
            goal = np.array([c * dx + s * dy, -s * dx + c * dy, wrap_angle(float(gth - pth))], dtype=np.float32)
        else:
            goal = np.zeros(3, dtype=np.float32)
        obs = {
            "pose": pose.astype(np.float32),
            "covariance": (cov[_FLAT_ROWS, _FLAT_COLS] if self.config.covariance == "flat"
                           else cov).astype(np.float32),
            "goal": goal,
            "wheel_speeds": np.array(wheels, dtype=np.float32),
        }
        if self.config.observe_image:
            frame = self._frame if self._frame is not None else np.zeros((480, 512), np.uint8)
            obs["image"] = np.asarray(frame, dtype=np.uint8).reshape(480, 512, 1).copy()
        if self.config.observe_status:
            obs["status"] = np.int64(STATUSES.index(status))
        return obs

    def _info(self, accepted: int, rejected: int, collision: bool, true_pose: np.ndarray | None = None,
              est: np.ndarray | None = None, odometry_pose: np.ndarray | None = None) -> dict:
        """The step's info; the poses, when given, are this step's (copied: the paths keep them)."""
        ep = self._episode
        true_pose = ep.true_pose if true_pose is None else true_pose
        est = ep.believed_pose if est is None else est
        odometry_pose = ep.odometry_pose if odometry_pose is None else odometry_pose
        tx, ty, _ = true_pose.tolist()
        ex, ey, _ = est.tolist()
        return {
            "true_pose": true_pose.copy(),
            "estimated_pose": est.copy(),
            "odometry_pose": odometry_pose.copy(),
            "position_error": float(np.hypot(tx - ex, ty - ey)),
            "observations": {"accepted": int(accepted), "rejected": int(rejected)},
            "collision": bool(collision),
        }


def _choices(values) -> str:
    return " | ".join(repr(v) for v in values)


def _fill_doc(doc: str) -> str:
    """The env docstring with its choice lists read from where they are defined."""
    from agvsim.loop.modes import LOCALIZATION_MODES
    from agvsim.sensors.registry import SOURCES
    from agvsim.sensors.vision import LENSES_MM
    from agvsim.vehicle.encoders import PRESETS

    tasks = "\n".join(f"    - ``{name}``: {cls.summary}" for name, cls in TASKS.items())
    codes = ", ".join(f"{i}: ``{name}``" for i, name in enumerate(STATUSES))
    return (doc.replace("{tasks}", tasks).replace("{n_statuses}", str(len(STATUSES)))
            .replace("{status_codes}", codes).replace("{statuses}", _choices(STATUSES))
            .replace("{reset_options}", ", ".join(f"``{k}``" for k in RESET_OPTIONS)).replace("{odometry}", _choices(PRESETS))
            .replace("{localization}", _choices(LOCALIZATION_MODES)).replace("{observations}", _choices(SOURCES))
            .replace("{lenses}", " | ".join(f"{v:g}" for v in LENSES_MM)))


AGVEnv.__doc__ = _fill_doc(AGVEnv.__doc__ or "")
