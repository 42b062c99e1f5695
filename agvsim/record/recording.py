"""A run as a Rerun recording: the floor, the paths, the covariance, the camera and the filter
on one ``sim_time`` timeline (seconds), to look at in the Rerun viewer (``rerun run.rrd``).

:class:`RecordingWriter` writes one recording (one ``recording_id``) to one ``.rrd`` file;
:class:`agvsim.record.process.RunRecording` runs one in a process of its own (a run waits for none of
it but the end). The
entity paths are :data:`ENTITY_PATHS` (stable: scripts and blueprints may rely on them):

========================== =============================================================
``world/map/walls``        static line strips of the walls' centrelines (m)
``world/map/targets``      static points at the targets' face centres, labelled with id and
                           polarity; ``world/map/targets/facing``: arrows along their normals
``world/map/stations``     static points at the stations, labelled with their ids
``world/truth``            the true pose: an arrow (x, y, heading), every recorded step
``world/dead_reckoning``   the odometry's pose, likewise
``world/estimate``         the filter's estimate, likewise
``world/<pose>/trail/<k>``  the path, one piece every :data:`TRAIL_PERIOD` seconds (points
                           :data:`TRAIL_SPACING` apart): at any time the pieces logged so far
``world/estimate/covariance`` the 2σ ellipse of the estimate's position
``camera/image``           the camera frame, JPEG-compressed
``camera/detections``      each target found: its outline in the frame (px) and a label with
                           d (m), β and α (degrees) and their σ
``filter/status``          the filter's status (tracking, relocalizing, lost) as a text log
``metrics/position_error`` the estimate's position error (m; with the truth only)
``metrics/position_sigma`` the estimate's largest position σ (m)
``metrics/nis``            each fused observation's NIS
``metrics/innovation``     each fused frame's accepted observations' count
========================== =============================================================

Poses are logged in the floor's frame (x east, y north, metres; heading CCW from +x). The
2-D view's y axis points up when opened with :func:`blueprint` (sent with every recording).
"""
from __future__ import annotations

import math
import os
from typing import Iterable, NamedTuple, Sequence

import numpy as np

__all__ = ["ENTITY_PATHS", "MapLayers", "TIMELINE", "TRAIL_PERIOD", "TRAIL_SPACING", "RecordingWriter", "detection_label", "detection_outline",
           "ellipse_points", "map_layers"]

#: the timeline every entity is logged on (seconds of simulated or logged time)
TIMELINE = "sim_time"
#: s, the time each piece of a trail (``world/<pose>/trail/<k>``) covers
TRAIL_PERIOD = 5.0
#: m, the spacing of a trail's points
TRAIL_SPACING = 0.05
#: the entity paths of a recording, and what each holds (module docstring)
ENTITY_PATHS: dict[str, str] = {
    "world/map/walls": "walls' centrelines (static)",
    "world/map/targets": "targets' face centres, labelled id and polarity (static)",
    "world/map/stations": "stations (static)",
    "world/truth": "true pose (arrow)",
    "world/dead_reckoning": "dead-reckoned pose (arrow)",
    "world/estimate": "filter's estimate (arrow)",
    "world/<pose>/trail/<k>": "each pose's path, piece by piece",
    "world/estimate/covariance": "2-sigma ellipse of the estimate's position",
    "camera/image": "camera frame (JPEG)",
    "camera/detections": "targets found: outline and d, beta, alpha, sigma",
    "filter/status": "filter status (text log)",
    "metrics/position_error": "estimate's position error (m)",
    "metrics/position_sigma": "estimate's largest position sigma (m)",
    "metrics/nis": "NIS of each fused observation",
    "metrics/innovation": "observations accepted per fused frame",
}
#: the pose entities, with their colours (RGB)
POSES = {"truth": (40, 40, 40), "dead_reckoning": (214, 39, 40), "estimate": (31, 119, 180)}
#: m, the length of a pose's arrow
ARROW = 0.4
#: JPEG quality of ``camera/image``
JPEG_QUALITY = 85
#: RGB of the detections' outlines
DETECTION_COLOR = (255, 200, 0)
#: s, the shortest time between two logs of the estimate's ellipse
ELLIPSE_PERIOD = 0.25
#: steps gathered before the per-step values are sent as columns
BATCH = 1024
#: camera frames gathered before they are sent as columns (bounds the JPEGs held: a few MB)
FRAME_BATCH = 64


