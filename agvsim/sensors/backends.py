"""The renderer backends: the one list behind ``CameraRenderer(backend=...)``,
``agvsim render --backend``, ``RenderedSource(backend=...)`` and the env's ``render_backend``."""
from __future__ import annotations

from localizer.numeric import check_choice

#: backend name -> one-line description (CLI help and docs read this)
BACKENDS: dict[str, str] = {
    "raycast": "compiled column raycaster: exact for the level camera, no OpenGL (default)",
    "pyrender": "OpenGL through pyrender (EGL/llvmpipe headless): the reference and the general 3-D path",
}
DEFAULT_BACKEND = "raycast"


def check_backend(value, name: str = "backend") -> str:
    """``value`` if it names a backend of :data:`BACKENDS`, else ``ValueError`` naming ``name``."""
    return check_choice(name, value, tuple(BACKENDS))


__all__ = ["BACKENDS", "DEFAULT_BACKEND", "check_backend"]
