"""Headless MuJoCo rendering: an OpenGL backend that works here, chosen once per process.

MuJoCo picks its GL backend from ``$MUJOCO_GL`` when it is imported (GLFW, which needs a
display, when unset). Without a display and without ``$MUJOCO_GL``, the first render tries
``egl`` then ``osmesa`` (each in a short subprocess, so a failing driver cannot break this
process) and renders through the first that works. ``$MUJOCO_GL`` set by the user is used as is.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
import weakref

import numpy as np

__all__ = ["gl_backend", "MujocoFrameRenderer"]

_PROBE = """
import mujoco
m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom type="sphere" size=".1"/></worldbody></mujoco>')
r = mujoco.Renderer(m, 8, 8)
d = mujoco.MjData(m)
r.update_scene(d)
r.render()
"""
_CHOSEN: list[str] = []  # the backend of this process, once chosen
_TRIED: dict[str, str] = {}
_LIVE_REGISTERED: list[bool] = []
_LIVE: "weakref.WeakSet[MujocoFrameRenderer]" = weakref.WeakSet()


def _close_all() -> None:
    # free the GL contexts before the backend's own exit hook (MuJoCo's EGL module terminates its
    # display at exit) and while OpenGL is still loaded: not in __del__ at shutdown
    for r in list(_LIVE):
        try:
            r.close()
        except Exception:  # noqa: BLE001 - at exit, nothing is left to do about it
            pass


def _works(backend: str) -> bool:
    env = {**os.environ, "MUJOCO_GL": backend}
    env.pop("PYOPENGL_PLATFORM", None)
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        _TRIED[backend] = "timed out"
        return False
    if out.returncode != 0:
        lines = [ln for ln in out.stderr.strip().splitlines() if ln.strip()]
        _TRIED[backend] = lines[-1] if lines else f"exit status {out.returncode}"
    return out.returncode == 0


def gl_backend() -> str:
    """The GL backend MuJoCo renders through in this process (``$MUJOCO_GL``, else the first
    of ``egl``, ``osmesa`` that works without a display, else ``glfw`` with one). Raises
    ``RuntimeError`` saying what was tried when none works."""
    if _CHOSEN:
        return _CHOSEN[0]
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if not chosen:
        if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
            chosen = "glfw"
        else:
            for cand in ("egl", "osmesa"):
                if _works(cand):
                    chosen = cand
                    break
            else:
                tried = "; ".join(f"{k}: {v}" for k, v in _TRIED.items())
                raise RuntimeError(f"MuJoCo cannot render here: no display and no working headless OpenGL backend "
                                   f"({tried}); install EGL drivers or OSMesa (Debian: apt-get install libosmesa6), "
                                   f"or set MUJOCO_GL")
    _install(chosen)
    _CHOSEN.append(chosen)
    return chosen


def _install(backend: str) -> None:
    """Make ``mujoco.Renderer`` create its contexts with ``backend`` (MuJoCo chose one at import)."""
    from mujoco.rendering.classic import gl_context

    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        return  # glfw / the platform's own: what MuJoCo chose at import
    gl_context.GLContext = GLContext


class MujocoFrameRenderer:
    """Draws one sub-env's ``MjData`` with a camera that tracks a body (Gymnasium's view)."""

    def __init__(self, model, *, width: int, height: int, track_body: int, distance: float,
                 elevation: float) -> None:
        import mujoco

        gl_backend()
        self._renderer = mujoco.Renderer(model, height=height, width=width)
        cam = mujoco.MjvCamera()
        mujoco.mjv_defaultFreeCamera(model, cam)
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = track_body
        cam.distance = distance
        cam.elevation = elevation
        self._camera = cam
        if not _LIVE_REGISTERED:  # after the first GL context (whose backend registers its own exit hook):
            atexit.register(_close_all)  # atexit runs last-registered first, so this closes ours before
            _LIVE_REGISTERED.append(True)
        _LIVE.add(self)

    def render(self, data) -> np.ndarray:
        self._renderer.update_scene(data, camera=self._camera)
        return np.ascontiguousarray(self._renderer.render())

    def close(self) -> None:
        renderer, self._renderer = self._renderer, None
        if renderer is not None:
            renderer.close()
