"""The frames of ``agvsim localize``'s inputs: image files, a folder of frames, or a video file.

:func:`open_input` decides what a path is -- by what it is, not only by its name:

* a folder: its image files (by extension, :data:`IMAGE_EXTENSIONS`) in name order, numbers in
  names compared as numbers (``frame_2.png`` before ``frame_10.png``); other entries skipped and
  counted;
* an image file: its header is one of :data:`localizer.image.io.FORMATS`, or its extension is an
  image's (a file named ``.png`` that is not one is then reported by the reader);
* a video: anything ``cv2.VideoCapture`` opens (``.mp4``, ``.avi``, ``.mkv``, ...);
* anything else: an :class:`Input` whose ``error`` says so (no such file, or none of these).

:meth:`Input.frames` yields :class:`Frame`\\ s: ``(index, time, grey image)`` or, for a frame
that cannot be read, ``error`` with the reason. Reading never stops at a bad frame: a video
frame the decoder cannot decode is one failed frame and the next is read; a video that ends
before the frame count in its header has the missing frames counted as failed (one
:class:`Frame` says how many).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

__all__ = ["IMAGE_EXTENSIONS", "VIDEO_HINT", "Frame", "Input", "grey", "natural_key", "open_input"]

#: extensions of the image files a folder's frames are taken from (what OpenCV reads)
IMAGE_EXTENSIONS = frozenset({".png", ".jpg", ".jpeg", ".jpe", ".bmp", ".dib", ".tif", ".tiff", ".webp",
                              ".pbm", ".pgm", ".ppm", ".pnm", ".pam"})
#: what a user is told a video is
VIDEO_HINT = "a video OpenCV can open (.mp4, .avi, .mkv, ...)"
#: consecutive failed reads after which a video is taken to have ended
_MAX_FAILED_READS = 8


@dataclass(frozen=True)
class Frame:
    """One frame of an input.

    Attributes:
        source: the frame's file (an image, or a frame of a folder) or the video's path.
        index: the frame's index in its input (0-based; image files given one by one count on).
        time: seconds from the input's start (video: the decoder's time stamp; folders and image
            files: ``index / fps``), or None when not known.
        image: ``(H, W)`` uint8 grey, or None when the frame could not be read.
        error: why the frame could not be read (None when it could).
        count: frames this item stands for (a video cut short: its missing frames in one item).
    """

    source: str
    index: int
    time: float | None
    image: np.ndarray | None = None
    error: str | None = None
    count: int = 1


def natural_key(name: str) -> list:
    """Sort key comparing the runs of digits in ``name`` as numbers (``f2`` before ``f10``)."""
    return [(0, int(part), part) if part.isdigit() else (1, 0, part) for part in re.split(r"(\d+)", name) if part]


def grey(frame: np.ndarray) -> np.ndarray:
    """A decoded frame as ``(H, W)`` uint8 grey (BGR and BGRA converted as OpenCV does; 16-bit scaled)."""
    import cv2

    if frame.dtype == np.uint16:
        frame = (frame >> 8).astype(np.uint8)
    if frame.ndim == 3 and frame.shape[2] == 1:
        frame = frame[:, :, 0]
    if frame.ndim == 3:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGRA2GRAY if frame.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    if frame.dtype != np.uint8 or frame.ndim != 2:
        raise ValueError(f"decoded to {frame.dtype} {frame.shape}, expected an 8-bit grey or colour frame")
    return np.ascontiguousarray(frame)


@dataclass
class Input:
    """One path given to ``agvsim localize``: what it is and how to read its frames.

    Attributes:
        path: as given.
        kind: ``"image"``, ``"folder"``, ``"video"``, or ``"error"`` (``error`` says why).
        files: a folder's image files, in order.
        skipped: a folder's entries that are not image files.
        count: frames expected (None: not known, as a video whose header does not say).
        fps: a video's frame rate from its header (None when it gives none).
        size: a video's ``(width, height)``.
    """

    path: str
    kind: str
    error: str | None = None
    files: tuple[str, ...] = ()
    skipped: int = 0
    count: int | None = None
    fps: float | None = None
    size: tuple[int, int] | None = None

    @property
    def is_stream(self) -> bool:
        """A folder or a video (frames with a progress bar), not one image file."""
        return self.kind in ("folder", "video")

    def frames(self, fps: float | None = None, first_index: int = 0) -> Iterator[Frame]:
        """The frames, in order (``fps``: frames per second for the times of image files and
        folders, and of a video whose decoder gives none; ``first_index``: an image file's index)."""
        from localizer.image.io import read_image_grey

        if self.kind == "error":
            yield Frame(self.path, first_index, None, error=self.error)
            return
        if self.kind == "video":
            yield from self._video_frames(fps)
            return
        names = self.files if self.kind == "folder" else (self.path,)
        for k, name in enumerate(names, start=first_index):
            t = k / fps if fps else None
            try:
                yield Frame(name, k, t, image=read_image_grey(name))
            except ValueError as exc:
                yield Frame(name, k, t, error=str(exc))

    def _video_frames(self, fps: float | None) -> Iterator[Frame]:
        import cv2

        cap = _capture(self.path)
        rate = self.fps or fps
        try:
            index = 0
            pending: list[int] = []  # failed reads not yet known to lie before a frame
            while True:
                ok, raw = cap.read()
                if not ok:
                    if self.count is not None and index >= self.count:
                        break  # the end, where the header says (a header counting short is read past)
                    pending.append(index)
                    index += 1
                    if len(pending) >= _MAX_FAILED_READS:
                        break
                    continue
                for k in pending:  # a frame came after them: they were frames the decoder could not read
                    yield Frame(self.path, k, k / rate if rate else None,
                                error=f"{self.path}: frame {k}: the decoder could not read it")
                pending = []
                msec = cap.get(cv2.CAP_PROP_POS_MSEC)
                t = msec / 1000.0 if msec > 0 or (index == 0 and msec == 0) else (index / rate if rate else None)
                try:
                    yield Frame(self.path, index, t, image=grey(raw))
                except ValueError as exc:
                    yield Frame(self.path, index, t, error=f"{self.path}: frame {index}: {exc}")
                index += 1
            read = index - len(pending)
            if self.count is not None and read < self.count:
                missing = self.count - read
                yield Frame(self.path, read, read / rate if rate else None, count=missing,
                            error=f"{self.path}: the video ends after {read} frames; its header says {self.count} "
                                  f"({missing} missing or unreadable at the end)")
        finally:
            cap.release()


def _capture(path: str):
    """``cv2.VideoCapture`` of ``path`` with OpenCV's and FFmpeg's own messages silenced (what
    cannot be read is reported here, once; ``OPENCV_FFMPEG_LOGLEVEL`` set by the user is kept)."""
    import cv2

    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # (read when FFmpeg first starts)
    logging = cv2.utils.logging
    level = logging.getLogLevel()
    logging.setLogLevel(logging.LOG_LEVEL_SILENT)
    try:
        cap = cv2.VideoCapture(path, cv2.CAP_FFMPEG)
        if not cap.isOpened():
            cap = cv2.VideoCapture(path)
    finally:
        logging.setLogLevel(level)
    return cap


def _is_image_file(path: Path) -> bool:
    from localizer.image.io import image_size

    if path.suffix.lower() in IMAGE_EXTENSIONS:
        return True
    try:
        with open(path, "rb") as f:
            return image_size(f) is not None
    except OSError:
        return False


def open_input(path: str) -> Input:
    """What ``path`` is (module docstring); never raises for a bad path: the :class:`Input`'s
    ``kind`` is ``"error"`` and its ``error`` one line naming the path and what was expected."""
    import cv2

    p = Path(path)
    if p.is_dir():
        try:
            entries = sorted(os.scandir(p), key=lambda e: natural_key(e.name))
        except OSError as exc:
            return Input(path, "error", f"{path}: cannot list the folder ({exc.strerror or exc})")
        files = tuple(os.path.join(path, e.name) for e in entries
                      if not e.name.startswith(".") and Path(e.name).suffix.lower() in IMAGE_EXTENSIONS
                      and e.is_file())
        if not files:
            return Input(path, "error", f"{path}: a folder with no image files; expected frames named *.png, *.jpg, "
                                        "... (or an image file, or a video)", skipped=len(entries))
        return Input(path, "folder", files=files, skipped=len(entries) - len(files), count=len(files))
    if not p.exists():
        return Input(path, "error", f"{path}: no such file")
    if _is_image_file(p):
        return Input(path, "image", count=1)
    cap = _capture(path)
    try:
        if cap.isOpened():
            w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            n = cap.get(cv2.CAP_PROP_FRAME_COUNT)
            fps = cap.get(cv2.CAP_PROP_FPS)
            if w > 0 and h > 0:
                return Input(path, "video", count=int(n) if n >= 1 else None,
                             fps=float(fps) if 0 < fps < 1e4 else None, size=(w, h))
    finally:
        cap.release()
    return Input(path, "error", f"{path}: not an image file (PNG, JPEG, ...), a folder of frames, or {VIDEO_HINT}")
