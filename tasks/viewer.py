"""The dm_control viewer with the task drawn (goals by belief, polytopes, the preferred route,
pushes and cues: :mod:`.drawing`)::

    from pathpref_tasks import load, viewer
    viewer.launch(lambda: load("navigate_control", map="office"))

``dm_control.viewer.launch`` builds its scene camera without a scene callback (its
``Application`` gives none), so :func:`launch` is dm_control's ``launch`` with
:func:`scene_callback` handed to the application's viewer (``app._viewer._scene_callback``,
read when the viewer initialises for each loaded environment). Needs a display (GLFW).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


def scene_callback(environment: Callable[[], Any]) -> Callable[[Any, Any, Any], None]:
    """The viewer's ``scene_callback(model, data, scene)``: draws the task of the
    environment ``environment()`` returns now (nothing while there is none or its physics
    has no drawing)."""

    def draw(model, data, scn) -> None:
        env = environment()
        drawing = getattr(getattr(env, "physics", None), "drawing", None)
        if drawing is not None:
            drawing(scn)

    return draw


def launch(environment_loader, policy=None, title: str = "pathpref", width: int = 1024,
           height: int = 768) -> None:
    """``dm_control.viewer.launch`` (same arguments) with the task drawn in every frame."""
    from dm_control.viewer import application

    app = application.Application(title=title, width=width, height=height)
    app._viewer._scene_callback = scene_callback(lambda: app._environment)
    app.launch(environment_loader=environment_loader, policy=policy)
