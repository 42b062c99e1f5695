"""``agvsim localize``'s outputs over many frames: one row per frame and target (CSV or JSON
lines, written and flushed frame by frame), and annotated frames (a video or a folder).

Rows are SI: metres and radians (degrees only in the human table). A row is a target seen in a
frame (``target`` 1, 2, ...) or a frame that failed (``error`` says why; the measurement
fields empty); a frame without a target has no row. A frame's rows are written with Ctrl-C held
back, so an interrupted run leaves whole lines only.
"""
from __future__ import annotations

import csv
import io
import json
import sys
from pathlib import Path
from typing import Sequence

from agvsim.commands._output import JSON_DIGITS, clean_json
from agvsim.commands.frames import Frame

__all__ = ["COLUMNS", "FORMATS", "VIDEO_WRITERS", "FrameAnnotator", "RowWriter", "format_for", "rows_for"]

#: the columns of a row, in order (units in the names)
COLUMNS = ("source", "frame", "time_s", "target", "d_m", "beta_rad", "alpha_rad", "sigma_d_m", "sigma_beta_rad",
           "sigma_alpha_rad", "polarity", "error")
#: row formats (``--format``; ``--out``'s extension)
FORMATS = ("csv", "jsonl")
#: video extensions ``--annotate`` writes, and the codec (FourCC) of each
VIDEO_WRITERS = {".avi": "MJPG", ".mp4": "mp4v", ".mkv": "MJPG", ".mov": "mp4v"}


def format_for(path: str, flag: str = "--out") -> str:
    """The row format of a file name by its extension (``.csv``; ``.jsonl``, ``.ndjson``), else one
    ``ValueError`` naming the flag."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return "csv"
    if suffix in (".jsonl", ".ndjson"):
        return "jsonl"
    raise ValueError(f"{flag} {path!r}: expected a .csv or .jsonl file name (rows as CSV or JSON lines), "
                     f"got {suffix or 'no extension'}")


def rows_for(frame: Frame, observations: Sequence = ()) -> list[dict]:
    """The rows of one frame: one per observation (:class:`localizer.TargetObservation`), or one
    with the frame's ``error``; none for a frame read without a target."""
    base = {"source": frame.source, "frame": frame.index, "time_s": frame.time}
    if frame.error is not None:
        return [{**base, "error": frame.error}]
    rows = []
    for k, o in enumerate(observations, start=1):
        sd = o.sigma
        rows.append({**base, "target": k, "d_m": float(o.distance), "beta_rad": float(o.beta),
                     "alpha_rad": float(o.alpha), "sigma_d_m": float(sd[0]), "sigma_beta_rad": float(sd[1]),
                     "sigma_alpha_rad": float(sd[2]), "polarity": o.polarity})
    return rows


class RowWriter:
    """Rows to a file (``path``) or to stdout (``path`` None) as ``fmt`` (:data:`FORMATS`).

    The file is created at once (its folder made; a name that cannot be written fails before any
    work). :meth:`write` writes one frame's rows in one piece and flushes.
    """

    def __init__(self, path: str | None, fmt: str) -> None:
        self.path, self.fmt = path, fmt
        self.rows = 0
        if path is None:
            self.stream = sys.stdout
        else:
            p = Path(path)
            if p.is_dir():
                raise ValueError(f"--out {path!r}: a folder, expected a .csv or .jsonl file name")
            try:
                p.parent.mkdir(parents=True, exist_ok=True)
                self.stream = open(p, "w", encoding="utf-8", newline="")
            except OSError as exc:
                raise OSError(f"--out {path!r}: cannot write ({exc.strerror or exc})") from None
        if fmt == "csv":
            self._put(",".join(COLUMNS) + "\r\n")

    def _put(self, text: str) -> None:
        from agvsim.commands.workers import sigint_blocked

        with sigint_blocked():  # (a Ctrl-C now is raised after the frame's rows are out)
            self.stream.write(text)
            self.stream.flush()

    def write(self, rows: list[dict]) -> None:
        if not rows:
            return
        if self.fmt == "csv":
            buf = io.StringIO()
            w = csv.writer(buf)
            for r in rows:
                w.writerow(["" if r.get(c) is None else _csv_value(r[c]) for c in COLUMNS])
            text = buf.getvalue()
        else:
            text = "".join(json.dumps(clean_json({c: r.get(c) for c in COLUMNS})) + "\n" for r in rows)
        self._put(text)
        self.rows += len(rows)

    def close(self) -> None:
        if self.stream is not sys.stdout:
            self.stream.close()


def _csv_value(value):
    """A float with the digits of the JSON lines (:data:`agvsim.commands._output.JSON_DIGITS`)."""
    return f"{value:.{JSON_DIGITS}g}" if isinstance(value, float) else value


class FrameAnnotator:
    """Annotated frames of one folder (``out`` a folder: ``<frame name>.png`` in it) or one video
    (``out`` a video file of :data:`VIDEO_WRITERS`, the input's size and frame rate).

    Raises:
        ValueError: ``out`` is not what the input needs (before any work).
        OSError: OpenCV cannot write a video there.
    """

    def __init__(self, out: str, kind: str, size: tuple[int, int] | None = None, fps: float | None = None) -> None:
        import cv2

        self.out, self.kind, self.frames = Path(out), kind, 0
        self.size = tuple(size) if size is not None else None
        self.writer = None
        if kind == "folder":
            if self.out.exists() and not self.out.is_dir():
                raise ValueError(f"--annotate {out!r}: a file; for a folder of frames expected a folder name")
            self.out.mkdir(parents=True, exist_ok=True)
            return
        suffix = self.out.suffix.lower()
        if suffix not in VIDEO_WRITERS:
            raise ValueError(f"--annotate {out!r}: for a video expected a video file name "
                             f"({', '.join(VIDEO_WRITERS)}), got {suffix or 'no extension'}")
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self.writer = cv2.VideoWriter(str(self.out), cv2.VideoWriter_fourcc(*VIDEO_WRITERS[suffix]),
                                      float(fps or 25.0), tuple(size), True)
        if not self.writer.isOpened():
            raise OSError(f"--annotate {out!r}: OpenCV cannot write a {VIDEO_WRITERS[suffix]} video there")

    def add(self, frame: Frame, observations: Sequence) -> None:
        """Draw ``observations`` on ``frame`` with its index and time, and write it (a frame that
        was not read is left out)."""
        from localizer import annotate
        from localizer.tools.annotation import draw_text, text_box

        if frame.image is None:
            return
        img = annotate(frame.image, observations)
        label = f"frame {frame.index}" + (f"  {frame.time:.2f} s" if frame.time is not None else "")
        _, h = text_box(label)
        draw_text(img, label, (2, img.shape[0] - h - 2), color=(255, 255, 255))
        if self.writer is not None:
            if img.shape[1::-1] != self.size:
                return  # (a frame of another size cannot go into this video; it failed already)
            self.writer.write(img)
        else:
            from agvsim.commands._args import write_image

            write_image(self.out / (Path(frame.source).stem + ".png"), img, "--annotate")
        self.frames += 1

    def close(self) -> None:
        if self.writer is not None:
            self.writer.release()
