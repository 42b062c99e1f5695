"""agvsim: a plant-floor simulator for vision-guided AGV navigation.

Import-light on purpose: ``import agvsim`` loads neither numpy, pymunk nor
OpenGL. The names below are imported on first use.

    >>> import agvsim
    >>> floor = agvsim.load_map("plant_floor")
"""
from __future__ import annotations

import importlib
from typing import Any

#: public name -> module that defines it (imported lazily, PEP 562).
_LAZY = {
    "load_map": "agvsim.world.map",
    "Map": "agvsim.world.map",
    "MapError": "agvsim.world.map",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'agvsim' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
