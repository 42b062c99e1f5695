"""Dead-reckoning drift of the three odometry presets on one route.

Drives the default route of a map with each odometry preset (steering on the
true pose) and prints the dead-reckoning error after each lap.

    python examples/odometry_drift.py --map corridor --laps 2 --seeds 3
"""
from __future__ import annotations

import argparse

import numpy as np

import agvsim


def main(map_name: str = "plant_floor", laps: float = 1.0, seeds: int = 2,
         presets: tuple[str, ...] = agvsim.ODOMETRY_PRESETS) -> dict[str, float]:
    """Mean final dead-reckoning error (m) per preset over ``seeds`` seeds."""
    floor = agvsim.load_map(map_name)
    results: dict[str, float] = {}
    for preset in presets:
        config = agvsim.MissionConfig(sim=agvsim.SimConfig(odometry=agvsim.OdometryErrorModel.preset(preset)),
                                      laps=laps, vision=False, steer_on="truth")
        finals = []
        for seed in range(seeds):
            log = agvsim.run_mission(floor, None, np.random.default_rng(seed), config)
            finals.append(float(log.odometry_error()[-1]))
        results[preset] = float(np.mean(finals))
        print(f"{preset:>8}: {results[preset]:7.3f} m after {log.distance[-1]:6.1f} m "
              f"({100 * results[preset] / log.distance[-1]:.2f} % of distance), mean of {seeds} seeds")
    return results


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", default="plant_floor")
    parser.add_argument("--laps", type=float, default=1.0)
    parser.add_argument("--seeds", type=int, default=2)
    args = parser.parse_args()
    main(args.map, args.laps, args.seeds)
