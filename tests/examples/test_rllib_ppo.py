"""examples/rllib_ppo.py: one tiny PPO iteration through an RLlib env runner process learns.

Needs the ``rllib`` extra (``make test`` installs it); skipped without Ray's RLlib or torch.
About 20-30 s: Ray's start and the env runner's imports are most of it.
"""
import importlib.util
import math
from pathlib import Path

import pytest

pytest.importorskip("ray.rllib")
pytest.importorskip("torch")

SCRIPT = Path(__file__).resolve().parents[2] / "examples" / "rllib_ppo.py"


def load_example():
    spec = importlib.util.spec_from_file_location("rllib_ppo", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_tiny_ppo_iteration_samples_through_the_env_runner_and_learns(capsys):
    example = load_example()
    tiny = example.TINY
    result = example.train(iterations=5, env_runners=1, seed=0, tiny=True)

    (row,) = result["iterations"]  # --tiny: one iteration, whatever was asked
    assert row["iteration"] == 1
    # the env runner sampled about one tiny batch ("auto" rollout fragments: exactly, here)
    assert tiny["train_batch"] <= row["env_steps"] <= 1.25 * tiny["train_batch"]
    assert row["env_steps_lifetime"] == row["env_steps"]
    # episodes were cut at the tiny max_episode_steps (the registered 3000 would finish none)
    assert row["episodes_lifetime"] >= tiny["train_batch"] // tiny["max_episode_steps"] - 1
    assert math.isfinite(row["episode_return_mean"])
    # the learner updated on finite losses, and the new weights reached the env runner
    assert {"total_loss", "policy_loss", "vf_loss"} <= set(row["losses"])
    assert all(math.isfinite(v) for v in row["losses"].values())
    assert result["weight_change"] > 0.0
    out = capsys.readouterr().out
    assert f"env steps {row['env_steps']:6d}" in out and "return mean" in out
