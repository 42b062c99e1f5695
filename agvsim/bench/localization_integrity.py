"""``agvsim bench localization-integrity``: does the estimate ever lie?

Four experiments, each trial in a worker process (a local pool, ``--workers``), on rendered
frames (the raycast backend, the envs' default camera):

``random``
    ``agvsim/PlantFloor-v2`` (the status observed, the covariance flat) with its defaults, ``reset(seed=s)``, then ``--steps`` steps of
    the smoothed random policy ``a <- 0.9 a + 0.1 (U(0.2, 1), U(-1, 1))`` drawn from
    ``numpy.random.default_rng(s)`` (the agent drives into things). Per step: *honest* when
    the filter reports itself lost (``lost`` or ``relocalizing``) or the true position error
    ``e`` is inside the reported covariance's "3σ" region, ``eᵀ P⁻¹ e <= χ²₂(0.9973) = 11.83``.
``kidnap``
    The default route, the follower steering on the *true* pose (an oracle driver: the
    experiment isolates the filter; a lost AGV would stop on its own). After ``--settle`` s
    the vehicle is carried 2-20 m to a free point of the route with any heading, without
    telling the filter, and drives on from there for ``--after`` s.
``unknown``
    The filter is told nothing (``believed_pose="unknown"``): it starts lost at a station of
    the default route of each shipped map, and must find itself.
``wall``
    After ``--settle`` s the vehicle turns to the nearest wall or obstacle and pushes into it
    for ``--push`` s (wheels spinning), backs off towards where it left the route, then drives on
    from the nearest route point in sight along the route for
    ``--after`` s.

Per event (kidnap, unknown start, end of the push): seconds from the first refused
detection to ``lost`` (floor 5 s); seconds from having seen two distinct targets (their truth
ids) to an error <= 10 cm while ``tracking`` again (floor 15 s); wrong re-localizations (a
confirmed hypothesis more than 0.5 m from the truth at its capture time: floor none).
Re-localization cost: the filter's wall ms per frame fused while lost.
"""
from __future__ import annotations

import math
import time

import numpy as np

from agvsim.commands._args import number
from agvsim.bench.integrity_report import format_table, summarize

__all__ = ["EXPERIMENTS", "add_arguments", "format_table", "run", "summarize"]

#: the experiments, in report order
EXPERIMENTS = ("random", "kidnap", "unknown", "wall")
#: χ²(2) quantile of 0.9973 (the 2-D counterpart of ±3σ)
CHI2_2_3SIGMA = 11.829
#: (the floors: agvsim.bench.integrity_report)
RECOVERED_M = 0.10  # m
WRONG_RELOC_M = 0.5  # m
MAPS = ("plant_floor", "corridor")


def add_arguments(parser) -> None:
    parser.add_argument("--experiments", nargs="+", default=list(EXPERIMENTS), choices=EXPERIMENTS)
    parser.add_argument("--seeds", type=number(1, integer=True), default=20, help="random-agent drives (default: %(default)s)")
    parser.add_argument("--steps", type=number(1, integer=True), default=3000, help="policy steps per drive (default: %(default)s)")
    parser.add_argument("--kidnaps", type=number(0, integer=True), default=50, help="kidnap trials (default: %(default)s)")
    parser.add_argument("--unknown", type=number(0, integer=True), default=20, help="unknown-start trials per map (default: %(default)s)")
    parser.add_argument("--walls", type=number(0, integer=True), default=20, help="wall-push trials (default: %(default)s)")
    parser.add_argument("--settle", type=number(0.0, unit="s"), default=15.0, help="s driven before the event (default: %(default)s)")
    parser.add_argument("--after", type=number(0.0, low_open=True, unit="s"), default=45.0, help="s driven after the event (default: %(default)s)")
    parser.add_argument("--push", type=number(0.0, low_open=True, unit="s"), default=60.0, help="s pushing into the wall (default: %(default)s)")
    parser.add_argument("--workers", type=number(1, integer=True), default=2, help="worker processes (default: %(default)s)")


# ----------------------------------------------------------------------------- per step


