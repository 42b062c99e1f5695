"""A strip of camera frames along a route, with the targets the localizer found (for ``agvsim demo``).

    >>> from agvsim.sensors.render.strip import route_poses, save_camera_strip
    >>> floor = load_map("plant_floor")
    >>> summary = save_camera_strip(floor, route_poses(floor, 8), "out/demo/camera_strip.png",
    ...                             rng=np.random.default_rng(0))
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from localizer.model.camera import Camera


def route_poses(world_map, n: int, route: str = "default", mount=None,
                lookahead_target: bool = True) -> list[tuple[float, float, float]]:
    """``n`` vehicle poses ``(x, y, θ)`` spread evenly along a route's straight legs, heading along the leg.

    With ``lookahead_target`` each pose is moved to the nearest point of its leg from
    which the camera (``mount``, default forward-looking; on ``plant_floor``'s
    counter-clockwise ring the targets are on the right: ``CameraMount.side_looking("right")``)
    sees a target 2-8 m away near its optical axis, when there is one, so the strip
    shows targets rather than blank walls.
    """
    from agvsim.sensors.render.mount import CameraMount

    mount = mount if mount is not None else CameraMount()
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n!r}")
    pts = np.array([s.position for s in world_map.route(route)])
    seg = np.diff(pts, axis=0)
    lens = np.linalg.norm(seg, axis=1)
    keep = lens > 1e-9
    pts0, seg, lens = pts[:-1][keep], seg[keep], lens[keep]
    cum = np.concatenate([[0.0], np.cumsum(lens)])
    out = []
    for k in range(n):
        s = (k + 0.5) / n * cum[-1]
        i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(lens) - 1)
        heading = math.atan2(seg[i, 1], seg[i, 0])
        if lookahead_target:
            s = _best_station(world_map, pts0[i], seg[i] / lens[i], lens[i], s - cum[i], mount.yaw) + cum[i]
        p = pts0[i] + seg[i] / lens[i] * (s - cum[i])
        out.append((float(p[0]), float(p[1]), heading))
    return out


def _best_station(world_map, a, e, length, s0, yaw: float = 0.0) -> float:
    """Along-leg position (m from ``a`` along unit ``e``) nearest ``s0`` from which some target is
    2-8 m away, within 13 deg of the camera axis (the leg direction turned by ``yaw``) and seen
    at most 70 deg off its normal, with a clear line of sight; ``s0`` when there is none."""
    c, si = math.cos(yaw), math.sin(yaw)
    axis = np.array([c * e[0] - si * e[1], si * e[0] + c * e[1]])
    best, best_cost = s0, math.inf
    for s in np.linspace(0.0, length, max(2, int(length / 0.25) + 1)):
        p = a + e * s
        for t in world_map.targets:
            v = t.position - p
            d = float(np.linalg.norm(v))
            if not 2.0 <= d <= 8.0:
                continue
            bearing = math.atan2(axis[0] * v[1] - axis[1] * v[0], axis[0] * v[0] + axis[1] * v[1])
            facing = float(np.dot(t.normal, -v)) / d
            if abs(bearing) < math.radians(13) and facing > 0.34 and \
                    world_map.line_of_sight(p, t.position + 0.05 * t.normal):
                cost = abs(s - s0)
                if cost < best_cost:
                    best, best_cost = float(s), cost
    return best


#: what the strip's marks mean, drawn across its top
LEGEND = ("Camera frames at true poses along the route.  Green: bar edges found; red: bar heights;",
          "yellow: the localizer's d, α, β;  magenta box: a decoy sign (not a target: it must not be found).")
CAPTION_PX = 14  # text size (px) at the strip's final size: capitals about 10 px high
_DECOY_NAMES = {"bars_sign": "two-bar look-alike", "striped_sign": "striped sign", "barcode": "barcode",
                "hazard_sign": "hazard sign"}
_DECOY = (255, 0, 255)  # BGR magenta
_TEXT, _DIM, _OK, _WARN = (255, 255, 255), (200, 200, 200), (120, 230, 120), (80, 170, 255)


def decoys_in_view(distractors, world_map, camera: Camera, cam_pose) -> list[tuple[str, np.ndarray]]:
    """The scene's distractors (decoy signs) the camera at ``cam_pose`` sees: ``(kind, (4, 2) pixel
    corners)`` for each one in front of the camera, facing it, with its centre inside the frame and
    a clear line of sight to it."""
    out = []
    lens = np.asarray(cam_pose.position, float)
    for d in distractors:
        c = np.asarray(d.centre, float)
        n = np.asarray(d.normal, float)
        if float(np.dot(n, lens[:2] - c[:2])) <= 0.0:
            continue
        t = np.array([-n[1], n[0]])
        w, h = 0.5 * d.size[0], 0.5 * d.size[1]
        quad = np.array([[*(c[:2] + s * w * t), c[2] + v * h] for s, v in ((-1, 1), (1, 1), (1, -1), (-1, -1))])
        pts = cam_pose.to_camera(np.vstack([quad, c]))
        if np.any(pts[:, 2] < 0.2):
            continue
        px = camera.project(pts)
        if not (0 <= px[4, 0] < camera.width and 0 <= px[4, 1] < camera.height):
            continue
        if world_map.line_of_sight(lens[:2], c[:2] + 0.05 * n):
            out.append((d.kind, px[:4]))
    return out


def _caption(width: int, lines: list[tuple[str, tuple[int, int, int]]]) -> np.ndarray:
    """A dark band ``width`` px wide with one line of text per ``(text, BGR colour)``."""
    from localizer.tools.annotation import draw_text, text_box

    step = text_box("Ag", CAPTION_PX, 0)[1] + 4
    band = np.full((6 + step * len(lines), width, 3), 32, np.uint8)
    for i, (text, colour) in enumerate(lines):
        draw_text(band, text, (6, 3 + i * step), CAPTION_PX, color=colour, halo_color=None)
    return band


def _mark_decoys(tile: np.ndarray, decoys, scale: float) -> None:
    """Outline each decoy on ``tile`` and write "decoy" next to it (at the tile's size)."""
    import cv2

    from localizer.tools.annotation import draw_text, text_box

    for _, px in decoys:
        q = np.round(px * scale).astype(np.int32)
        cv2.polylines(tile, [q], True, _DECOY, 2, cv2.LINE_AA)
        w, h = text_box("decoy", CAPTION_PX)
        x = int(np.clip(q[:, 0].min(), 0, tile.shape[1] - w))
        y = int(q[:, 1].min()) - h - 2
        if y < 0:
            y = int(min(q[:, 1].max() + 2, tile.shape[0] - h))
        draw_text(tile, "decoy", (x, y), CAPTION_PX, color=_DECOY, halo_color=(0, 0, 0))


def _matches(obs, vis) -> list[dict]:
    """Each observation with the visible target nearest in bearing (within 0.03 rad) and its errors."""
    found = []
    for o in obs:
        match = min(vis, key=lambda t: abs(t.beta - o.beta), default=None)
        if match is not None and abs(match.beta - o.beta) > 0.03:
            match = None
        found.append({"distance": o.distance, "alpha": o.alpha, "beta": o.beta, "polarity": o.polarity,
                      "target": match.id if match else None,
                      "distance_error": (o.distance - match.distance) if match else None,
                      "alpha_error": (o.alpha - match.alpha) if match else None})
    return found


def _tile_lines(k: int, pose, n_visible: int, found: list[dict], decoys) -> list[tuple]:
    """The caption of tile ``k``: ``(text, colour)`` lines: the pose, targets in view and found, decoys."""
    wrong = sum(f["target"] is None for f in found)
    right = len(found) - wrong
    lines = [(f"#{k + 1}  x={pose[0]:.1f} m  y={pose[1]:.1f} m  θ={math.degrees(pose[2]):.0f}°", _TEXT),
             (f"targets: {n_visible} in view, {right} found" + (f", {wrong} false" if wrong else ""),
              _OK if right == n_visible and not wrong else _WARN)]
    if decoys:
        names = sorted({_DECOY_NAMES.get(kind, kind.replace("_", " ")) for kind, _ in decoys})
        lines.append((f"decoy{'s' if len(decoys) > 1 else ''}: " + ", ".join(names), _DECOY))
    else:
        lines.append(("no decoy in view", _DIM))
    return lines


def save_camera_strip(world_map, poses, path, camera: Camera | None = None, rng: np.random.Generator | None = None,
                      renderer=None, mount=None, conditions=None, columns: int = 4, scale: float = 0.5) -> dict:
    """Render frames at the true ``poses``, run :func:`localizer.detect_targets` on each,
    annotate what it found and tile the frames into one PNG.

    Each tile is the frame at ``scale`` with the localizer's marks and labels (drawn at the
    tile's size), decoy signs in view outlined, and a caption below it (pose, targets in view and
    found, decoys); a legend across the top says what the marks mean.

    Args:
        world_map: the map (ignored for rendering when ``renderer`` is given).
        poses: sequence of ``(x m, y m, θ rad)`` true vehicle poses.
        path: output PNG.
        camera: intrinsics (default thesis 16 mm); ignored when ``renderer`` is given.
        rng: randomness for sensor noise (default: ``numpy.random.default_rng(0)``).
        renderer: an existing :class:`~agvsim.sensors.render.renderer.CameraRenderer` to reuse
            (recommended: one per process).
        mount, conditions: for a new renderer / every frame.
        columns: frames per row of the strip. scale: size of each tile relative to the frame.
    Returns:
        ``{"path", "frames": [{"pose", "visible", "decoys", "found": [{"distance", "alpha", "beta",
        "polarity", "target", "distance_error", "alpha_error"}]}]}`` (SI units; ``decoys``: the
        kinds of the decoy signs in view).
    """
    import cv2

    from localizer import annotate, detect_targets
    from agvsim.sensors.render.mount import CameraPose
    from agvsim.sensors.render.renderer import CameraRenderer, RenderConditions
    from agvsim.sensors.render.scene import build_scene

    if renderer is None:
        renderer = CameraRenderer(world_map, camera=camera, mount=mount)
    rng = rng if rng is not None else np.random.default_rng(0)
    conditions = conditions if conditions is not None else RenderConditions()
    distractors = build_scene(renderer.map).distractors
    tiles, frames = [], []
    for k, pose in enumerate(poses):
        image, truth = renderer.render(pose, conditions, rng)
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        obs = detect_targets(grey, renderer.camera)
        vis = [t for t in truth.targets if t.visible]
        decoys = decoys_in_view(distractors, renderer.map, renderer.camera,
                                CameraPose.from_vehicle(renderer.mount, pose))
        found = _matches(obs, vis)
        frames.append({"pose": [float(v) for v in pose], "visible": [t.id for t in vis],
                       "decoys": [kind for kind, _ in decoys], "found": found})
        tile = annotate(grey, obs, scale=scale)
        _mark_decoys(tile, decoys, scale)
        tiles.append(np.vstack([tile, _caption(tile.shape[1], _tile_lines(k, pose, len(vis), found, decoys))]))
    if not tiles:
        raise ValueError("poses is empty")
    columns = max(1, min(columns, len(tiles)))
    blank = np.full_like(tiles[0], 32)
    while len(tiles) % columns:
        tiles.append(blank)
    for t in tiles:  # a 2 px gap between tiles
        t[:, -2:] = 255
        t[-2:, :] = 255
    rows = [np.hstack(tiles[i:i + columns]) for i in range(0, len(tiles), columns)]
    body = np.vstack(rows)
    head = _caption(body.shape[1], [(line, _TEXT) for line in LEGEND])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), np.vstack([head, body])):
        raise ValueError(f"could not write {path}")
    return {"path": str(path), "frames": frames}
