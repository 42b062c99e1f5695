"""Headless OpenGL platform choice for pyrender (EGL first, OSMesa as fallback).

PyOpenGL binds its platform (``PYOPENGL_PLATFORM``) when ``OpenGL`` is first
imported, and pyrender imports ``OpenGL`` at import time, so the choice must be
made before the first ``import pyrender``. :func:`import_pyrender` does that,
and it is only called when a frame is first needed (never at import of
:mod:`agvsim.sensors.render`), so building a renderer opens no GL context and a
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
    """Whether EGL can offer a headless device (ctypes probe; PyOpenGL is not imported).

    Loads ``libEGL.so.1`` and asks ``eglQueryDevicesEXT`` (the extension pyrender's
    EGL platform uses) for at least one device; no display is initialised.
    """
    lib = _load(("libEGL.so.1", "EGL"))
    if lib is None:
        return False
    try:
        lib.eglGetProcAddress.restype = ctypes.c_void_p
        lib.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        addr = lib.eglGetProcAddress(b"eglQueryDevicesEXT")
        if not addr:
            return False
        query = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int))(addr)
        n = ctypes.c_int(0)
        return bool(query(0, None, ctypes.byref(n))) and n.value > 0
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
                "OpenGL was imported before agvsim.sensors.render chose a headless platform "
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


class GLContext:
    """One headless OpenGL context (a pyrender ``OffscreenRenderer``), opened at the first frame.

    Create one per process and share it between renderers (pass it as
    ``CameraRenderer(..., context=ctx)``): pyrender cannot hold two EGL
    contexts in one process safely (deleting the second raised ``EGL_BAD_DISPLAY``).
    Nothing is opened until :meth:`renderer` is first called, so a process may
    build renderers and then fork (Gymnasium's ``AsyncVectorEnv``).

    Attributes (after the first frame):
        platform: ``"egl"`` or ``"osmesa"``.
        startup_s: seconds spent creating the context (s).
    """

    def __init__(self) -> None:
        self._offscreen = None
        self._pid = None
        self._scenes: dict = {}  # map object -> pyrender scene shared by that map's renderers
        self.platform: str | None = None
        self.startup_s: float | None = None

    def shared_scene(self, key, build):
        """The pyrender scene for ``key`` (a map object), built by ``build()`` once per context.

        Renderers of the same map share it (each adds its own camera node), so
        alternating between cameras does not re-upload meshes and textures, which
        pyrender does whenever the scene it renders changes.
        """
        entry = self._scenes.get(id(key))
        if entry is None or entry[0] is not key:
            entry = (key, build())
            self._scenes[id(key)] = entry
        return entry[1]

    @property
    def is_open(self) -> bool:
        """Whether the GL context exists (a frame has been rendered)."""
        return self._offscreen is not None

    def renderer(self, width: int, height: int):
        """The pyrender ``OffscreenRenderer``, created on first use, resized to ``width x height``."""
        import time

        if self._offscreen is not None and self._pid != os.getpid():
            raise RenderUnavailable("this GL context was opened in another process (before a fork); "
                                    "create renderers after forking, or render the first frame in the child")
        if self._offscreen is None:
            t0 = time.perf_counter()
            self._offscreen, self.platform = create_offscreen(width, height)
            self.startup_s = time.perf_counter() - t0
            self._pid = os.getpid()
        r = self._offscreen
        if r.viewport_width != width or r.viewport_height != height:
            r.viewport_width, r.viewport_height = int(width), int(height)
        return r

    def close(self) -> None:
        """Free this context's GL resources (call when this process renders no more frames with it).

        pyrender's own ``OffscreenRenderer.delete`` also calls ``eglTerminate`` on the
        process-wide EGL display, which breaks every other EGL context in the process
        (the ``EGL_BAD_DISPLAY`` trap); here only this context is destroyed and the
        display stays initialised.
        """
        off, self._offscreen = self._offscreen, None
        self._scenes = {}
        if off is None or self._pid != os.getpid():
            return
        platform = getattr(off, "_platform", None)
        if self.platform == "egl" and platform is not None and getattr(platform, "_egl_context", None) is not None:
            from OpenGL.EGL import EGL_NO_CONTEXT, EGL_NO_SURFACE, eglDestroyContext, eglMakeCurrent

            display = platform._egl_display
            try:
                platform.make_current()
                off._renderer.delete()
            finally:
                eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT)
                eglDestroyContext(display, platform._egl_context)
                platform._egl_context = None
                platform._egl_display = None
                off._renderer = None
                off._platform = None  # pyrender's __del__ then has nothing left to delete
        else:
            off.delete()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - never raise from a finaliser
            pass
