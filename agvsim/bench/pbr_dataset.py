"""The physically based frame set on disk: made once by ``agvsim bench pbr --generate`` (Mitsuba 3,
:mod:`agvsim.bench.pbr_render`, then :mod:`agvsim.bench.pbr_sensor`), versioned with the project,
read by ``agvsim bench pbr``.

A set is a folder: ``dataset.json`` (its version and how it was made) and, per frame, the
stored frame (``<size>/<index>.jpg`` or ``.png``, exactly the bytes a camera would have written)
beside ``<index>.json`` (the scene, the camera settings, the truth and the frame's attributes).
A frame's JSON is written after its image (both whole files, by renaming): a frame is done
when its JSON exists, so an interrupted run resumes where it stopped, redoing nothing.

The split: a third of the frames (:func:`split_of`) are for tuning the localizer; the rest are
held out, and the benchmark reports on them unless told otherwise.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agvsim.bench.envelope_frames import bar_rows
from agvsim.bench.pbr_scene import PbrScene, camera_for, sample_scene
from agvsim.bench.pbr_sensor import SensorSettings, expose, sample_settings
from localizer.model.target import TargetSpec

#: the set's layout version (a change to the scenes, the sensor or the plan is a new version)
VERSION = 1
#: the shipped set, beside the tests that read it
DEFAULT_DIR = Path(__file__).resolve().parents[2] / "tests" / "data" / "pbr"
#: samples per pixel of every light pass
SPP = 16
#: the splits, in report order
SPLITS = ("held-out", "tune")
#: in-spec at 512 x 480 (scaled with the resolution): the narrower bar at least this wide (px)
#: and the shorter this tall (rows), the blur's sd at most this (px), the noise's sd at most
#: this (grey levels), the bars' contrast against the gap at least this (grey levels: a target
#: lost in the dark of a frame exposed for a lamp's hot spot is not clearly visible)
SPEC_BAR_PX, SPEC_BAR_ROWS, SPEC_BLUR_SD, SPEC_NOISE, SPEC_CONTRAST = 5.0, 16.0, 3.0, 8.0, 20.0


@dataclass(frozen=True)
class Batch:
    """Frames of one kind in the plan."""

    width: int  # px
    height: int  # px
    focal_mm: float  # the thesis lens whose field of view the camera has
    has_target: bool
    count: int


#: what the set holds, in index order
PLAN: tuple[Batch, ...] = (
    Batch(512, 480, 16.0, True, 72),
    Batch(512, 480, 50.0, True, 48),
    Batch(512, 480, 16.0, False, 16),
    Batch(1280, 1200, 16.0, True, 12),
)


def plan() -> list[tuple[int, Batch]]:
    """``(index, batch)`` of every frame of the set."""
    out, index = [], 0
    for batch in PLAN:
        for _ in range(batch.count):
            out.append((index, batch))
            index += 1
    return out


def split_of(index: int) -> str:
    """The frame's split: every third frame is for tuning, the rest held out."""
    return "tune" if index % 3 == 0 else "held-out"


def frame_paths(folder: Path, index: int, batch: Batch, lossless: bool) -> tuple[Path, Path]:
    """``(image, record)`` paths of frame ``index``."""
    d = Path(folder) / f"{batch.width}x{batch.height}"
    return d / f"{index:04d}.{'png' if lossless else 'jpg'}", d / f"{index:04d}.json"


def contrast(frame: np.ndarray, scene: PbrScene, target: TargetSpec = TargetSpec()) -> float:
    """The bars' contrast in ``frame`` (grey levels): the median of the gap's middle less the mean
    of the bars' middles' medians, absolute (windows of half a bar's width and height)."""
    camera = camera_for(scene.width, scene.height, scene.focal_mm)
    pose, b, h = scene.pose, target.bar_width, target.bar_height
    values = []
    for u in (-b, 0.0, b):
        corners = camera.project(pose.points(np.array([u - b / 4, u + b / 4]), np.array([-h / 4, h / 4])))
        (x0, y0), (x1, y1) = np.floor(corners.min(axis=0)).astype(int), np.ceil(corners.max(axis=0)).astype(int)
        window = frame[max(y0, 0):max(y1, y0 + 1) + 1, max(x0, 0):max(x1, x0 + 1) + 1]
        values.append(float(np.median(window)) if window.size else float("nan"))
    return abs(values[1] - 0.5 * (values[0] + values[2]))


