"""A top-down picture of a plant floor, drawn with OpenCV.

The static layer (lighting zones, obstacles, walls, targets with their
facing, stations) is drawn once per view; each call to :meth:`TopDownView.render`
copies it and adds trajectories, covariance ellipses and the vehicle.
Images are RGB ``uint8`` arrays of shape (H, W, 3), map +y pointing up.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

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


@dataclass(frozen=True)
class Trajectory:
    """A path to draw: (N, 2) or (N, 3) poses in the map frame (m)."""

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
        max_size: the longer image side is capped at this many pixels.
    """

    def __init__(self, world_map, pixels_per_metre: float = 20.0, margin: float = 1.0,
                 max_size: int = 1600) -> None:
        xmin, ymin, xmax, ymax = world_map.bounds
        span = max(xmax - xmin, ymax - ymin) + 2 * margin
        self.scale = min(pixels_per_metre, max_size / span)  # px/m
        self.origin = (xmin - margin, ymax + margin)  # map point at pixel (0, 0)
        self.size = (int(math.ceil((xmax - xmin + 2 * margin) * self.scale)),
                     int(math.ceil((ymax - ymin + 2 * margin) * self.scale)))  # (W, H) px
        self.map = world_map
        self._static = self._draw_static()

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
            level = float(zone.level)
            color = (70, 70, 110) if level < 1.0 else (255, 236, 150)
            cv2.fillPoly(overlay, [self._ipx(zone.polygon)], color)
            alpha = min(0.45, 0.25 * abs(math.log(max(level, 1e-3))) + 0.1)
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
        font_scale = max(0.3, min(0.5, self.scale / 40))
        for station in m.stations:
            x, y, theta = station.pose
            c = tuple(self._ipx((x, y)))
            r = max(3, int(round(0.3 * self.scale)))
            cv2.circle(img, c, r, _STATION, 2, cv2.LINE_AA)
            tip = tuple(self._ipx((x + 0.6 * math.cos(theta), y + 0.6 * math.sin(theta))))
            cv2.line(img, c, tip, _STATION, 2, cv2.LINE_AA)
            cv2.putText(img, station.id, (c[0] + r + 2, c[1] - r), cv2.FONT_HERSHEY_SIMPLEX, font_scale,
                        _STATION, 1, cv2.LINE_AA)
        return img

    def render(self, trajectories: tuple[Trajectory, ...] = (),
               vehicle_pose: tuple[float, float, float] | None = None,
               vehicle_size: tuple[float, float] = (1.0, 0.7),
               ellipses: tuple[tuple[np.ndarray, np.ndarray, tuple[int, int, int]], ...] = (),
               fov: tuple[tuple[float, float, float], float, float] | None = None,
               legend: bool = True) -> np.ndarray:
        """Draw the view.

        Args:
            trajectories: paths to draw, in order.
            vehicle_pose: true pose (x m, y m, θ rad) to draw the AGV at.
            vehicle_size: chassis (length, width) in metres.
            ellipses: (mean (2,), covariance (2, 2) m², RGB) to draw as 2σ ellipses.
            fov: ((x, y, yaw) of the camera, half field of view rad, range m).
            legend: label the trajectories.

        Returns:
            (H, W, 3) uint8 RGB image.
        """
        img = self._static.copy()
        for traj in trajectories:
            pts = np.asarray(traj.points, dtype=float)
            if pts.shape[0] >= 2:
                cv2.polylines(img, [self._ipx(pts[:, :2])], False, traj.color, traj.thickness, cv2.LINE_AA)
        for mean, cov, color in ellipses:
            self._ellipse(img, np.asarray(mean, float), np.asarray(cov, float), color)
        if fov is not None:
            (cx, cy, yaw), half, rng_m = fov
            left = (cx + rng_m * math.cos(yaw + half), cy + rng_m * math.sin(yaw + half))
            right = (cx + rng_m * math.cos(yaw - half), cy + rng_m * math.sin(yaw - half))
            tri = self._ipx(np.array([(cx, cy), left, right]))
            overlay = img.copy()
            cv2.fillPoly(overlay, [tri], (120, 200, 255))
            img = cv2.addWeighted(overlay, 0.3, img, 0.7, 0)
        if vehicle_pose is not None:
            self._vehicle(img, vehicle_pose, vehicle_size)
        if legend and trajectories:
            width = 48 + 8 * max(len(t.label) for t in trajectories)
            panel = img[4:10 + 18 * len(trajectories), 4:4 + width]
            panel[:] = (0.25 * panel + 0.75 * 255).astype(np.uint8)
            y0 = 18
            for traj in trajectories:
                cv2.line(img, (10, y0 - 4), (34, y0 - 4), traj.color, 3, cv2.LINE_AA)
                cv2.putText(img, traj.label, (40, y0), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (30, 30, 30), 1, cv2.LINE_AA)
                y0 += 18
        return img

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
