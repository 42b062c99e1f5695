"""Package names loaded on first use (PEP 562), for every package ``__init__`` of the project.

    _LAZY = {"Camera": "localizer.model.camera", "PRESETS": "agvsim.vehicle.encoders:PRESETS"}
    __all__ = sorted(_LAZY)
    __getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())

A target is ``"module"`` (the attribute of the same name) or ``"module:attribute"``.
Importing a package then imports none of its heavy modules (numba, pymunk, OpenGL).
"""
from __future__ import annotations

import importlib
from typing import Any, Callable, Mapping

__all__ = ["lazy_exports"]


def lazy_exports(package: str, names: Mapping[str, str],
                 namespace: dict) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` exporting ``names`` lazily."""

    def __getattr__(name: str) -> Any:
        target = names.get(name)
        if target is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, attr = target.partition(":")
        return getattr(importlib.import_module(module), attr or name)

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return __getattr__, __dir__
