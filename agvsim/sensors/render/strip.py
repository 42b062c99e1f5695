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

from localizer.camera import Camera


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


def save_camera_strip(world_map, poses, path, camera: Camera | None = None, rng: np.random.Generator | None = None,
                      renderer=None, mount=None, conditions=None, columns: int = 4, scale: float = 0.5) -> dict:
    """Render frames at the true ``poses``, run :func:`localizer.detect_targets` on each,
    annotate what it found and tile the frames into one PNG.

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
        ``{"path", "frames": [{"pose", "visible", "found": [{"distance", "alpha", "beta",
        "polarity", "target", "distance_error", "alpha_error"}]}]}`` (SI units).
    """
    import cv2

    from localizer import annotate, detect_targets
    from agvsim.sensors.render.renderer import CameraRenderer, RenderConditions

    if renderer is None:
        renderer = CameraRenderer(world_map, camera=camera, mount=mount)
    rng = rng if rng is not None else np.random.default_rng(0)
    conditions = conditions if conditions is not None else RenderConditions()
    tiles, frames = [], []
    for k, pose in enumerate(poses):
        image, truth = renderer.render(pose, conditions, rng)
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        obs = detect_targets(grey, renderer.camera)
        vis = [t for t in truth.targets if t.visible]
        found = []
        for o in obs:
            match = min(vis, key=lambda t: abs(t.beta - o.beta), default=None)
            if match is not None and abs(match.beta - o.beta) > 0.03:
                match = None
            found.append({"distance": o.distance, "alpha": o.alpha, "beta": o.beta, "polarity": o.polarity,
                          "target": match.id if match else None,
                          "distance_error": (o.distance - match.distance) if match else None,
                          "alpha_error": (o.alpha - match.alpha) if match else None})
        frames.append({"pose": [float(v) for v in pose], "visible": [t.id for t in vis], "found": found})
        tile = annotate(grey, obs)
        label = f"#{k + 1} ({pose[0]:.1f}, {pose[1]:.1f}, {math.degrees(pose[2]):.0f} deg)  " \
                f"visible {len(vis)} found {len(obs)}"
        cv2.putText(tile, label, (6, tile.shape[0] - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(tile, label, (6, tile.shape[0] - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 255, 255), 1,
                    cv2.LINE_AA)
        if scale != 1.0:
            tile = cv2.resize(tile, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        tiles.append(tile)
    if not tiles:
        raise ValueError("poses is empty")
    columns = max(1, min(columns, len(tiles)))
    blank = np.zeros_like(tiles[0])
    while len(tiles) % columns:
        tiles.append(blank)
    rows = [np.hstack(tiles[i:i + columns]) for i in range(0, len(tiles), columns)]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), np.vstack(rows)):
        raise ValueError(f"could not write {path}")
    return {"path": str(path), "frames": frames}
