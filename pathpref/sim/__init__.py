"""The MuJoCo layer: physics only (scene from a map, bases and arm, force sensing and cue
detection, controllers, rendering); it registers the ``mujoco`` body (:mod:`.body`) with the
episode layer when imported. Importing it sets ``MUJOCO_GL=egl`` when unset (headless rendering),
before any submodule imports mujoco: mujoco picks its GL backend at import time, and fails
there when that backend's system library is missing, so the import is checked here."""

import os

from ..errors import ConfigError

os.environ.setdefault("MUJOCO_GL", "egl")

GL_HELP = ("no working OpenGL backend for headless rendering (MUJOCO_GL={gl}): on Debian "
           "install libegl1 libgl1-mesa-dri libopengl0 for EGL, or libosmesa6 and set "
           "MUJOCO_GL=osmesa (MUJOCO_GL=disable runs physics without rendering)")

#: MUJOCO_GL values mujoco accepts on Linux (the documented ones first)
GL_BACKENDS = ("egl", "osmesa", "glfw", "disable", "glx", "disabled", "off", "false", "0",
               "enable", "enabled", "on", "true", "1", "")
_gl = os.environ.get("MUJOCO_GL", "")
if _gl.lower().strip() not in GL_BACKENDS:
    raise ConfigError(f"MUJOCO_GL={_gl[:40]!r} is not a rendering backend; set MUJOCO_GL to "
                      "one of egl, osmesa, glfw or disable (physics without rendering), or "
                      "unset it (egl)")

try:
    import mujoco  # noqa: F401
except (ImportError, AttributeError, OSError, RuntimeError) as e:
    raise ConfigError(GL_HELP.format(gl=os.environ.get("MUJOCO_GL")) + f" ({e})") from None

from . import body  # noqa: E402,F401 - registers the "mujoco" body with the episode layer
