"""Gymnasium environments over agvsim and localizer.

Importing this package registers the environments under the ``agvsim``
namespace::

    import gymnasium, envs
    env = gymnasium.make("agvsim/PlantFloor-v2", localization="ekf")

or without the import: ``gymnasium.make("envs:agvsim/PlantFloor-v2")``.
Versions: ``-v2`` observes the covariance as its 6 unique entries (``covariance="flat"``,
the flat vector Stable-Baselines3 and RLlib expect), and the status as ``-v1``; ``-v1``
observes the localization status (``observe_status=True``) and the 3 x 3 covariance;
``-v0`` is kept as it was (no ``status`` in the observation).
No physics, vision or filtering lives here: see :class:`envs.agv_env.AGVEnv`.
"""
from gymnasium.envs.registration import register, registry

from envs.agv_env import AGVEnv
from envs.config import EnvConfig

#: name -> (default keyword arguments, max_episode_steps), registered as each version
_BASE_SPECS: dict[str, tuple[dict, int]] = {
    "agvsim/PlantFloor": ({"map": "plant_floor", "task": "goto"}, 3000),
    "agvsim/Corridor": ({"map": "corridor", "task": "goto"}, 1500),
    "agvsim/ActiveLocalization": ({"map": "plant_floor", "task": "localize"}, 1000),
}
#: version suffix -> the keyword arguments it adds (v1: the localization status observed; v2:
#: and the covariance as its 6 unique entries, the flat vector SB3 and RLlib expect)
VERSIONS: dict[str, dict] = {"v0": {}, "v1": {"observe_status": True},
                             "v2": {"observe_status": True, "covariance": "flat"}}

#: id -> (default keyword arguments, max_episode_steps)
ENV_SPECS: dict[str, tuple[dict, int]] = {
    f"{name}-{version}": ({**kwargs, **extra}, steps)
    for version, extra in VERSIONS.items() for name, (kwargs, steps) in _BASE_SPECS.items()
}

for _env_id, (_kwargs, _steps) in ENV_SPECS.items():
    if _env_id not in registry:
        register(id=_env_id, entry_point="envs.agv_env:AGVEnv", kwargs=dict(_kwargs),
                 max_episode_steps=_steps)

__all__ = ["AGVEnv", "ENV_SPECS", "EnvConfig", "VERSIONS"]
