"""A drive logged as a plain folder, read (:func:`read_folder`) and written (:class:`FolderWriter`).

Layout (every stamp in seconds, on one clock)::

    DIR/frames/            the images (PNG, JPEG, ... anything OpenCV reads)
    DIR/frames.csv         t,file          (file relative to frames/)
    DIR/odometry.csv       t,left,right    cumulative wheel encoder ticks, or
                           t,v,omega       measured speed (m/s) and yaw rate (rad/s) over the
                                           interval ending at t
    DIR/truth.csv          t,x,y,theta     the true pose (m, m, rad), optional
    DIR/vehicle.yaml       the vehicle (:func:`agvsim.replay.drive.load_vehicle`), optional
    DIR/camera.yaml        the camera's OpenCV calibration, optional

A row that cannot be read (cut off, not a number) is one line naming the file and the row.
"""
from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from agvsim.files import TMP_PREFIX
from agvsim.replay.drive import DriveLog, clean_times

__all__ = ["FolderWriter", "read_folder"]

#: the odometry file's columns, by kind
ODOMETRY_COLUMNS = {"ticks": ("t", "left", "right"), "twist": ("t", "v", "omega")}


def _rows(path: Path, columns: tuple[str, ...]) -> list[list[str]]:
    """The rows of a CSV file whose header is ``columns`` (a cut-off last row included, to be
    refused by the caller's conversion)."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    if not rows or tuple(c.strip() for c in rows[0]) != columns:
        got = ",".join(rows[0]) if rows else "an empty file"
        raise ValueError(f"{path}: header {got!r}; expected {','.join(columns)}")
    return rows[1:]


def _numbers(path: Path, rows: list[list[str]], width: int) -> np.ndarray:
    out = np.empty((len(rows), width))
    for i, row in enumerate(rows):
        try:
            if len(row) != width:
                raise ValueError
            out[i] = [float(v) for v in row]
        except ValueError:
            raise ValueError(f"{path}: row {i + 2} {','.join(row)!r} is cut off or not {width} numbers") from None
    return out


def read_folder(folder: str | os.PathLike) -> DriveLog:
    """The drive logged in ``folder`` (the module docstring's layout). Raises ``ValueError`` (one
    line naming the file) for a missing or unreadable part."""
    import cv2

    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder}: not a folder; expected a logged drive (frames/, frames.csv, odometry.csv)")
    for name in ("frames.csv", "odometry.csv"):
        if not (folder / name).is_file():
            raise ValueError(f"{folder}: no {name}; expected a logged drive (frames/, frames.csv, odometry.csv)")
    frame_rows = _rows(folder / "frames.csv", ("t", "file"))
    try:
        stamps = [float(r[0]) for r in frame_rows]
        files = [r[1] for r in frame_rows]
    except (ValueError, IndexError):
        bad = next(i for i, r in enumerate(frame_rows) if len(r) != 2 or not _is_number(r[0]))
        raise ValueError(f"{folder / 'frames.csv'}: row {bad + 2} {','.join(frame_rows[bad])!r} is cut off or not "
                         "t,file") from None
    notes = []
    order, n = clean_times(stamps, "frames", str(folder / "frames.csv"))
    notes += n
    with open(folder / "odometry.csv", newline="", encoding="utf-8", errors="replace") as f:
        header = tuple(c.strip() for c in next(csv.reader(f), []))
    kind = next((k for k, cols in ODOMETRY_COLUMNS.items() if cols == header), None)
    if kind is None:
        raise ValueError(f"{folder / 'odometry.csv'}: header {','.join(header)!r}; expected "
                         + " or ".join(",".join(c) for c in ODOMETRY_COLUMNS.values()))
    odo = _numbers(folder / "odometry.csv", _rows(folder / "odometry.csv", ODOMETRY_COLUMNS[kind]), 3)
    o_order, n = clean_times(odo[:, 0], "odometry records", str(folder / "odometry.csv"))
    notes += n
    odo = odo[o_order]
    truth = None
    if (folder / "truth.csv").is_file():
        truth = _numbers(folder / "truth.csv", _rows(folder / "truth.csv", ("t", "x", "y", "theta")), 4)
        truth = truth[clean_times(truth[:, 0], "truth records", str(folder / "truth.csv"))[0]]
    frames_dir = folder / "frames"
    names = [files[i] for i in order]

    def read_frame(k: int) -> np.ndarray:
        path = frames_dir / names[k]
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED) if path.is_file() else None
        if image is None:
            raise ValueError(f"{path}: missing or not an image OpenCV can decode")
        return image

    return DriveLog(str(folder), np.asarray(stamps, dtype=float)[order], read_frame, odo[:, 0], odo[:, 1:], kind,
                    truth, tuple(notes))


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


class FolderWriter:
    """Writes a drive as a log folder (the module docstring) as it is driven: frames as PNG,
    odometry as a twist (v, ω over each control step), the truth. The CSV files are written under
    temporary names and renamed into place by :meth:`close` (an interrupted export leaves no
    half-written file under a final name); a folder that already holds a log is refused."""

    def __init__(self, folder: str | os.PathLike) -> None:
        self.folder = Path(folder)
        if (self.folder / "frames.csv").exists():
            raise ValueError(f"--export-log {str(self.folder)!r}: holds a logged drive already; expected a new folder")
        (self.folder / "frames").mkdir(parents=True, exist_ok=True)
        self._files = {}
        self._writers = {}
        for name, header in (("frames.csv", ("t", "file")), ("odometry.csv", ODOMETRY_COLUMNS["twist"]),
                             ("truth.csv", ("t", "x", "y", "theta"))):
            f = open(self.folder / (TMP_PREFIX + name), "w", newline="", encoding="utf-8")
            self._files[name] = f
            self._writers[name] = csv.writer(f)
            self._writers[name].writerow(header)
        self.frames = 0

    def describe(self, vehicle, camera) -> None:
        """The vehicle (:class:`~agvsim.replay.drive.VehicleFile`) and the camera
        (:class:`localizer.Camera`): ``vehicle.yaml`` and ``camera.yaml`` beside the log."""
        vehicle.to_yaml(self.folder / "vehicle.yaml")
        camera.to_opencv_yaml(self.folder / "camera.yaml")

    def odometry(self, t: float, v: float, omega: float) -> None:
        """The measured (v m/s, ω rad/s) over the interval ending at ``t`` (s)."""
        self._writers["odometry.csv"].writerow((repr(float(t)), repr(float(v)), repr(float(omega))))

    def truth(self, t: float, pose) -> None:
        """The true pose (x m, y m, θ rad) at ``t`` (s)."""
        self._writers["truth.csv"].writerow((repr(float(t)), *(repr(float(p)) for p in pose)))

    def frame(self, t: float, image: np.ndarray) -> None:
        """A frame captured at ``t`` (s), written losslessly (PNG)."""
        import cv2

        name = f"{self.frames:06d}.png"
        cv2.imwrite(str(self.folder / "frames" / name), image)
        self._writers["frames.csv"].writerow((repr(float(t)), name))
        self.frames += 1

    def close(self, keep: bool = True) -> None:
        """Close the files and rename them into place (``keep``), or remove them."""
        for name, f in self._files.items():
            f.close()
            tmp = self.folder / (TMP_PREFIX + name)
            if keep:
                os.replace(tmp, self.folder / name)
            else:
                tmp.unlink(missing_ok=True)
        self._files = {}
