"""The 2-D parts of a rollout video frame: the colours of goal probabilities, the info panel
(method, ΔT, map, step, time, what the human and the robot just did, the goal belief as a bar
chart with its legend) and the composition with the 3-D views of
:class:`pathpref.sim.render.RolloutRenderer`.

Frame layout (``W`` x ``H``, 960 x 540 by default)::

    +------------------+-----------------+
    |                  |   perspective   |
    |   top view       +-----------------+
    |   (H x H)        |   info panel    |
    |                  |  text, P(goal)  |
    +------------------+-----------------+

Goal colours are absolute: probability ``p`` maps through matplotlib's ``viridis`` (0: dark
purple, 1: yellow), so a uniform belief over 10 goals paints every goal the same dark colour
(``p = 0.1``), never bright.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from PIL import Image, ImageDraw, ImageFont

BG = (248, 248, 250)
INK = (25, 25, 35)
PUSH_RGB = (230, 30, 30)
CUE_RGB = (25, 200, 75)
TRUE_GOAL_RGB = (255, 77, 178)
ROBOT_RGB = (25, 100, 255)
PREF_RGB = (50, 50, 56)
POLY_RGB = (255, 215, 25)
HEADING_NAMES = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


def belief_rgba(p: np.ndarray, alpha: float = 0.95) -> np.ndarray:
    """RGBA in [0, 1] of probabilities ``p`` (absolute: viridis of ``clip(p, 0, 1)``)."""
    from matplotlib import colormaps

    rgba = colormaps["viridis"](np.clip(np.asarray(p, float), 0.0, 1.0))
    rgba[..., 3] = alpha
    return rgba


@lru_cache(maxsize=8)
def font(px: int) -> ImageFont.ImageFont:
    """DejaVu Sans (shipped with matplotlib; it has Δ) at ``px`` pixels, else Pillow's
    built-in font."""
    from matplotlib import font_manager

    try:
        return ImageFont.truetype(font_manager.findfont("DejaVu Sans"), px)
    except OSError:  # pragma: no cover - no FreeType
        return ImageFont.load_default()


@dataclass
class PanelInfo:
    """The text and chart of one frame's panel."""

    title: str
    step: int
    t_max: int
    sim_time: float
    belief: np.ndarray
    true_goal: int
    pushes: int = 0
    #: events shown this frame: "push" (with its force in N) and "cue" (detected heading)
    push_n: float | None = None
    cue_heading: int | None = None
    extra: list[str] = field(default_factory=list)


