"""``agvsim bench sim``: physics + odometry throughput on one core, no rendering.

The route's commands are recorded once by driving it with the follower, then
replayed (timed) through :meth:`agvsim.vehicle.simulation.Simulation.step`. The peer
measured in the same run is bare pymunk: the same space and chassis stepped
with the same control-body velocities but without encoders, dead reckoning
or contact bookkeeping — the floor our own per-step overhead sits on.
"""
from __future__ import annotations

import math
import time

from localizer.numeric import check_number
from agvsim.commands._args import number
from agvsim.bench.floors import floor_line, verdict
from agvsim.vehicle.encoders import PRESETS

#: the floor on the simulation's real-time factor (physics + odometry, one core)
FLOOR_REAL_TIME_FACTOR = 500.0


def add_arguments(parser) -> None:
    parser.add_argument("--map", default="plant_floor", help="map (default: %(default)s)")
    parser.add_argument("--odometry", default="typical", choices=PRESETS)
    parser.add_argument("--laps", type=number(0.0, low_open=True), default=2.0, help="route passes to replay (default: %(default)s)")
    parser.add_argument("--repeats", type=number(1, integer=True), default=3, help="timed repeats, best kept (default: %(default)s)")
    parser.add_argument("--seed", type=number(0, integer=True), default=0)


def run(args) -> dict:
    import numpy as np

    from agvsim.loop.mission import MissionConfig, run_mission
    from agvsim.vehicle.simulation import SimConfig, Simulation
    from agvsim.vehicle.encoders import OdometryErrorModel
    from agvsim.world import load_map

    check_number("--repeats", args.repeats, low=1, integer=True)
    check_number("--laps", args.laps, low=0.0, low_open=True)
    world_map = load_map(args.map)
    config = SimConfig(odometry=OdometryErrorModel.preset(args.odometry))
    recorded = run_mission(world_map, None, np.random.default_rng(args.seed),
                           MissionConfig(sim=config, laps=args.laps, vision=False, steer_on="truth"))
    commands = [tuple(map(float, c)) for c in recorded.command]
    start = world_map.route("default")[0].pose
    n_physics = len(commands) * config.substeps
    sim_seconds = len(commands) * config.control_dt

    best = math.inf
    for _ in range(args.repeats):
        sim = Simulation(world_map, start, config, np.random.default_rng(args.seed))
        t0 = time.perf_counter()
        for v, w in commands:
            sim.step(v, w)
        best = min(best, time.perf_counter() - t0)

    peer_best = math.inf
    for _ in range(args.repeats):
        sim = Simulation(world_map, start, config, np.random.default_rng(args.seed))
        space, vehicle, dt = sim.space, sim.vehicle, config.physics_dt
        t0 = time.perf_counter()
        for v, w in commands:
            v, w = config.vehicle.clip_command(v, w)
            for _ in range(config.substeps):
                vehicle.track(v, w, dt)
                space.step(dt)
        peer_best = min(peer_best, time.perf_counter() - t0)

    return {
        "benchmark": "sim",
        "map": world_map.name,
        "odometry": args.odometry,
        "physics_rate_hz": config.physics_rate,
        "control_rate_hz": config.control_rate,
        "simulated_seconds": sim_seconds,
        "physics_steps": n_physics,
        "wall_seconds": best,
        "physics_steps_per_second": n_physics / best,
        "real_time_factor": sim_seconds / best,
        "peer": {
            "name": "bare pymunk (same space and chassis, no encoders/odometry)",
            "wall_seconds": peer_best,
            "physics_steps_per_second": n_physics / peer_best,
            "real_time_factor": sim_seconds / peer_best,
        },
        "floor_real_time_factor": FLOOR_REAL_TIME_FACTOR,
        "floor": verdict(sim_seconds / best, ">=", FLOOR_REAL_TIME_FACTOR, "x"),
    }


def format_table(result: dict) -> str:
    peer = result["peer"]
    return "\n".join([
        f"agvsim bench sim — {result['map']}, {result['odometry']} odometry, "
        f"{result['physics_rate_hz']:.0f} Hz physics, {result['simulated_seconds']:.0f} s simulated",
        f"machine: {result['machine'].get('cpu_model', '?')}, {result['machine'].get('cpu_count')} cores (one used)",
        f"{'':28}{'steps/s':>12}{'real-time x':>14}",
        f"{'agvsim (physics+odometry)':28}{result['physics_steps_per_second']:12.0f}{result['real_time_factor']:14.0f}",
        f"{'bare pymunk (peer)':28}{peer['physics_steps_per_second']:12.0f}{peer['real_time_factor']:14.0f}",
        floor_line("real-time factor", result.get("floor") or verdict(
            result["real_time_factor"], ">=", result["floor_real_time_factor"], "x")),
    ])