class _Watch:
    """Per-step bookkeeping of one run: honesty, errors while tracking, re-localizations and
    the event timeline (after :meth:`event`)."""

    def __init__(self, loop) -> None:
        self.loop = loop
        self.truth: list[np.ndarray] = [loop.true_pose]  # by step index (0: the start)
        self.honest = 0
        self.steps = 0
        self.tracking_errors: list[float] = []
        self.relocs = 0
        self.wrong: list[float] = []  # errors of wrong re-localizations (m)
        self.lost_ms: list[float] = []  # filter ms of frames fused while lost
        self.lost_steps = 0
        self._t_event = None
        self._seen: set[str] = set()
        self.t_refused = None
        self.t_lost = None
        self.t_two = None
        self.t_recovered = None

    def event(self) -> None:
        """Start an event's timeline now (a kidnap, an unknown start, the end of a push)."""
        self._t_event = self.loop.sim.time
        self._seen = set()
        self.t_refused = self.t_lost = self.t_two = self.t_recovered = None
        if self.loop.ekf.lost:
            self.t_lost = self._t_event

    def after_step(self, step) -> None:
        loop = self.loop
        ekf = loop.ekf
        true = loop.true_pose
        self.truth.append(true)
        est = loop.believed_pose
        e = true[:2] - est[:2]
        err = float(math.hypot(e[0], e[1]))
        status = ekf.status
        self.steps += 1
        P = loop.covariance[:2, :2]
        try:
            m2 = float(e @ np.linalg.solve(P, e))
        except np.linalg.LinAlgError:
            m2 = math.inf
        if status != "tracking":
            self.lost_steps += 1
            self.honest += 1
        else:
            self.tracking_errors.append(err)
            if m2 <= CHI2_2_3SIGMA:
                self.honest += 1
        now = loop.sim.time
        for f in step.fused:
            if f.result.relocalized:
                if self._t_event is not None and self.t_lost is None:  # lost and found in one frame
                    self.t_lost = f.fuse_time
                self.relocs += 1
                truth = self.truth[min(f.step + 1, len(self.truth) - 1)]  # the pose at capture
                x = ekf.x
                off = float(math.hypot(x[0] - truth[0], x[1] - truth[1]))
                if off > WRONG_RELOC_M:
                    self.wrong.append(off)
            if f.result.lost or f.result.relocalized:
                self.lost_ms.append(f.filter_ms)
            if self._t_event is not None and f.capture_time >= self._t_event:
                if self.t_refused is None and f.result.accepted < len(f.observations):
                    self.t_refused = f.capture_time
                for o in f.observations:
                    if o.truth_id is not None:
                        self._seen.add(o.truth_id)
                if self.t_two is None and len(self._seen) >= 2:
                    self.t_two = f.capture_time
        if self._t_event is not None:
            if self.t_lost is None and status != "tracking":
                self.t_lost = now
            if (self.t_recovered is None and self.t_two is not None and status == "tracking"
                    and err <= RECOVERED_M and (self.t_lost is not None)):
                self.t_recovered = now

    def event_figures(self) -> dict:
        t0 = self._t_event
        # rounded to the µs: the times are sums of control steps (5.000000000000071 is 5 s)
        detect = (None if self.t_refused is None or self.t_lost is None
                  else round(max(self.t_lost - max(self.t_refused, t0), 0.0), 6))
        recover = (None if self.t_two is None or self.t_recovered is None
                   else round(max(self.t_recovered - self.t_two, 0.0), 6))
        return {"detect_s": detect, "recover_s": recover, "refused": self.t_refused is not None,
                "declared_lost": self.t_lost is not None, "saw_two": self.t_two is not None}

    def figures(self) -> dict:
        return {"steps": self.steps, "honest": self.honest, "lost_steps": self.lost_steps,
                "tracking_errors": self.tracking_errors, "relocalizations": self.relocs, "wrong": self.wrong,
                "lost_ms": self.lost_ms}


# ----------------------------------------------------------------------------- trials


def _random_trial(seed: int, steps: int) -> dict:
    import gymnasium as gym

    import envs  # noqa: F401  (registers the envs)

    env = gym.make("agvsim/PlantFloor-v2")
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    a = np.zeros(2)
    watch = _Watch(env.unwrapped.loop)
    # the env's LoopStep is not returned: step the loop through a hook that records it
    figures = {"steps": 0, "honest": 0, "lost_steps": 0, "tracking_errors": [], "relocalizations": 0,
               "wrong": [], "lost_ms": []}
    episodes = 1
    for _ in range(steps):
        a = 0.9 * a + 0.1 * np.array([rng.uniform(0.2, 1.0), rng.uniform(-1.0, 1.0)])
        loop = env.unwrapped.loop
        if watch.loop is not loop:
            _merge(figures, watch.figures())
            watch = _Watch(loop)
        step = _step_env(env, a)
        watch.after_step(step)
        if step.done:
            env.reset()
            episodes += 1
    _merge(figures, watch.figures())
    env.close()
    return {"experiment": "random", "seed": seed, "episodes": episodes, **figures}