def _empty_rows() -> dict[str, list]:
    """The per-step values gathered since the last send: each key a column (``t``: s)."""
    return {"t": [], "sigma": [], "error": [], **{name: [] for name in POSES},
            "ellipse_t": [], "ellipse": [], "image_t": [], "image": [], "lines_t": [], "lines": [], "labels": [],
            "text_t": [], "text": [], "fused_t": [], "nis": [], "accepted": []}


class MapLayers(NamedTuple):
    """What a recording shows of a map (:func:`map_layers`; plain arrays, so that it crosses to
    the recording's process).

    Attributes:
        walls: each wall's centreline, ``(k, 2)`` (m).
        target_xy, target_normal: ``(T, 2)`` face centres (m) and unit normals.
        target_labels: ``"<id> (<polarity>)"`` per target; target_positive: (T,) bool.
        station_xy: ``(S, 2)`` (m); station_ids: their ids.
    """

    walls: tuple
    target_xy: np.ndarray
    target_normal: np.ndarray
    target_labels: tuple
    target_positive: tuple
    station_xy: np.ndarray
    station_ids: tuple


def map_layers(world_map) -> MapLayers:
    """The :class:`MapLayers` of an :class:`agvsim.world.map.Map`."""
    ts, ss = world_map.targets, world_map.stations
    return MapLayers(tuple(np.asarray(w.points, dtype=float) for w in world_map.walls),
                     np.array([t.position for t in ts], dtype=float).reshape(-1, 2),
                     np.array([t.normal for t in ts], dtype=float).reshape(-1, 2),
                     tuple(f"{t.id} ({t.polarity})" for t in ts), tuple(t.polarity == "positive" for t in ts),
                     np.array([s.pose[:2] for s in ss], dtype=float).reshape(-1, 2), tuple(s.id for s in ss))


def ellipse_points(mean_xy, cov_xy, k: float = 2.0, n: int = 48) -> np.ndarray:
    """``(n + 1, 2)`` closed outline of the ``k``-σ ellipse of a 2-D Gaussian (m)."""
    vals, vecs = np.linalg.eigh(np.asarray(cov_xy, dtype=float))
    radii = k * np.sqrt(np.clip(vals, 0.0, None))
    t = np.linspace(0.0, 2.0 * math.pi, n + 1)
    circle = np.stack([np.cos(t), np.sin(t)], axis=1) * radii
    return np.asarray(mean_xy, dtype=float)[:2] + circle @ vecs.T


def detection_outline(measurements) -> np.ndarray:
    """``(5, 2)`` closed outline (px) of a target found in a frame, from its
    :class:`localizer.model.observation.ImageMeasurements`: the outer bar edges from the bar tops to
    the bar bottoms."""
    m = measurements
    x0, x1 = m.outer_edges
    return np.array([[x0, m.top_y[0]], [x1, m.top_y[1]], [x1, m.bottom_y[1]], [x0, m.bottom_y[0]],
                     [x0, m.top_y[0]]], dtype=float)


def detection_label(obs) -> str:
    """``"d 3.214±0.004 m  β 4.1±0.1°  α -12.0±0.6°"`` of an observation (its covariance's σ)."""
    sd = np.sqrt(np.clip(np.diag(np.asarray(obs.covariance, dtype=float)), 0.0, None))
    return (f"d {obs.distance:.3f}±{sd[0]:.3f} m  β {math.degrees(obs.beta):.1f}±{math.degrees(sd[1]):.1f}°  "
            f"α {math.degrees(obs.alpha):.1f}±{math.degrees(sd[2]):.1f}°")


