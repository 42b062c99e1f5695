"""PPO on ``agvsim/PlantFloor-v2`` with RLlib: env runners in their own processes, one learner.

    python examples/rllib_ppo.py --iterations 10 --env-runners 1 --train-batch 4000
    python examples/rllib_ppo.py --tiny      # smoke run: one small iteration (~200 steps)

Needs the ``rllib`` extra (``pip install -e '.[ray,rllib]'``; ``make test`` installs it).

RLlib does not read Gymnasium's registry: the environment is registered with RLlib under
``agvsim-plantfloor`` through ``ray.tune.register_env``. Its creator imports ``envs`` itself,
since each env runner is a separate process that must register the Gymnasium ids before
``gymnasium.make``. The env's observation is a ``Dict`` (pose, the covariance's 6 entries, goal,
wheel speeds: Boxes; the filter's status: Discrete), which RLlib's default model catalog does
not encode: the creator flattens it with Gymnasium's ``FlattenObservation`` into one
``Box((17,), float32)`` (the status one-hot). The action is the
env's own ``Box(-1, 1, (2,))`` (forward speed, yaw rate).

Ray runs on this machine only (``num_cpus`` = its cores, no GPU, no dashboard); the env
runners get ``PYOPENGL_PLATFORM=egl`` and single-threaded numba and BLAS through the runtime
environment. RLlib's new API stack (RLModule, Learner, EnvRunner) is used, as this Ray's default.

Prints one line per iteration: the iteration, the env steps sampled in it (and in all),
the mean return of the (last 100) episodes finished so far (``nan`` before the first: a
PlantFloor episode runs up to 3000 steps unless the goal is reached), the learner's total
loss and the iteration's wall time (s).
"""
from __future__ import annotations

import argparse
import math
import os
import time