class _EnvStep:
    __slots__ = ("fused", "done")


def _step_env(env, action) -> _EnvStep:
    """One env step, with the loop's fused frames (read off the loop's step through a wrapper)."""
    loop = env.unwrapped.loop
    captured = []
    inner = loop.step

    def hooked(v, w):
        s = inner(v, w)
        captured.append(s)
        return s

    loop.step = hooked
    try:
        _, _, term, trunc, _ = env.step(action)
    finally:
        del loop.step
    out = _EnvStep()
    out.fused = captured[0].fused if captured else ()
    out.done = bool(term or trunc)
    return out


def _merge(total: dict, part: dict) -> None:
    for k, v in part.items():
        total[k] = total[k] + v


def _loop_for(map_name: str, seed: int, start, believed=None):
    from agvsim.loop.closed_loop import ClosedLoop, LoopConfig
    from agvsim.sensors import VisionConfig, make_source
    from agvsim.vehicle.encoders import OdometryErrorModel
    from agvsim.vehicle.simulation import SimConfig
    from agvsim.world import load_map

    world_map = load_map(map_name)
    vision = VisionConfig().for_map(world_map)
    sim = SimConfig(control_rate=10.0, odometry=OdometryErrorModel.preset("typical"))
    source = make_source("rendered", world_map, vision, backend="raycast")
    loop = ClosedLoop(world_map, start, np.random.default_rng(seed), LoopConfig(sim=sim, vision_config=vision),
                      source, believed_pose=believed)
    return world_map, loop


def _follower(world_map, loop):
    from agvsim.loop.pure_pursuit import FollowerParams, PurePursuit, RoutePath

    path = RoutePath.from_route(world_map, "default")
    vp = loop.config.sim.vehicle
    return path, PurePursuit(path, FollowerParams(), laps=1000.0, max_speed=vp.max_speed, max_yaw_rate=vp.max_yaw_rate)


def _drive(loop, pursuit, watch, seconds: float) -> None:
    for _ in range(int(round(seconds * loop.config.sim.control_rate))):
        v, w = pursuit.command(tuple(loop.true_pose))
        watch.after_step(loop.step(v, w))


def _event_trial(experiment: str, trial: int, settle: float, after: float, push: float, map_name: str) -> dict:
    rng = np.random.default_rng(1000 + trial + 7919 * EXPERIMENTS.index(experiment))
    from agvsim.world import load_map

    wm = load_map(map_name)
    stations = wm.route("default")
    start_station = stations[int(rng.integers(len(stations)))]
    start = tuple(float(v) for v in start_station.pose)
    believed = "unknown" if experiment == "unknown" else None
    world_map, loop = _loop_for(map_name, int(rng.integers(2 ** 31)), start, believed)
    path, pursuit = _follower(world_map, loop)
    pursuit.progress = path.project(np.asarray(start[:2]), 0.0, window=path.length)
    watch = _Watch(loop)
    info: dict = {"experiment": experiment, "trial": trial, "map": map_name}
    if experiment == "unknown":
        watch.event()
        _drive(loop, pursuit, watch, after)
    elif experiment == "kidnap":
        _drive(loop, pursuit, watch, settle)
        here = loop.true_pose
        for _ in range(2000):
            s = float(rng.uniform(0.0, path.length))
            xy = path.point_at(s)
            dist = float(np.hypot(*(xy - here[:2])))
            if 2.0 <= dist <= 20.0 and world_map.is_free(float(xy[0]), float(xy[1]), 0.8):
                break
        else:
            raise RuntimeError("no free route point 2-20 m away")
        pose = (float(xy[0]), float(xy[1]), float(rng.uniform(-math.pi, math.pi)))
        loop.kidnap(pose)
        pursuit.progress = s
        info["kidnap_m"] = dist
        watch.event()
        _drive(loop, pursuit, watch, after)
    else:  # wall
        _drive(loop, pursuit, watch, settle)
        _push_into_wall(loop, watch, push)
        pursuit.progress = _rejoin(world_map, path, loop.true_pose[:2])
        watch.event()
        _drive(loop, pursuit, watch, after)
    return {**info, **watch.figures(), **watch.event_figures()}