def blueprint():
    """The viewer's layout: the floor (2-D, y up) beside the camera, the metrics below."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(rrb.Vertical(
        rrb.Horizontal(rrb.Spatial2DView(origin="world", name="floor"),
                       rrb.Spatial2DView(origin="camera", name="camera")),
        rrb.Horizontal(rrb.TimeSeriesView(origin="metrics", name="metrics"),
                       rrb.TextLogView(origin="filter", name="filter")),
        row_shares=[3, 1]))


class RecordingWriter:
    """One run's recording, written to ``path`` as it is made, in the calling thread
    (:class:`agvsim.record.process.RunRecording` calls it in a process of its own).

    Args:
        path: the ``.rrd`` file (written; its folder is made).
        recording_id: the recording's id (e.g. ``"seed-3"``); the application id is ``"agvsim"``.
        world_map: the map (or its :class:`MapLayers`) whose walls, targets and stations are
            logged static (None: no map).
        every: log every ``every``-th camera frame (1: all of them); the poses and metrics of
            every step whatever it is.

    Call :meth:`close` at the end.
    """

    def __init__(self, path: str | os.PathLike, recording_id: str, world_map=None, every: int = 1) -> None:
        import rerun as rr

        self.every = int(every)
        self._rr = rr
        self.path = os.fspath(path)
        os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
        self.stream = rr.RecordingStream("agvsim", recording_id=recording_id)
        self.stream.save(self.path, default_blueprint=blueprint())
        self._frames = 0
        self._rows = _empty_rows()
        self._ellipse_due = 0.0
        self._trail_due = TRAIL_PERIOD
        self._pieces = 0
        self._trails: dict[str, list] = {name: [] for name in POSES}
        if world_map is not None:
            self.map(world_map if isinstance(world_map, MapLayers) else map_layers(world_map))

    # -- static -------------------------------------------------------------------------------
    def map(self, layers: "MapLayers") -> None:
        """The map's walls, targets (and their facing) and stations (:func:`map_layers`), static."""
        rr, log = self._rr, self.stream.log
        log("world/map/walls", rr.LineStrips2D(list(layers.walls), colors=(120, 120, 120)), static=True)
        if len(layers.target_xy):
            log("world/map/targets", rr.Points2D(layers.target_xy, labels=list(layers.target_labels),
                                                 colors=[(0, 0, 0) if positive else (200, 120, 0)
                                                         for positive in layers.target_positive], radii=0.08),
                static=True)
            log("world/map/targets/facing", rr.Arrows2D(origins=layers.target_xy, vectors=0.5 * layers.target_normal),
                static=True)
        if len(layers.station_xy):
            log("world/map/stations", rr.Points2D(layers.station_xy, labels=list(layers.station_ids), radii=0.06,
                                                  colors=(44, 160, 44)), static=True)

    # -- per step -----------------------------------------------------------------------------
    def poses(self, t: float, poses: dict[str, Sequence[float]], covariance=None, status: str | None = None) -> None:
        """The poses (``{"truth"|"dead_reckoning"|"estimate": (x m, y m, θ rad)}``, any of them) at
        ``t`` (s), the estimate's position error and σ from ``covariance`` ((3, 3), m², m·rad,
        rad²), its 2σ ellipse (at most every :data:`ELLIPSE_PERIOD` s), and ``status`` when it
        changed. The per-step values are gathered and sent as columns, :data:`BATCH` steps at a
        time (a log call per value would cost more than the run)."""
        t = float(t)
        rows = self._rows
        rows["t"].append(t)
        for name in POSES:
            pose = poses.get(name)
            rows[name].append((math.nan,) * 3 if pose is None else tuple(float(v) for v in pose))
            if pose is not None:
                trail = self._trails[name]
                x, y = float(pose[0]), float(pose[1])
                if not trail or math.hypot(x - trail[-1][0], y - trail[-1][1]) >= TRAIL_SPACING:
                    trail.append((x, y))
        estimate = poses.get("estimate")
        sigma = err = math.nan
        if estimate is not None and covariance is not None:
            cov = np.asarray(covariance, dtype=float)[:2, :2]
            sigma = math.sqrt(max(0.5 * (cov[0, 0] + cov[1, 1]) + math.hypot(0.5 * (cov[0, 0] - cov[1, 1]), cov[0, 1]),
                                  0.0))
            if t >= self._ellipse_due:
                self._ellipse_due = t + ELLIPSE_PERIOD
                rows["ellipse_t"].append(t)
                rows["ellipse"].append(ellipse_points(estimate, cov))
            if "truth" in poses:
                err = math.hypot(estimate[0] - poses["truth"][0], estimate[1] - poses["truth"][1])
        rows["sigma"].append(sigma)
        rows["error"].append(err)
        if status is not None:
            self.stream.set_time(TIMELINE, duration=t)
            self.stream.log("filter/status", self._rr.TextLog(status, level="WARN" if status != "tracking" else "INFO"))
        if len(rows["t"]) >= BATCH:
            self._send_rows()
        if t >= self._trail_due:
            self._trail_due = t + TRAIL_PERIOD
            self._trail_pieces()

    def _trail_pieces(self) -> None:
        """Each trail's points since the last piece, as the next piece (its last point kept as the
        next piece's first, so that the pieces join)."""
        rr = self._rr
        for name, trail in self._trails.items():
            if len(trail) > 1:
                self.stream.log(f"world/{name}/trail/{self._pieces:05d}", rr.LineStrips2D(
                    [np.asarray(trail, dtype=float)], colors=POSES[name], radii=0.02))
                del trail[:-1]
        self._pieces += 1

    def _send_rows(self) -> None:
        """The gathered per-step values, as one column per entity (a log call per value would cost
        more than the run)."""
        rr, rows, send = self._rr, self._rows, self.stream.send_columns

        def time(key):
            return [rr.TimeColumn(TIMELINE, duration=np.asarray(rows[key], dtype=float))]

        t = np.asarray(rows["t"], dtype=float)
        for name in POSES:
            pose = np.asarray(rows[name], dtype=float).reshape(-1, 3)
            keep = np.isfinite(pose[:, 0])
            if keep.any():
                p = pose[keep]
                send(f"world/{name}", [rr.TimeColumn(TIMELINE, duration=t[keep])], rr.Arrows2D.columns(
                    origins=p[:, :2], vectors=ARROW * np.stack([np.cos(p[:, 2]), np.sin(p[:, 2])], axis=1)))
        for key, path in (("sigma", "metrics/position_sigma"), ("error", "metrics/position_error")):
            values = np.asarray(rows[key], dtype=float)
            keep = np.isfinite(values)
            if keep.any():
                send(path, [rr.TimeColumn(TIMELINE, duration=t[keep])], rr.Scalars.columns(scalars=values[keep]))
        if rows["ellipse_t"]:
            send("world/estimate/covariance", time("ellipse_t"), rr.LineStrips2D.columns(
                strips=rows["ellipse"], colors=[POSES["estimate"]] * len(rows["ellipse"])))
        if rows["image_t"]:
            send("camera/image", time("image_t"), rr.EncodedImage.columns(
                blob=rows["image"], media_type=["image/jpeg"] * len(rows["image"])))
        if rows["lines_t"]:
            strips = [s for frame in rows["lines"] for s in frame]
            labels = [s for frame in rows["labels"] for s in frame]
            send("camera/detections", time("lines_t"), rr.LineStrips2D.columns(
                strips=strips, labels=labels, colors=[DETECTION_COLOR] * len(strips)).partition(
                [len(frame) for frame in rows["lines"]]))
        if rows["text_t"]:
            send("camera/detections", time("text_t"), rr.TextLog.columns(text=rows["text"]))
        if rows["fused_t"]:
            send("metrics/nis", time("fused_t"), rr.Scalars.columns(
                scalars=[v for values in rows["nis"] for v in values]).partition([len(v) for v in rows["nis"]]))
            send("metrics/innovation", time("fused_t"), rr.Scalars.columns(
                scalars=np.asarray(rows["accepted"], dtype=float)))
        self._rows = _empty_rows()

    def frame(self, t: float, image: np.ndarray | None, detections: Iterable = ()) -> None:
        """A camera frame captured at ``t`` (s): ``image`` ((H, W) or (H, W, 3) uint8; None: the
        detections only) and what was found in it (:class:`localizer.TargetObservation`, whose
        ``measurements`` give the outline; observations without it get the label only). Sent
        :data:`FRAME_BATCH` frames at a time."""
        self._frames += 1
        if (self._frames - 1) % self.every:
            return
        rows, t = self._rows, float(t)
        if image is not None:
            import cv2

            ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if ok:
                rows["image_t"].append(t)
                rows["image"].append(jpeg.tobytes())
        detections = list(detections)
        outlines = [detection_outline(d.measurements) for d in detections if getattr(d, "measurements", None)]
        labels = [detection_label(d) for d in detections]
        if len(outlines) == len(detections):
            rows["lines_t"].append(t)
            rows["lines"].append(outlines)
            rows["labels"].append(labels)
        else:
            rows["text_t"].append(t)
            rows["text"].append("; ".join(labels) or "no target")
        if len(rows["image_t"]) >= FRAME_BATCH:
            self._send_rows()

    def fused(self, t: float, nis: Sequence[float], accepted: int) -> None:
        """A frame captured at ``t`` (s) fused: its observations' NIS and how many were accepted."""
        rows = self._rows
        rows["fused_t"].append(float(t))
        rows["nis"].append([float(v) for v in nis])
        rows["accepted"].append(int(accepted))

    def close(self) -> None:
        """Write the last trails and flush the file."""
        self._send_rows()
        self._trail_pieces()
        self.stream.flush()
        self.stream.disconnect()
