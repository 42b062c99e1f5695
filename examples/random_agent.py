"""A random agent on an agvsim environment (the smallest Gymnasium loop).

    python examples/random_agent.py --env agvsim/Corridor-v2 --steps 200
"""
from __future__ import annotations

import argparse

import gymnasium as gym

import agvsim

import envs  # noqa: F401  (registers the agvsim/ environments)


def main(env_id: str = "agvsim/PlantFloor-v2", steps: int = 200, seed: int = 0,
         **env_kwargs) -> dict[str, float]:
    """Run ``steps`` random actions; returns the return, collisions and final error."""
    env = gym.make(env_id, **env_kwargs)
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    total, collisions, episodes = 0.0, 0, 1
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        total += reward
        collisions += int(info["collision"])
        if terminated or truncated:
            obs, info = env.reset()
            episodes += 1
    env.close()
    result = {"return": total, "collisions": collisions, "episodes": episodes,
              "final_position_error_m": info["position_error"]}
    print(f"{env_id}: {steps} random steps, return {total:.2f}, {collisions} collisions, "
          f"{episodes} episode(s), final position error {info['position_error']:.3f} m")
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="agvsim/PlantFloor-v2")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--localization", default="ekf", choices=agvsim.LOCALIZATION_MODES)
    args = parser.parse_args()
    main(args.env, args.steps, args.seed, localization=args.localization)
