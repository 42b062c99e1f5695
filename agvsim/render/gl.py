"""Headless OpenGL platform choice for pyrender (EGL first, OSMesa as fallback).

PyOpenGL binds its platform (``PYOPENGL_PLATFORM``) when ``OpenGL`` is first
imported, and pyrender imports ``OpenGL`` at import time, so the choice must be
made before the first ``import pyrender``. :func:`import_pyrender` does that,
and it is only called when a frame is first needed (never at import of
:mod:`agvsim.render`), so building a renderer opens no GL context and a
process may fork safely before its first frame.

Order of preference:

1. ``PYOPENGL_PLATFORM`` already set by the user (``egl`` or ``osmesa``): honoured.
2. EGL (Mesa's ``libEGL.so.1``; software rasterizer llvmpipe when there is no GPU):
   probed with ctypes (load the library, ``eglGetDisplay`` + ``eglInitialize``)
   without importing PyOpenGL.
3. OSMesa (``libOSMesa.so``; needs PyOpenGL >= 3.1.5), about 3x slower.

When neither works, :class:`RenderUnavailable` says what to install.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

PLATFORMS: tuple[str, ...] = ("egl", "osmesa")

INSTALL_HINT = (
    "no headless OpenGL platform works: install Mesa's EGL "
    "(Debian/Ubuntu: `apt-get install libegl1 libgl1-mesa-dri libgbm1`) "
    "or OSMesa (`apt-get install libosmesa6`), and PyOpenGL >= 3.1.9 "
    "(`pip install 'PyOpenGL>=3.1.9'`); or set PYOPENGL_PLATFORM=egl|osmesa to force one"
)


class RenderUnavailable(RuntimeError):
    """No headless OpenGL platform could be used; the message says what to install."""


def _load(names: tuple[str, ...]):
    for name in names:
        path = ctypes.util.find_library(name) if "." not in name else name
        if not path:
            continue
        try:
            return ctypes.CDLL(path)
        except OSError:
            continue
    return None


def egl_works() -> bool:
    """Whether an EGL display can be initialised (ctypes probe; PyOpenGL is not imported)."""
    lib = _load(("libEGL.so.1", "EGL"))
    if lib is None:
        return False
    try:
        lib.eglGetDisplay.restype = ctypes.c_void_p
        lib.eglGetDisplay.argtypes = [ctypes.c_void_p]
        lib.eglInitialize.restype = ctypes.c_uint
        lib.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]
        display = lib.eglGetDisplay(None)  # EGL_DEFAULT_DISPLAY
        if not display:
            return False
        major, minor = ctypes.c_int(), ctypes.c_int()
        return bool(lib.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor)))
    except (AttributeError, OSError):
        return False


def osmesa_works() -> bool:
    """Whether libOSMesa can be loaded."""
    return _load(("libOSMesa.so.8", "libOSMesa.so.6", "OSMesa")) is not None


def choose_platform() -> str:
    """The platform to use (``"egl"`` or ``"osmesa"``), honouring ``PYOPENGL_PLATFORM``.

    Raises:
        RenderUnavailable: neither platform works (the message names what to install).
        ValueError: ``PYOPENGL_PLATFORM`` names something that is not headless.
    """
    forced = os.environ.get("PYOPENGL_PLATFORM")
    if forced:
        if forced not in PLATFORMS:
            raise ValueError(f"PYOPENGL_PLATFORM={forced!r} is not a headless platform; "
                             f"expected one of {', '.join(PLATFORMS)} (or unset it)")
        return forced
    if egl_works():
        return "egl"
    if osmesa_works():
        return "osmesa"
    raise RenderUnavailable(INSTALL_HINT)


def import_pyrender():
    """Choose the platform (if pyrender/OpenGL are not imported yet) and import pyrender.

    Returns:
        ``(pyrender_module, platform_name)``.
    Raises:
        RenderUnavailable: no platform works, or pyrender/PyOpenGL cannot be imported.
    """
    if "OpenGL" in sys.modules or "pyrender" in sys.modules:
        platform = os.environ.get("PYOPENGL_PLATFORM", "")
        if platform not in PLATFORMS:
            raise RenderUnavailable(
                "OpenGL was imported before agvsim.render chose a headless platform "
                f"(PYOPENGL_PLATFORM={platform!r}); set PYOPENGL_PLATFORM=egl before importing OpenGL")
    else:
        platform = choose_platform()
        os.environ["PYOPENGL_PLATFORM"] = platform
    try:
        import pyrender
    except ImportError as exc:
        raise RenderUnavailable(f"cannot import pyrender ({exc}); `pip install pyrender2` "
                                "(a maintained fork that imports as pyrender). " + INSTALL_HINT) from exc
    return pyrender, platform


def create_offscreen(width: int, height: int):
    """A pyrender ``OffscreenRenderer`` of ``width x height`` pixels on the chosen platform.

    Raises:
        RenderUnavailable: the GL context could not be created (message names what to install).
    """
    pyrender, platform = import_pyrender()
    try:
        return pyrender.OffscreenRenderer(viewport_width=int(width), viewport_height=int(height)), platform
    except Exception as exc:  # noqa: BLE001 - any platform failure becomes one clear error
        raise RenderUnavailable(f"could not create a {platform} OpenGL context ({type(exc).__name__}: {exc}); "
                                + INSTALL_HINT) from exc
