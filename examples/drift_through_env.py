"""Drift-correction evaluation through the Gym API: EKF against dead reckoning.

The pure-pursuit follower (examples/pure_pursuit_planner.py) drives each
episode of ``agvsim/PlantFloor-v2`` twice with the same seed: once steering
on the EKF estimate and once on dead reckoning. The true pose comes from
``info`` (evaluation may read it; the agent never does).

    python examples/drift_through_env.py --episodes 3 --odometry worn
"""
from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import numpy as np

import agvsim


def _planner():
    path = Path(__file__).with_name("pure_pursuit_planner.py")
    spec = importlib.util.spec_from_file_location("pure_pursuit_planner", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main(env_id: str = "agvsim/PlantFloor-v2", episodes: int = 2, odometry: str = "typical",
         observations: str = "rendered") -> dict[str, dict[str, float]]:
    """Goal reach rate and final position error (m) per localization mode."""
    planner = _planner()
    table: dict[str, dict[str, float]] = {}
    for mode in ("ekf", "odometry"):
        runs = [planner.main(env_id, seed=seed, localization=mode, odometry=odometry,
                             observations=observations) for seed in range(episodes)]
        table[mode] = {"reached": float(np.mean([r["reached"] for r in runs])),
                       "final_position_error_m": float(np.mean([r["final_position_error_m"] for r in runs])),
                       "collisions": float(np.sum([r["collisions"] for r in runs]))}
    print(f"\n{'localization':>14}{'goals reached':>15}{'mean final error (m)':>22}{'collisions':>12}")
    for mode, row in table.items():
        print(f"{mode:>14}{100 * row['reached']:14.0f}%{row['final_position_error_m']:22.3f}"
              f"{row['collisions']:12.0f}")
    return table


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="agvsim/PlantFloor-v2")
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--odometry", default="typical", choices=agvsim.ODOMETRY_PRESETS)
    parser.add_argument("--observations", default="rendered", choices=agvsim.SOURCES)
    args = parser.parse_args()
    main(args.env, args.episodes, args.odometry, args.observations)
