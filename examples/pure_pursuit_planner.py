"""The pure-pursuit path follower driving to the goal station through the Gym API.

The planner follows the map's route from the start station to the goal
station, steering on the *observed* pose (what the vehicle believes, per
``localization``), as a real AGV controller would. With ``odometry`` the
vehicle misses its goal as dead reckoning drifts; with ``ekf`` the camera
keeps it on track.

    python examples/pure_pursuit_planner.py --env agvsim/PlantFloor-v2 --localization ekf
"""
from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import agvsim
import envs  # noqa: F401  (registers the agvsim/ environments)
from agvsim.loop.pure_pursuit import FollowerParams, PurePursuit, RoutePath


def route_between(world_map, route: str, start: str, goal: str) -> RoutePath:
    """The route's stations from ``start`` to ``goal`` in route order (wrapping round a loop)."""
    ids = [s.id for s in world_map.route(route)]
    if ids[0] == ids[-1]:
        ids = ids[:-1]
    i, j = ids.index(start), ids.index(goal)
    legs = ids[i:j + 1] if i <= j else ids[i:] + ids[:j + 1]
    points = np.array([world_map.station(k).pose[:2] for k in legs])
    return RoutePath(points, legs, loop=False)


def main(env_id: str = "agvsim/Corridor-v2", seed: int = 0, max_steps: int = 3000,
         **env_kwargs) -> dict:
    """Drive one episode; returns whether the goal was reached and the errors."""
    env = gym.make(env_id, **env_kwargs)
    obs, info = env.reset(seed=seed)
    base = env.unwrapped
    path = route_between(base.map, base.config.route, info["start_station"], info["goal_station"])
    limits = base._limits  # (max speed m/s, max yaw rate rad/s)
    follower = PurePursuit(path, FollowerParams(), max_speed=limits[0], max_yaw_rate=limits[1])
    total, steps, collisions = 0.0, 0, 0
    terminated = truncated = False
    while not (terminated or truncated) and steps < max_steps:
        v, w = follower.command(tuple(float(p) for p in obs["pose"]))
        action = np.array([v / limits[0], w / limits[1]], np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        total += reward
        collisions += int(info["collision"])
        steps += 1
    env.close()
    result = {"reached": bool(terminated), "steps": steps, "return": total, "collisions": collisions,
              "path_length_m": path.length, "final_position_error_m": info["position_error"]}
    print(f"{env_id} ({env_kwargs.get('localization', 'ekf')}): "
          f"{'reached' if terminated else 'did not reach'} {path.names[-1]} ({path.length:.0f} m of route) "
          f"in {steps} steps, return {total:.2f}, {collisions} collisions, "
          f"final estimate error {info['position_error']:.3f} m")
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="agvsim/Corridor-v2")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--localization", default="ekf", choices=agvsim.LOCALIZATION_MODES)
    args = parser.parse_args()
    main(args.env, args.seed, localization=args.localization)