def info_panel(width: int, height: int, info: PanelInfo) -> np.ndarray:
    """The panel (``height`` x ``width`` x 3, uint8): text lines, the goal belief as bars in
    their goal colours on an absolute 0..1 axis with the true goal marked, and the legend."""
    img = Image.new("RGB", (width, height), BG)
    d = ImageDraw.Draw(img)
    u = max(8, height // 18)  # text line height
    f, fs = font(u), font(max(7, int(u * 0.8)))
    x0, y = max(4, width // 40), max(2, u // 4)
    d.text((x0, y), info.title, fill=INK, font=f)
    y += int(u * 1.25)
    d.text((x0, y), f"step {info.step}/{info.t_max}   t = {info.sim_time:5.1f} s   "
           f"pushes {info.pushes}", fill=INK, font=fs)
    y += int(u * 1.15)
    events = []
    if info.push_n is not None:
        events.append((f"human pushes: {info.push_n:.0f} N", PUSH_RGB))
    if info.cue_heading is not None:
        events.append((f"robot detected: {HEADING_NAMES[info.cue_heading]}", CUE_RGB))
    ex = x0
    for text, rgb in events:
        d.text((ex, y), text, fill=rgb, font=fs)
        ex += int(d.textlength(text, font=fs)) + u
    y += int(u * 1.2)
    # bar chart of P(goal)
    legend_h = int(u * 2.4)
    chart_top, chart_bottom = y + u // 2, height - legend_h - u
    n = len(info.belief)
    if n and chart_bottom - chart_top > 10:
        axis_x = x0 + int(d.textlength("1.0", font=fs)) + 4
        span = max(1, width - axis_x - x0)
        bw = span / n
        d.line([(axis_x, chart_top), (axis_x, chart_bottom)], fill=INK)
        d.line([(axis_x, chart_bottom), (width - x0, chart_bottom)], fill=INK)
        for v, label in ((1.0, "1.0"), (0.5, "0.5"), (0.0, "0")):
            yy = chart_bottom - v * (chart_bottom - chart_top)
            d.text((x0, yy - u // 2), label, fill=INK, font=fs)
            if v > 0:
                d.line([(axis_x, yy), (width - x0, yy)], fill=(215, 215, 222))
        rgb = (belief_rgba(info.belief)[:, :3] * 255).astype(int)
        for k, p in enumerate(info.belief):
            left = axis_x + k * bw + bw * 0.15
            right = axis_x + (k + 1) * bw - bw * 0.15
            top = chart_bottom - float(np.clip(p, 0, 1)) * (chart_bottom - chart_top)
            d.rectangle([left, min(top, chart_bottom - 1), right, chart_bottom],
                        fill=tuple(rgb[k]),
                        outline=TRUE_GOAL_RGB if k == info.true_goal else None,
                        width=max(1, u // 6))
            label = f"g{k}"
            if d.textlength(label, font=fs) < bw:
                d.text((left, chart_bottom + 1), label, font=fs,
                       fill=TRUE_GOAL_RGB if k == info.true_goal else INK)
        d.text((axis_x + 4 + int(d.textlength("1.0", font=fs)), chart_top - int(u * 0.9)),
               "P(goal)", fill=INK, font=fs)
    # legend: colour bar, then the symbols
    y = height - legend_h
    bar_w = max(10, width // 4)
    ramp = (belief_rgba(np.linspace(0, 1, bar_w))[:, :3] * 255).astype(np.uint8)
    img.paste(Image.fromarray(np.repeat(ramp[None], max(4, u // 2), axis=0)), (x0, y))
    d.text((x0, y + max(4, u // 2)), "0", fill=INK, font=fs)
    d.text((x0 + bar_w - int(d.textlength("1", font=fs)), y + max(4, u // 2)), "1", fill=INK,
           font=fs)
    keys = [("true goal", TRUE_GOAL_RGB), ("robot", ROBOT_RGB), ("push", PUSH_RGB),
            ("detected", CUE_RGB), ("preferred", PREF_RGB), ("polytope", POLY_RGB)]
    kx, ky = x0 + bar_w + u, y - u // 4
    for text, rgb in keys:
        w = int(d.textlength(text, font=fs)) + u
        if kx + w > width - x0:
            kx, ky = x0 + bar_w + u, ky + u
        d.rectangle([kx, ky + u // 4, kx + u // 2, ky + u // 4 + u // 2], fill=rgb)
        d.text((kx + int(u * 0.7), ky), text, fill=INK, font=fs)
        kx += w + u // 2
    return np.asarray(img)


def compose(top: np.ndarray, persp: np.ndarray | None, panel: np.ndarray | None,
            width: int, height: int) -> np.ndarray:
    """The frame (``height`` x ``width`` x 3): top view left, perspective over the panel on
    the right (module docstring)."""
    frame = np.empty((height, width, 3), np.uint8)
    frame[:] = BG
    side = top.shape[1]
    frame[:top.shape[0], :side] = top
    y = 0
    for part in (persp, panel):
        if part is not None:
            h = min(part.shape[0], height - y)
            frame[y:y + h, side:side + part.shape[1]] = part[:h]
            y += h
    return frame


def frame_grid(frames: list[np.ndarray], cols: int = 3, scale: float = 0.5) -> np.ndarray:
    """Frames side by side in rows of ``cols``, each scaled by ``scale`` (a contact sheet)."""
    tiles = []
    for f in frames:
        img = Image.fromarray(np.asarray(f, np.uint8))
        w, h = img.size
        tiles.append(np.asarray(img.resize((max(1, int(w * scale)), max(1, int(h * scale))),
                                           Image.LANCZOS)))
    th, tw = tiles[0].shape[:2]
    rows = -(-len(tiles) // cols)
    grid = np.full((rows * th, cols * tw, 3), 255, np.uint8)
    for k, t in enumerate(tiles):
        r, c = divmod(k, cols)
        grid[r * th:(r + 1) * th, c * tw:(c + 1) * tw] = t[:th, :tw]
    return grid


#: seconds the outcome card is held at the end of a video
CARD_S = 1.0


def outcome_lines(result) -> list[tuple[str, tuple[int, int, int]]]:
    """The outcome card's lines (text, colour) for an :class:`~pathpref.episode.EpisodeResult`:
    success (goal reached by the preferred route), the route, homotopy-level success (goal
    reached in the preferred homotopy class), pushes and steps."""
    good, bad = (20, 140, 60), (190, 30, 30)
    if result.success:
        head = ("SUCCESS: goal reached by the preferred route", good)
    elif result.goal_reached:
        head = ("FAILURE: goal reached by another route", bad)
    else:
        head = ("FAILURE: goal not reached", bad)
    yes = {True: "yes", False: "no"}
    return [head,
            (f"preferred route followed: {yes[bool(result.pref_followed)]}", INK),
            (f"homotopy-level success: {yes[bool(result.homotopy_success)]}", INK),
            (f"pushes: {result.inputs}   steps: {result.steps}", INK)]


def outcome_card(frame: np.ndarray, lines: list[tuple[str, tuple[int, int, int]]]
                 ) -> np.ndarray:
    """``frame`` faded towards white with ``lines`` in a box at its centre (the last frame of
    a video, held)."""
    img = Image.fromarray((0.45 * np.asarray(frame, float) + 0.55 * 255).astype(np.uint8))
    d = ImageDraw.Draw(img)
    w, h = img.size
    u = max(10, h // 16)
    f = font(u)
    tw = max(int(d.textlength(text, font=f)) for text, _ in lines)
    bw, bh = tw + 2 * u, int(len(lines) * u * 1.4) + u
    x, y = (w - bw) // 2, (h - bh) // 2
    d.rectangle([x, y, x + bw, y + bh], fill=(255, 255, 255), outline=INK, width=2)
    for k, (text, rgb) in enumerate(lines):
        d.text((x + u, y + u // 2 + int(k * u * 1.4)), text, fill=rgb, font=f)
    return np.asarray(img)
