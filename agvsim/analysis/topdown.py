"""A top-down picture of a plant floor, drawn with OpenCV.

The static layer (lighting zones, obstacles, walls, targets with their
facing, stations, the axes in metres) is drawn once per view; each call to
:meth:`TopDownView.render` copies it and adds trajectories, covariance ellipses,
the vehicle, the labels (above everything, with a halo) and the key (what every
colour means and a scale bar) in a panel beside the map, never on it.
Images are RGB ``uint8`` arrays of shape (H, W, 3), map +y pointing up.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from agvsim.analysis import topdown_key as tk
from localizer.tools.annotation import draw_text, text_box

# RGB colours
_BACKGROUND = (250, 250, 246)
_WALL = (60, 60, 66)
_OBSTACLE = {"rack": (176, 141, 87), "machine": (120, 146, 178), "pillar": (110, 110, 110),
             "pallet": (196, 170, 120)}
_OBSTACLE_DEFAULT = (150, 150, 150)
_STATION = (30, 130, 60)
_TARGET_POS = (20, 20, 20)
_TARGET_NEG = (235, 235, 235)
_VEHICLE = (230, 140, 20)
_FOV = (120, 200, 255)
_LEFT, _TOP, _AXIS, _PAD = 40, 22, 26, 8  # px: gutters for the axes' labels, padding
_PANEL_W = 260  # px: the key beside the map (key="right")
_ROW = 22  # px per key row


@dataclass(frozen=True)
class Trajectory:
    """A path to draw: (N, 2) or (N, 3) poses in the map frame (m).

    :meth:`TopDownView.render` draws the first trajectory it is given on top (the truth, by
    convention) and each later one beneath it, wider, so a path that follows another shows."""

    points: np.ndarray
    color: tuple[int, int, int]  # RGB
    label: str
    thickness: int = 2  # px


class TopDownView:
    """Draws a map and what moves on it.

    Args:
        world_map: an :class:`agvsim.world.map.Map`.
        pixels_per_metre: scale (px/m).
        margin: blank border around the map's bounds (m).
        max_size: the map area's longer side is capped at this many pixels.
        key: where the key goes: ``"bottom"`` (a band below the map) or ``"right"`` (a panel
            beside it, with room for a camera frame when ``camera_size`` is given).
        camera_size: ``(width, height)`` px of the camera frames :meth:`render` may inset
            (``key="right"`` only): the panel keeps a box for them.

    Attributes:
        map_box: ``(u0, v0, u1, v1)`` pixels of the map area (the map and its margin).
        key_box, inset_box: the key's and the camera frame's pixel boxes in the last render.
    """

    def __init__(self, world_map, pixels_per_metre: float = 20.0, margin: float = 1.0,
                 max_size: int = 1600, key: str = "bottom", camera_size: tuple[int, int] | None = None) -> None:
        if key not in ("bottom", "right"):
            raise ValueError(f"key must be 'bottom' or 'right', got {key!r}")
        if camera_size is not None and key != "right":
            raise ValueError("camera_size needs key='right' (the camera frame goes in the panel)")
        xmin, ymin, xmax, ymax = world_map.bounds
        span = max(xmax - xmin, ymax - ymin) + 2 * margin
        self.scale = min(pixels_per_metre, max_size / span)  # px/m
        w = int(math.ceil((xmax - xmin + 2 * margin) * self.scale))
        h = int(math.ceil((ymax - ymin + 2 * margin) * self.scale))
        self.map_box = (_LEFT, _TOP, _LEFT + w, _TOP + h)
        self.origin = (xmin - margin - _LEFT / self.scale, ymax + margin + _TOP / self.scale)  # map point at pixel (0, 0)
        self.size = (_LEFT + w + _PAD, _TOP + h + _AXIS)  # (W, H) px of the map and its axes, without the key
        self.key_side = key
        self.camera_size = camera_size
        self.key_box = self.inset_box = None
        self.map = world_map
        self._labels: list[tuple[str, tuple[int, int]]] = []
        self._static = self._draw_static()
        tk.draw_axes(self._static, self)

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """Map points (..., 2) in metres to pixel coordinates (..., 2), float."""
        xy = np.asarray(xy, dtype=float)
        u = (xy[..., 0] - self.origin[0]) * self.scale
        v = (self.origin[1] - xy[..., 1]) * self.scale
        return np.stack([u, v], axis=-1)

    def _ipx(self, xy) -> np.ndarray:
        return np.round(self.to_pixels(xy)).astype(np.int32)

    def _draw_static(self) -> np.ndarray:
        w, h = self.size
        img = np.full((h, w, 3), _BACKGROUND, dtype=np.uint8)
        m = self.map
        for zone in m.lighting_zones:
            overlay = img.copy()
            color, alpha = _zone_look(float(zone.level))
            cv2.fillPoly(overlay, [self._ipx(zone.polygon)], color)
            img = cv2.addWeighted(overlay, alpha, img, 1 - alpha, 0)
        for obstacle in m.obstacles:
            color = _OBSTACLE.get(obstacle.kind, _OBSTACLE_DEFAULT)
            pts = self._ipx(obstacle.polygon)
            cv2.fillPoly(img, [pts], color, lineType=cv2.LINE_AA)
            cv2.polylines(img, [pts], True, (80, 80, 80), 1, cv2.LINE_AA)
        for wall in m.walls:
            thick = max(2, int(round(wall.thickness * self.scale)))
            cv2.polylines(img, [self._ipx(wall.points)], False, _WALL, thick, cv2.LINE_AA)
        for target in m.targets:
            half = 0.5 * target.spec.outer_width
            tangent = np.array([-target.normal[1], target.normal[0]])
            a = target.position - tangent * half
            b = target.position + tangent * half
            face = _TARGET_POS if target.polarity == "positive" else _TARGET_NEG
            thick = max(3, int(round(0.12 * self.scale)))
            cv2.line(img, tuple(self._ipx(a)), tuple(self._ipx(b)), (200, 40, 40), thick + 2, cv2.LINE_AA)
            cv2.line(img, tuple(self._ipx(a)), tuple(self._ipx(b)), face, thick, cv2.LINE_AA)
            tip = target.position + target.normal * 0.8
            cv2.arrowedLine(img, tuple(self._ipx(target.position)), tuple(self._ipx(tip)), (200, 40, 40),
                            1, cv2.LINE_AA, tipLength=0.35)
        for station in m.stations:
            x, y, theta = station.pose
            c = tuple(self._ipx((x, y)))
            r = max(3, int(round(0.3 * self.scale)))
            cv2.circle(img, c, r, _STATION, 2, cv2.LINE_AA)
            tip = tuple(self._ipx((x + 0.6 * math.cos(theta), y + 0.6 * math.sin(theta))))
            cv2.line(img, c, tip, _STATION, 2, cv2.LINE_AA)
            self._labels.append((station.id, (c[0] + r + 1, c[1] - r - text_box(station.id, tk.TEXT_PX)[1] + 3)))
        return img

    def _static_entries(self) -> list:
        """Key entries for what the map shows: ``(swatch kind, colour, extra, label)``."""
        m = self.map
        out = [("wall", _WALL, None, "wall")]
        kinds = {o.kind for o in m.obstacles}
        out += [("patch", _OBSTACLE.get(k, _OBSTACLE_DEFAULT), None, k) for k in sorted(kinds)]
        pol = {t.polarity for t in m.targets}
        if "positive" in pol:
            out.append(("target", _TARGET_POS, None, "target, dark bars"))
        if "negative" in pol:
            out.append(("target", _TARGET_NEG, None, "target, light bars"))
        if m.stations:
            out.append(("station", _STATION, None, "station"))
        levels = [float(z.level) for z in m.lighting_zones]
        if any(v < 1.0 for v in levels):
            out.append(("zone", _zone_look(min(levels)), None, "dim light"))
        if any(v >= 1.0 for v in levels):
            out.append(("zone", _zone_look(max(levels)), None, "bright light"))
        return out

    def render(self, trajectories: tuple[Trajectory, ...] = (),
               vehicle_pose: tuple[float, float, float] | None = None,
               vehicle_size: tuple[float, float] = (1.0, 0.7),
               ellipses: tuple[tuple[np.ndarray, np.ndarray, tuple[int, int, int]], ...] = (),
               fov: tuple[tuple[float, float, float], float, float] | None = None,
               legend: bool = True, camera_frame: np.ndarray | None = None,
               ellipse_label: str = "2σ position ellipse") -> np.ndarray:
        """Draw the view.

        Args:
            trajectories: paths to draw; the first on top, each later one beneath it and wider.
            vehicle_pose: true pose (x m, y m, θ rad) to draw the AGV at.
            vehicle_size: chassis (length, width) in metres.
            ellipses: (mean (2,), covariance (2, 2) m², RGB) to draw as 2σ ellipses.
            fov: ((x, y, yaw) of the camera, half field of view rad, range m).
            legend: draw the key (what each colour means, a scale bar) beside the map.
            camera_frame: a grey or RGB camera frame for the panel's box (``camera_size`` views).
            ellipse_label: the ellipses' key entry (say if they are magnified).

        Returns:
            (H, W, 3) uint8 RGB image.
        """
        img = self._static.copy()
        if fov is not None:
            (cx, cy, yaw), half, rng_m = fov
            left = (cx + rng_m * math.cos(yaw + half), cy + rng_m * math.sin(yaw + half))
            right = (cx + rng_m * math.cos(yaw - half), cy + rng_m * math.sin(yaw - half))
            tri = self._ipx(np.array([(cx, cy), left, right]))
            overlay = img.copy()
            cv2.fillPoly(overlay, [tri], _FOV)
            img = cv2.addWeighted(overlay, 0.3, img, 0.7, 0)
        n = len(trajectories)
        for depth in range(n - 1, -1, -1):  # the last beneath, the first on top
            traj = trajectories[depth]
            pts = np.asarray(traj.points, dtype=float)
            if pts.shape[0] >= 2:
                cv2.polylines(img, [self._ipx(pts[:, :2])], False, traj.color, traj.thickness + 2 * depth,
                              cv2.LINE_AA)
        for mean, cov, color in ellipses:
            self._ellipse(img, np.asarray(mean, float), np.asarray(cov, float), color)
        if vehicle_pose is not None:
            self._vehicle(img, vehicle_pose, vehicle_size)
        for text, org in self._labels:  # above the paths, with a halo
            draw_text(img, text, org, tk.TEXT_PX, color=_STATION, halo_color=(255, 255, 255))
        self.key_box = self.inset_box = None
        if not legend:
            return img
        entries = [("line", t.color, t.thickness + 2 * i, t.label) for i, t in enumerate(trajectories)]
        if vehicle_pose is not None:
            entries.append(("vehicle", _VEHICLE, None, "vehicle (true pose)"))
        if ellipses:
            entries.append(("ellipse", ellipses[0][2], None, ellipse_label))
        if fov is not None:
            entries.append(("fov", _FOV, None, "camera view"))
        return self._with_key(img, entries + self._static_entries(), camera_frame)

    def _with_key(self, img: np.ndarray, entries, camera_frame) -> np.ndarray:
        """``img`` with the key panel below or beside it (and the camera frame in it)."""
        h, w = img.shape[:2]
        if self.key_side == "bottom":
            rows = 1 + tk.rows_needed(entries, w - 2 * _PAD)
            panel = np.full((rows * _ROW + 2 * _PAD, w, 3), _BACKGROUND, np.uint8)
            tk.draw_scale_bar(panel, _PAD, _PAD, self.scale, _ROW)
            tk.draw_entries(panel, (_PAD, _PAD + _ROW, w - _PAD, panel.shape[0]), entries, _ROW)
            cv2.line(panel, (0, 0), (w, 0), (200, 200, 200), 1)
            self.key_box = (0, h, w, h + panel.shape[0])
            return np.vstack([img, panel])
        pw = _PANEL_W
        rows = 1 + tk.rows_needed(entries, pw - 2 * _PAD)
        inset_h = 0
        if self.camera_size is not None:
            cw, ch = self.camera_size
            inset_w = pw - 2 * _PAD
            inset_h = int(round(ch * inset_w / cw)) + _ROW
        need = _PAD + rows * _ROW + _PAD + inset_h + _PAD
        H = max(h, need)
        out = np.full((H, w + pw, 3), _BACKGROUND, np.uint8)
        out[:h, :w] = img
        x0 = w
        tk.draw_scale_bar(out, x0 + _PAD, _PAD, self.scale, _ROW)
        y = tk.draw_entries(out, (x0 + _PAD, _PAD + _ROW, x0 + pw - _PAD, H), entries, _ROW)
        cv2.line(out, (x0, 0), (x0, H), (200, 200, 200), 1)
        self.key_box = (x0, 0, x0 + pw, y)
        if self.camera_size is not None:
            y += _PAD
            draw_text(out, "camera frame", (x0 + _PAD, y), tk.TEXT_PX, color=(30, 30, 30), halo_color=None)
            y += _ROW
            box = (x0 + _PAD, y, x0 + _PAD + inset_w, y + inset_h - _ROW)
            self._inset(out, box, camera_frame)
        return out

    @property
    def inset_fraction(self) -> float:
        """Share of the last rendered image the camera frame covers (0 without one)."""
        if self.inset_box is None or self._last_shape is None:
            return 0.0
        x0, y0, x1, y1 = self.inset_box
        return (x1 - x0) * (y1 - y0) / float(self._last_shape[0] * self._last_shape[1])

    def _inset(self, out: np.ndarray, box, frame) -> None:
        x0, y0, x1, y1 = box
        self.inset_box = box
        self._last_shape = out.shape[:2]
        if frame is None:
            out[y0:y1, x0:x1] = 200
            draw_text(out, "no frame yet", (x0 + 6, y0 + 6), tk.TEXT_PX, color=(60, 60, 60), halo_color=None)
        else:
            small = cv2.resize(frame, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
            if small.ndim == 2:
                small = np.repeat(small[..., None], 3, axis=2)
            out[y0:y1, x0:x1] = small[..., :3]
        cv2.rectangle(out, (x0 - 1, y0 - 1), (x1, y1), (20, 20, 20), 1)

    _last_shape = None

    def _vehicle(self, img: np.ndarray, pose, size) -> None:
        x, y, theta = pose
        length, width = size
        c, s = math.cos(theta), math.sin(theta)
        corners = np.array([[length / 2, width / 2], [length / 2, -width / 2],
                            [-length / 2, -width / 2], [-length / 2, width / 2]])
        world = corners @ np.array([[c, s], [-s, c]]) + np.array([x, y])
        pts = self._ipx(world)
        cv2.fillPoly(img, [pts], _VEHICLE, cv2.LINE_AA)
        cv2.polylines(img, [pts], True, (40, 40, 40), 1, cv2.LINE_AA)
        nose = self._ipx((x + 0.5 * length * c, y + 0.5 * length * s))
        cv2.line(img, tuple(self._ipx((x, y))), tuple(nose), (40, 40, 40), 2, cv2.LINE_AA)

    def _ellipse(self, img: np.ndarray, mean: np.ndarray, cov: np.ndarray, color) -> None:
        vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
        vals = np.clip(vals, 0.0, None)
        angle = math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))
        axes = (max(1, int(round(2 * math.sqrt(vals[1]) * self.scale))),
                max(1, int(round(2 * math.sqrt(vals[0]) * self.scale))))
        centre = tuple(self._ipx(mean))
        cv2.ellipse(img, centre, axes, -angle, 0, 360, color, 1, cv2.LINE_AA)

    @staticmethod
    def save_png(image: np.ndarray, path: str | Path) -> Path:
        """Write an RGB image to ``path`` (PNG); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR)):
            raise OSError(f"could not write PNG to {path}")
        return path


def _zone_look(level: float) -> tuple[tuple[int, int, int], float]:
    """(RGB, opacity) of a lighting zone of ``level`` on the map."""
    color = (70, 70, 110) if level < 1.0 else (255, 236, 150)
    return color, min(0.45, 0.25 * abs(math.log(max(level, 1e-3))) + 0.1)