#: RLlib's name for the environment (``ray.tune.register_env``)
ENV_NAME = "agvsim-plantfloor"
#: the Gymnasium id it makes
GYM_ID = "agvsim/PlantFloor-v2"
#: environment variables of every Ray worker (env runners): headless EGL for a pyrender
#: backend, one numba and one BLAS thread per process (the processes share the cores)
WORKER_ENV = {"PYOPENGL_PLATFORM": "egl", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: the ``--tiny`` smoke configuration: the batch, minibatch, epochs, network and episode length
TINY = {"train_batch": 200, "minibatch": 50, "epochs": 1, "hiddens": [16], "max_episode_steps": 50}


def make_env(env_config: dict):
    """RLlib's env creator: ``gymnasium.make(GYM_ID, **env_config)`` with a flat observation.

    Imports ``envs`` here, in the env runner's own process, so the ``agvsim/`` ids are registered
    there. ``env_config`` takes any ``gymnasium.make`` keyword (``max_episode_steps``, the env's
    options such as ``localization`` or ``observations``).
    """
    import gymnasium
    from gymnasium.wrappers import FlattenObservation

    import envs  # noqa: F401  (registers the agvsim/ environments in this process)

    return FlattenObservation(gymnasium.make(GYM_ID, **dict(env_config)))


def build_config(env_runners: int = 1, train_batch: int = 4000, seed: int = 0, tiny: bool = False):
    """The ``PPOConfig``: ``--tiny`` makes the batch, the network and the episodes small."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    env_config = {"max_episode_steps": TINY["max_episode_steps"]} if tiny else {}
    if tiny:
        train_batch = TINY["train_batch"]
    minibatch = TINY["minibatch"] if tiny else min(128, train_batch)
    return (
        PPOConfig()
        .environment(ENV_NAME, env_config=env_config)
        .framework("torch")
        .env_runners(num_env_runners=env_runners, num_envs_per_env_runner=1,
                     num_cpus_per_env_runner=1, rollout_fragment_length="auto")
        .learners(num_learners=0, num_gpus_per_learner=0)  # learns in this process, on the CPU
        .training(train_batch_size_per_learner=train_batch, minibatch_size=minibatch,
                  num_epochs=TINY["epochs"] if tiny else 10, lr=3e-4, gamma=0.99)
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=TINY["hiddens"] if tiny else [64, 64]))
        .debugging(seed=seed)
    )


def _flat_weights(state) -> dict:
    """{name: float64 array} of a (nested) module state dict."""
    import numpy as np

    out = {}
    for key, value in state.items():
        if isinstance(value, dict):
            out.update({f"{key}/{k}": v for k, v in _flat_weights(value).items()})
        elif hasattr(value, "shape"):
            out[key] = np.array(value.detach().cpu() if hasattr(value, "detach") else value, dtype=np.float64)
    return out


def runner_weights(algo) -> dict:
    """The policy weights of the first env runner (a remote process when there is one)."""
    if algo.env_runner_group.num_remote_env_runners() > 0:
        states = algo.env_runner_group.foreach_env_runner(
            lambda runner: runner.module.get_state(), local_env_runner=False)
        return _flat_weights(states[0])
    return _flat_weights(algo.get_module().get_state())


def summarize(result: dict, seconds: float) -> dict:
    """One iteration's figures from RLlib's result dict (new API stack keys)."""
    from ray.rllib.core import DEFAULT_MODULE_ID

    runners = result.get("env_runners", {})
    learner = result.get("learners", {}).get(DEFAULT_MODULE_ID, {})
    losses = {k: float(learner[k]) for k in ("total_loss", "policy_loss", "vf_loss") if k in learner}
    return {
        "iteration": int(result["training_iteration"]),
        "env_steps": int(runners.get("num_env_steps_sampled", 0)),
        "env_steps_lifetime": int(runners.get("num_env_steps_sampled_lifetime", 0)),
        "episodes_lifetime": int(runners.get("num_episodes_lifetime", 0)),
        "episode_return_mean": float(runners.get("episode_return_mean", math.nan)),
        "losses": losses,
        "seconds": seconds,
    }


def train(iterations: int = 10, env_runners: int = 1, train_batch: int = 4000, seed: int = 0,
          tiny: bool = False) -> dict:
    """Train PPO for ``iterations`` and print a line each; Ray is shut down however it ends.

    Returns ``{"iterations": [summarize(...) per iteration], "weight_change": max |Δw| of the
    first env runner's policy from before the first iteration to after the last}``.
    """
    import numpy as np
    import ray
    from ray.tune.registry import register_env

    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no usage report leaves the machine
    if tiny:
        iterations = 1
    ray.init(num_cpus=max(os.cpu_count() or 1, env_runners), num_gpus=0, include_dashboard=False,
             runtime_env={"env_vars": WORKER_ENV}, logging_level="warning")
    try:
        register_env(ENV_NAME, make_env)
        algo = build_config(env_runners, train_batch, seed, tiny).build_algo()
        before = runner_weights(algo)
        rows = []
        for _ in range(iterations):
            start = time.perf_counter()
            row = summarize(algo.train(), time.perf_counter() - start)
            rows.append(row)
            print(f"iter {row['iteration']:3d}  env steps {row['env_steps']:6d} "
                  f"({row['env_steps_lifetime']} in all)  return mean {row['episode_return_mean']:8.3f}  "
                  f"loss {row['losses'].get('total_loss', math.nan):8.4f}  {row['seconds']:6.1f} s", flush=True)
        after = runner_weights(algo)
        change = max(float(np.max(np.abs(after[k] - before[k]))) for k in before if k in after)
        algo.stop()
        return {"iterations": rows, "weight_change": change}
    finally:
        ray.shutdown()


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=10, help="training iterations (default 10)")
    parser.add_argument("--env-runners", type=int, default=1, help="env runner processes (default 1)")
    parser.add_argument("--train-batch", type=int, default=4000, help="env steps per iteration (default 4000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tiny", action="store_true",
                        help=f"smoke run: 1 iteration of {TINY['train_batch']} steps, "
                             f"{TINY['max_episode_steps']}-step episodes, a {TINY['hiddens']} network")
    args = parser.parse_args(argv)
    return train(args.iterations, args.env_runners, args.train_batch, args.seed, args.tiny)


if __name__ == "__main__":
    main()