def attributes(scene: PbrScene, noise: float, frame: np.ndarray, target: TargetSpec = TargetSpec()) -> dict:
    """What a frame shows, for the report's conditions: the narrower bar's width (px) and the
    shorter's height (rows), the defocus disc's diameter and sd (px), the noise (grey levels), the
    bars' contrast (:func:`contrast`), the angle, whether the dark band crosses the target's face,
    and whether all are in spec."""
    camera = camera_for(scene.width, scene.height, scene.focal_mm)
    scale = camera.width / 512.0
    out = {"noise_grey": noise, "alpha_deg": math.degrees(scene.alpha), "lens_mm": scene.focal_mm,
           "size": f"{scene.width}x{scene.height}"}
    aperture = scene.focal_mm / 1000.0 / scene.f_number  # m, the aperture's diameter
    disc = aperture * camera.fx * abs(scene.distance - scene.focus) / (scene.distance * scene.focus)
    out.update(blur_disc_px=disc, blur_sd_px=disc / 4.0)
    if not scene.has_target:
        out["in_spec"] = False
        return out
    pose = scene.pose
    b = target.bar_width
    xs = camera.project(pose.points(np.array([-1.5, -0.5, 0.5, 1.5]) * b, np.zeros(4)))[:, 0]
    rows = bar_rows(pose, camera, target)
    half = 0.5 * target.outer_height
    band = scene.band[0] < half and scene.band[1] > -half
    out.update(bar_px=float(min(xs[1] - xs[0], xs[3] - xs[2])), bar_rows=float(rows), dark_band_on_face=bool(band),
               contrast_grey=contrast(frame, scene, target))
    out["in_spec"] = bool(out["bar_px"] >= SPEC_BAR_PX * scale and rows >= SPEC_BAR_ROWS * scale
                          and out["blur_sd_px"] <= SPEC_BLUR_SD * scale and noise <= SPEC_NOISE
                          and out["contrast_grey"] >= SPEC_CONTRAST)
    return out


def _write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    part = path.with_name(path.name + ".part")
    part.write_bytes(data)
    os.replace(part, path)


def frame_rng(seed: int, index: int, stage: str) -> np.random.Generator:
    """The generator of frame ``index``'s ``stage`` (``"scene"``, ``"sensor"``, ``"noise"``)."""
    return np.random.default_rng([int(seed), int(index), ("scene", "sensor", "noise").index(stage)])


def make_frame(folder: Path, index: int, batch: Batch, seed: int) -> dict:
    """Render, expose and store frame ``index``; returns its record (also written as its JSON)."""
    from agvsim.bench.pbr_render import render_radiance

    scene = sample_scene(frame_rng(seed, index, "scene"), batch.width, batch.height, batch.focal_mm, batch.has_target)
    settings: SensorSettings = sample_settings(frame_rng(seed, index, "sensor"))
    radiance = render_radiance(scene, SPP, seed * 100003 + index)
    frame, stored = expose(radiance, settings, frame_rng(seed, index, "noise"))
    clean, _ = expose(radiance, settings, None)
    noise = float(np.std(frame.astype(np.float64) - clean))
    image_path, record_path = frame_paths(folder, index, batch, settings.jpeg_quality == 0)
    record = {"index": index, "split": split_of(index), "image": image_path.name, "scene": scene.to_dict(),
              "sensor": settings.to_dict(), "attributes": attributes(scene, noise, frame)}
    _write(image_path, stored)
    _write(record_path, (json.dumps(record, indent=1) + "\n").encode())
    return record


def read_set(folder: Path) -> list[dict]:
    """Every finished frame's record (index order), each with ``path`` (its image) added; a
    ``ValueError`` naming the folder when it holds no set or a record is unreadable."""
    folder = Path(folder)
    meta = folder / "dataset.json"
    if not meta.is_file():
        raise ValueError(f"--dataset {str(folder)!r}: no dataset.json (make one with agvsim bench pbr --generate)")
    records = []
    for path in sorted(folder.glob("*/[0-9][0-9][0-9][0-9].json")):
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
            record["path"] = str(path.with_name(record["image"]))
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{path}: not a frame record of the set ({exc})") from None
        records.append(record)
    return sorted(records, key=lambda r: r["index"])


def generate(folder: Path, seed: int = 0, progress=None) -> int:
    """Make every frame of :data:`PLAN` that ``folder`` does not hold yet; returns how many were made.
    ``progress``: a tqdm-like callable wrapping the list of frames to make."""
    folder = Path(folder)
    meta = {"version": VERSION, "seed": int(seed), "spp": SPP,
            "plan": [b.__dict__ for b in PLAN], "renderer": _renderer()}
    old = folder / "dataset.json"
    if old.is_file():
        have = json.loads(old.read_text(encoding="utf-8"))
        if {k: have.get(k) for k in ("version", "seed", "spp", "plan")} != {k: meta[k] for k in ("version", "seed", "spp", "plan")}:
            raise ValueError(f"--dataset {str(folder)!r}: holds a different set (version {have.get('version')}, "
                             f"seed {have.get('seed')}); expected version {VERSION}, seed {seed} -- use another folder")
    _write(old, (json.dumps(meta, indent=1) + "\n").encode())
    todo = [(i, b) for i, b in plan() if not frame_paths(folder, i, b, False)[1].exists()]
    for index, batch in (progress(todo) if progress else todo):
        make_frame(folder, index, batch, seed)
    return len(todo)


def _renderer() -> str:
    from agvsim.bench.pbr_render import VARIANT, mitsuba

    return f"mitsuba {mitsuba().__version__} {VARIANT}"