def _rejoin(world_map, path, xy) -> float:
    """Arc length (m) of the nearest route point in plain sight of ``xy`` (the vehicle may
    have slid along the wall far from where it left the route)."""
    best, best_s = math.inf, 0.0
    for s in np.arange(0.0, path.length, 0.5):
        p = path.point_at(float(s))
        d = float(np.hypot(*(p - xy)))
        if d < best and world_map.line_of_sight(tuple(xy), tuple(p)):
            best, best_s = d, float(s)
    return best_s


def _push_into_wall(loop, watch, seconds: float) -> None:
    """Turn to the nearest solid (by sight lines), drive into it, keep pushing ``seconds`` s."""
    world_map = loop.map
    x, y, th = loop.true_pose.tolist()
    best = None
    for k in range(72):
        a = th + k * 2 * math.pi / 72
        for r in np.arange(0.5, 6.0, 0.25):
            if not world_map.line_of_sight((x, y), (x + r * math.cos(a), y + r * math.sin(a))):
                if best is None or r < best[0]:
                    best = (r, a)
                break
    heading = best[1] if best else th
    rate = loop.config.sim.control_rate
    for _ in range(int(10 * rate)):  # turn in place
        err = math.remainder(heading - loop.true_pose[2], 2 * math.pi)
        if abs(err) < 0.05:
            break
        watch.after_step(loop.step(0.0, max(min(2.0 * err, 1.0), -1.0)))
    pushed = 0.0
    origin = loop.true_pose[:2].copy()  # on the route: backed off to again afterwards
    for _ in range(int((seconds + 30.0) * rate)):
        step = loop.step(0.8, 0.0)
        watch.after_step(step)
        if step.sim.in_contact or step.sim.contacts:
            pushed += 1.0 / rate
            if pushed >= seconds:
                break
    nearest = math.inf
    for _ in range(int(20 * rate)):  # back off the wall towards where the push started
        gap = float(np.hypot(*(loop.true_pose[:2] - origin)))
        if gap < 0.2 or gap > nearest + 0.05:
            break
        nearest = min(nearest, gap)
        watch.after_step(loop.step(-0.5, 0.0))


def _run_trial(task: tuple) -> dict:
    kind = task[0]
    t0 = time.perf_counter()
    if kind == "random":
        out = _random_trial(task[1], task[2])
    else:
        out = _event_trial(*task)
    out["wall_s"] = time.perf_counter() - t0
    return out


# ----------------------------------------------------------------------------- run / report


def run(args) -> dict:
    import multiprocessing as mp
    import sys

    for flag in ("seeds", "steps", "kidnaps", "unknown", "walls", "workers"):
        if getattr(args, flag) < (1 if flag in ("steps", "workers") else 0):
            raise ValueError(f"--{flag} must be >= {1 if flag in ('steps', 'workers') else 0}, got {getattr(args, flag)}")
    tasks: list[tuple] = []
    if "random" in args.experiments:
        tasks += [("random", s, args.steps) for s in range(args.seeds)]
    if "kidnap" in args.experiments:
        tasks += [("kidnap", k, args.settle, args.after, args.push, "plant_floor") for k in range(args.kidnaps)]
    if "unknown" in args.experiments:
        tasks += [("unknown", k, args.settle, args.after, args.push, m) for m in MAPS for k in range(args.unknown)]
    if "wall" in args.experiments:
        tasks += [("wall", k, args.settle, args.after, args.push, "plant_floor") for k in range(args.walls)]
    t0 = time.perf_counter()
    results = []
    with mp.get_context("spawn").Pool(args.workers) as pool:
        for n, r in enumerate(pool.imap_unordered(_run_trial, tasks), 1):
            results.append(r)
            spent = time.perf_counter() - t0
            left = spent / n * (len(tasks) - n)  # at the pace so far
            print(f"\r  {n}/{len(tasks)} trials ({spent:.0f} s; about {left:.0f} s left)", end="", file=sys.stderr,
                  flush=True)
    print(file=sys.stderr)
    return {"wall_s": time.perf_counter() - t0, "workers": args.workers, "summary": summarize(results),
            "trials": results}
