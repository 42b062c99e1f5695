"""Gymnasium environments over agvsim and localizer.

Importing this package registers the environments under the ``agvsim``
namespace::

    import gymnasium, envs
    env = gymnasium.make("agvsim/PlantFloor-v0", localization="ekf")

or without the import: ``gymnasium.make("envs:agvsim/PlantFloor-v0")``.
No physics, vision or filtering lives here: see :class:`envs.agv_env.AGVEnv`.
"""
from gymnasium.envs.registration import register, registry

from envs.agv_env import AGVEnv
from envs.config import EnvConfig

#: id -> default keyword arguments
#: id -> (default keyword arguments, max_episode_steps)
ENV_SPECS: dict[str, tuple[dict, int]] = {
    "agvsim/PlantFloor-v0": ({"map": "plant_floor", "task": "goto"}, 3000),
    "agvsim/Corridor-v0": ({"map": "corridor", "task": "goto"}, 1500),
    "agvsim/ActiveLocalization-v0": ({"map": "plant_floor", "task": "localize"}, 1000),
}

for _env_id, (_kwargs, _steps) in ENV_SPECS.items():
    if _env_id not in registry:
        register(id=_env_id, entry_point="envs.agv_env:AGVEnv", kwargs=dict(_kwargs),
                 max_episode_steps=_steps)

__all__ = ["AGVEnv", "ENV_SPECS", "EnvConfig"]
