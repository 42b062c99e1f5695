"""Pure-pursuit path following along a route of stations.

The path is the polyline through the route's station positions (a closed
loop when ``loop`` is set). The follower steers towards a look-ahead point
on the path and limits its speed by the path curvature and the distance to
the next stop. It is given a *pose* each step: the estimate (the closed loop)
or the true pose (``steer_on="truth"``, dead-reckoning runs). It never reads
ground truth itself.

Pure pursuit (Coulter 1992): with the look-ahead point at angle η from the
heading and distance L, the arc through it has curvature κ = 2 sin(η) / L;
the command is (v, ω = v κ).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.numeric import check_number


@dataclass(frozen=True)
class FollowerParams:
    """Tuning of the path follower."""

    cruise_speed: float = 1.2  # m/s
    lookahead: float = 1.2  # m, look-ahead distance at cruise speed
    min_lookahead: float = 0.6  # m
    max_lateral_accel: float = 0.6  # m/s^2, limits speed in curves
    max_yaw_rate: float = 1.2  # rad/s
    stop_decel: float = 0.5  # m/s^2, braking towards a stop
    arrival_radius: float = 0.25  # m, a station counts as reached within this
    min_speed: float = 0.15  # m/s, crawl speed near a stop

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            check_number(f"FollowerParams.{name}", value, low=0.0, low_open=True)


class RoutePath:
    """A polyline through station positions with arc-length bookkeeping.

    Args:
        points: (N, 2) station positions (m), N >= 2.
        names: station ids, one per point.
        loop: whether the path returns from the last point to the first.
    """

    def __init__(self, points: np.ndarray, names: list[str], loop: bool) -> None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2:
            raise ValueError(f"route points must have shape (N>=2, 2), got {pts.shape}")
        if loop and np.linalg.norm(pts[0] - pts[-1]) > 1e-9:
            pts = np.vstack([pts, pts[:1]])
            names = [*names, names[0]]
        self.points = pts
        self.names = list(names)
        self.loop = loop
        seg = np.diff(pts, axis=0)
        self.seg_len = np.linalg.norm(seg, axis=1)
        if np.any(self.seg_len < 1e-6):
            raise ValueError("route has two consecutive stations at the same position")
        self.seg_dir = seg / self.seg_len[:, None]
        self.cum = np.concatenate([[0.0], np.cumsum(self.seg_len)])
        self.length = float(self.cum[-1])  # m, one pass

    @classmethod
    def from_route(cls, world_map, route: str = "default") -> "RoutePath":
        stations = world_map.route(route)
        pts = np.array([s.pose[:2] for s in stations], dtype=float)
        names = [s.id for s in stations]
        loop = len(stations) > 2 and names[0] == names[-1]
        if loop:
            pts, names = pts[:-1], names[:-1]
        return cls(pts, names, loop=loop)

    def point_at(self, s: float) -> np.ndarray:
        """Point at arc length ``s`` (m), wrapped for loops, clamped otherwise."""
        if self.loop:
            s = s % self.length
        else:
            s = min(max(s, 0.0), self.length)
        i = int(np.searchsorted(self.cum, s, side="right") - 1)
        i = min(max(i, 0), len(self.seg_len) - 1)
        return self.points[i] + self.seg_dir[i] * (s - self.cum[i])

    def project(self, xy: np.ndarray, s_hint: float, window: float = 5.0) -> float:
        """Arc length of the path point nearest ``xy`` within ``window`` m
        ahead of or behind ``s_hint`` (progress never jumps across the map)."""
        best_s, best_d = s_hint, math.inf
        base = math.floor(s_hint / self.length) * self.length if self.loop else 0.0
        local = s_hint - base
        for offset in ((-self.length, 0.0, self.length) if self.loop else (0.0,)):
            for i in range(len(self.seg_len)):
                s0 = self.cum[i] + offset
                if s0 > local + window or s0 + self.seg_len[i] < local - window:
                    continue
                rel = xy - self.points[i]
                t = float(np.clip(rel @ self.seg_dir[i], 0.0, self.seg_len[i]))
                lo = max(0.0, local - window - s0)
                hi = min(self.seg_len[i], local + window - s0)
                if lo > hi:
                    continue
                t = min(max(t, lo), hi)
                d = float(np.linalg.norm(rel - self.seg_dir[i] * t))
                if d < best_d:
                    best_d, best_s = d, base + s0 + t
        return best_s


class PurePursuit:
    """Drives a :class:`RoutePath`, station by station.

    Args:
        path: the route.
        params: tuning.
        laps: passes of a loop route before the final stop (ignored for open
            routes); ``math.inf`` never stops.
    """

    def __init__(self, path: RoutePath, params: FollowerParams = FollowerParams(),
                 laps: float = 1.0, max_speed: float = 1.5, max_yaw_rate: float = 1.5) -> None:
        self.path = path
        self.params = params
        self.end_s = path.length * (laps if path.loop else 1.0)
        self.progress = 0.0  # m, arc length of the nearest path point
        self._cruise = min(params.cruise_speed, max_speed)
        self._max_w = min(params.max_yaw_rate, max_yaw_rate)
        self.next_station = 1  # index into path.names of the station ahead
        # (station id, distance to it when passed, m), appended as passed; the caller may clear it
        self.arrivals: list[tuple[str, float]] = []

    @property
    def finished(self) -> bool:
        return self.progress >= self.end_s - self.params.arrival_radius

    def _update_arrivals(self, xy: np.ndarray) -> None:
        n_pts = len(self.path.points)
        while True:
            lap, idx = divmod(self.next_station, n_pts - 1) if self.path.loop else (0, self.next_station)
            if not self.path.loop and idx >= n_pts:
                return
            s_station = lap * self.path.length + self.path.cum[idx]
            if s_station > self.end_s + 1e-9 or self.progress < s_station - self.params.arrival_radius:
                return
            station_xy = self.path.points[idx]
            self.arrivals.append((self.path.names[idx], float(np.linalg.norm(xy - station_xy))))
            self.next_station += 1

    def command(self, pose: tuple[float, float, float]) -> tuple[float, float]:
        """(v m/s, ω rad/s) for the vehicle believed to be at ``pose``."""
        x, y, theta = pose
        xy = np.array([x, y])
        self.progress = self.path.project(xy, self.progress)
        self._update_arrivals(xy)
        p = self.params
        remaining = self.end_s - self.progress
        if remaining <= p.arrival_radius:
            return 0.0, 0.0
        lookahead = max(p.min_lookahead, p.lookahead)
        s_target = min(self.progress + lookahead, self.end_s)
        target = self.path.point_at(s_target)
        dx, dy = target[0] - x, target[1] - y
        dist = math.hypot(dx, dy)
        eta = math.atan2(dy, dx) - theta
        # the lookahead point's bearing from the heading, in (-π, π], from its direction cosines;
        # not localizer.numeric.wrap_angle: the follower's paths (and the pinned figures) depend on
        # this expression to the last bit
        eta = math.atan2(math.sin(eta), math.cos(eta))
        kappa = 2.0 * math.sin(eta) / max(dist, 1e-6)
        v = self._cruise
        # look ahead for a sharp corner: slow down so the turn stays gentle
        corner = self._corner_curvature(self.progress, 2.5)
        v = min(v, math.sqrt(p.max_lateral_accel / max(abs(kappa), corner, 1e-6)))
        v = min(v, math.sqrt(2.0 * p.stop_decel * max(remaining - p.arrival_radius * 0.5, 0.0)) + p.min_speed)
        if abs(eta) > math.pi / 2:  # facing away: turn on the spot
            return 0.0, math.copysign(self._max_w, eta)
        v = max(v * math.cos(eta), p.min_speed)
        omega = v * kappa
        if abs(omega) > self._max_w:
            v *= self._max_w / abs(omega)
            omega = math.copysign(self._max_w, omega)
        return v, omega

    def _corner_curvature(self, s: float, horizon: float) -> float:
        """Rough curvature (1/m) of the sharpest vertex within ``horizon`` m."""
        a = self.path.point_at(s)
        b = self.path.point_at(s + 0.5 * horizon)
        c = self.path.point_at(s + horizon)
        ab, bc = b - a, c - b
        n1, n2 = np.linalg.norm(ab), np.linalg.norm(bc)
        if n1 < 1e-6 or n2 < 1e-6:
            return 0.0
        cosang = float(np.clip(ab @ bc / (n1 * n2), -1.0, 1.0))
        return math.acos(cosang) / (0.5 * horizon)
