"""``agvsim localize INPUT...``: find two-bar targets in image files, folders of frames or videos
and report d, β, α of each (a table, one JSON object, or rows as CSV / JSON lines)."""
from __future__ import annotations

import argparse
import os
import sys

from agvsim.commands._args import number
from agvsim.commands._output import add_json_flag, emit_json, log, plural
from localizer.model.params import METHODS

#: failures told one by one on stderr (the rest are counted in the summary)
_TOLD_FAILURES = 10
#: failures listed in the summary of --json with --out (the rows have them all)
_KEPT_FAILURES = 100


def register(sub) -> None:
    p = sub.add_parser("localize", help="localize two-bar targets in image files, folders of frames or videos",
                       description="Find the thesis's two-bar targets in image files, folders of frames or video "
                                   "files and print the distance d, orientation alpha and bearing beta of each. "
                                   "With --out or --format: one row per frame and target (SI: m, rad); "
                                   "--json with --out prints the run's summary.")
    p.add_argument("images", nargs="+", metavar="INPUT",
                   help="image files (PNG, JPEG, ...), folders of frames (their image files in name order) or "
                        "video files (anything OpenCV opens: .mp4, .avi, .mkv, ...); every frame that fails is "
                        "reported and the others localized (exit status 2); a path that is none of these too, "
                        "but with --out or --format it stops the run before it starts")
    cam = p.add_mutually_exclusive_group()
    cam.add_argument("--lens", type=number(0.0, low_open=True, unit="mm"), default=16.0, metavar="MM",
                     help="thesis camera (512x480) with this focal length in mm (default 16); an image file of "
                          "another size is localized with the thesis sensor scaled to it, a frame of a folder or "
                          "video fails")
    cam.add_argument("--camera", metavar="CALIB.yaml", help="OpenCV calibration file (camera_matrix, "
                     "distortion_coefficients, image_width, image_height); every frame must have its size (default: none, "
                          "the thesis camera of --lens)")
    p.add_argument("--method", choices=METHODS, default="exact",
                   help="thesis: the thesis's pipeline; exact: subpixel edges + exact pose (default)")
    p.add_argument("--bar-width", type=number(0.0, low_open=True, unit="m"), default=0.075, metavar="M",
                   help="bar width b in metres (thesis proportions H=2b, s=b/2; default 0.075)")
    rows = p.add_mutually_exclusive_group()
    rows.add_argument("--out", metavar="ROWS.csv|ROWS.jsonl",
                      help="write one row per frame and target (source, frame, time_s, d_m, beta_rad, alpha_rad, "
                           "their sigmas, polarity; a failed frame: its error) as CSV or JSON lines, by the "
                           "extension; written and flushed frame by frame")
    rows.add_argument("--format", choices=("csv", "jsonl"), help="print the rows of --out on stdout in this format (default: none, the table for a person)")
    p.add_argument("--fps", type=number(0.0, low_open=True, unit="Hz"), metavar="HZ",
                   help="frame rate of image files and folders: a frame's time is index / HZ (default: no time); "
                        "a video's times are its own")
    p.add_argument("--annotate", metavar="OUT",
                   help="write the frames with edges and numbers marked: for image files OUT.png (OUT_<n>.png for "
                        "several), for a video a video file (.mp4, .avi, .mkv; same frame rate), for a folder a "
                        "folder of PNGs")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_json_flag(p)
    p.set_defaults(func=run)


def _annotate_path(out: str, index: int, count: int) -> str:
    if count == 1:
        return out
    from pathlib import Path

    path = Path(out)
    return str(path.with_name(f"{path.stem}_{index}{path.suffix or '.png'}"))


def _camera_for(base, img, frame, is_image: bool, calibration: str | None):
    """The camera for ``img`` and a log line, or a ``ValueError`` if its size is wrong for the camera."""
    if img.shape == base.shape:
        return base, None
    size = f"{img.shape[1]}x{img.shape[0]}"
    if calibration:
        what = "image" if is_image else "frame"
        raise ValueError(f"{frame.source}: {what} is {size} but the calibration is for {base.width}x{base.height}")
    if is_image:  # an image file given by name: the thesis sensor scaled to it, as it always was
        return base.scaled(img.shape[1], img.shape[0]), f"{frame.source}: {size} image, thesis sensor scaled to it"
    raise ValueError(f"{frame.source}: frame is {size} but the thesis camera (--lens) is {base.width}x{base.height}; "
                     "for another camera give --camera CALIB.yaml")


def _check_videos(inputs, base, calibration: str | None) -> None:
    """One line, before any work, for a video whose frames are not the camera's size."""
    for inp in inputs:
        if inp.kind == "video" and inp.size != (base.width, base.height):
            camera = f"the calibration {calibration}" if calibration else "the thesis camera (--lens)"
            raise ValueError(f"{inp.path}: video frames are {inp.size[0]}x{inp.size[1]} but {camera} is "
                             f"{base.width}x{base.height}; expected a video from that camera"
                             + ("" if calibration else " (for another camera give --camera CALIB.yaml)"))


def run(args: argparse.Namespace) -> int:
    from agvsim.commands._args import image_writer
    from agvsim.commands.frame_rows import FrameAnnotator, RowWriter, format_for
    from agvsim.commands.frames import open_input
    from localizer import Camera, TargetSpec

    target = TargetSpec.from_bar_width(args.bar_width)
    if args.camera:
        try:
            base = Camera.from_opencv_yaml(args.camera)
        except (ValueError, FileNotFoundError) as exc:
            raise ValueError(f"--camera {exc}") from None
    else:
        base = Camera.thesis(args.lens)
    if args.json and args.format:
        raise ValueError(f"--json with --format {args.format}: both print on stdout; expected --out FILE for the "
                         "rows with --json")
    fmt = format_for(args.out) if args.out else args.format
    inputs = [open_input(name) for name in args.images]
    bad = [i for i in inputs if i.kind == "error"]
    if fmt and bad:  # rows for a recording: a path that is not one stops the run before it starts
        more = f" (and {plural(len(bad) - 1, 'other input')} that cannot be read)" if len(bad) > 1 else ""
        raise ValueError(bad[0].error + more)
    _check_videos(inputs, base, args.camera)
    streams = [i for i in inputs if i.is_stream]
    if args.annotate and streams and len(inputs) != 1:
        raise ValueError(f"--annotate {args.annotate!r} with a folder or a video: expected that one input, "
                         f"got {len(inputs)} inputs")
    if args.annotate and streams and os.path.realpath(args.annotate) == os.path.realpath(streams[0].path):
        raise ValueError(f"--annotate {args.annotate!r}: the input itself; expected another name (the input is "
                         "read, never written)")
    if args.annotate and not streams:  # a name OpenCV cannot write fails before any work
        image_writer(_annotate_path(args.annotate, 0, len(inputs)), "--annotate")
    writer = RowWriter(args.out, fmt) if fmt else None
    annotator = None
    if args.annotate and streams:
        try:
            annotator = FrameAnnotator(args.annotate, streams[0].kind, streams[0].size, streams[0].fps or args.fps)
        except (ValueError, OSError):
            if writer is not None and args.out:  # (nothing is left behind by a run that did not start)
                writer.close()
                os.remove(args.out)
            raise
    for inp in streams:
        if inp.skipped:
            log(f"{inp.path}: {plural(inp.skipped, 'entry', 'entries')} skipped (not image files)")
    run_ = _Run(args, base, target, inputs, writer, annotator)
    try:
        run_.all()
    except KeyboardInterrupt:
        run_.close()
        if writer is None:
            run_.report(interrupted=True)
        where = (f"the {plural(writer.rows, 'row')} in {args.out or 'stdout'} are complete" if writer
                 else "the frames done are printed")
        log(f"agvsim localize: interrupted after {plural(run_.frames, 'frame')}; {where}"
            + (f"; {annotator.out} holds {plural(annotator.frames, 'annotated frame')}" if annotator else ""))
        return 130
    run_.close()
    run_.report()
    return 2 if run_.failed else 0


class _Run:
    """One run over the inputs: counts, the results of the table or JSON, rows as they come."""

    def __init__(self, args, base, target, inputs, writer, annotator) -> None:
        self.args, self.base, self.target, self.inputs = args, base, target, inputs
        self.writer, self.annotator = writer, annotator
        self.frames = self.read = self.failed = self.with_targets = self.targets = 0
        self.failed_items = 0  # (failed frames told: a video cut short is one item)
        self.failures: list[str] = []  # (the first of them, for --json)
        self.results: list[dict] = []  # (the JSON without --out/--format)
        self.table = writer is None and not args.json  # (the human table: printed frame by frame)
        self.only_images = all(i.kind != "folder" and i.kind != "video" for i in inputs)
        self.bar = None

    def all(self) -> None:
        from tqdm import tqdm

        image_index = 0
        if self.table:
            print(_TABLE_HEADER, flush=True)
        for n, inp in enumerate(self.inputs):
            self.bar = tqdm(total=inp.count, desc=inp.path[-30:], unit="frame", file=sys.stderr, leave=False,
                            disable=self.args.no_progress or not inp.is_stream, dynamic_ncols=True)
            for frame in inp.frames(self.args.fps, image_index if not inp.is_stream else 0):
                self.frame(frame, n, inp.kind)
                self.bar.update(frame.count)
            self.bar.close()
            image_index += not inp.is_stream

    def frame(self, frame, n: int, kind: str) -> None:
        """Localize one frame, then count it and write its rows and annotation, with Ctrl-C held back
        throughout: an interrupted run has each frame done whole, or not at all, and no compiled
        call is cut short. (numba hands a kernel's results back through Python code, and a
        KeyboardInterrupt raised there crashes the interpreter: 2 of 96 interrupted runs over a
        video ended in a segmentation fault while the detection was not held back.)"""
        from agvsim.commands.workers import sigint_blocked

        with sigint_blocked():
            frame, obs, ms = self._detect(frame, kind in ("folder", "video"))
            self._commit(frame, obs, ms, n, kind)

    def _detect(self, frame, stream: bool):
        import dataclasses
        import statistics
        import time

        from localizer import detect_targets

        if frame.error is not None:
            return frame, [], None
        try:
            camera, note = _camera_for(self.base, frame.image, frame, not stream, self.args.camera)
        except ValueError as exc:
            return dataclasses.replace(frame, image=None, error=str(exc)), [], None
        if note:
            self._tell(note)
        try:
            times = []
            for _ in range(1 if stream else 6):  # an image file: the median of 5 more runs
                t0 = time.perf_counter()
                obs = detect_targets(frame.image, camera, self.target, method=self.args.method)
                times.append(time.perf_counter() - t0)
        except Exception as exc:  # this frame only: the others are still localized
            reason = " ".join(f"{type(exc).__name__}: {exc}".split())  # (one line, as every error here)
            return dataclasses.replace(frame, error=f"{frame.source}: frame {frame.index}: the detector failed "
                                                    f"({reason})"), [], None
        return frame, obs, 1000.0 * statistics.median(times[1:] or times)

    def _commit(self, frame, obs, ms, n: int, kind: str) -> None:
        from agvsim.commands.frame_rows import rows_for

        stream = kind in ("folder", "video")
        self.frames += frame.count
        if self.annotator is not None:  # (a frame the detector failed on: as it is, to keep the video whole)
            self.annotator.add(frame, obs)
        if frame.error is not None:
            self.failed += frame.count
            self.failed_items += 1
            if self.failed_items <= _TOLD_FAILURES:
                self._tell(f"agvsim localize: error: {frame.error}")
            elif self.failed_items == _TOLD_FAILURES + 1:
                self._tell("agvsim localize: further failed frames are counted in the summary")
            if len(self.failures) < _KEPT_FAILURES:
                self.failures.append(frame.error)
        else:
            self.read += 1
            self.with_targets += bool(obs)
            self.targets += len(obs)
            if self.args.annotate and not stream:
                self._annotate_image(frame, obs, n)
        if self.writer is not None:
            self.writer.write(rows_for(frame, obs))
        elif self.table:
            label = f"{frame.source}#{frame.index}" if kind == "video" else frame.source
            for line in _table_lines(self._result(frame, obs, ms, stream), label):
                self._tell(line, sys.stdout)
        else:
            self.results.append(self._result(frame, obs, ms, stream))

    def _annotate_image(self, frame, obs, n: int) -> None:
        from agvsim.commands._args import write_image
        from localizer import annotate

        out = write_image(_annotate_path(self.args.annotate, n, len(self.inputs)), annotate(frame.image, obs),
                          "--annotate")
        self._tell(f"wrote {out}")

    def _tell(self, line: str, file=None) -> None:
        """``line`` on stderr (or ``file``), above the progress bar."""
        if self.bar is not None and not self.bar.disable:
            self.bar.write(line, file=file or sys.stderr)
        elif file is not None:
            print(line, file=file, flush=True)
        else:
            log(line)

    def _result(self, frame, obs, ms, stream: bool) -> dict:
        r: dict = {"image": frame.source}
        if stream:
            r.update(frame=frame.index, time_s=frame.time)
        if frame.error is not None:
            return {**r, "error": frame.error, "targets": []}
        return {**r, "ms_per_frame": ms, "targets": [o.to_dict() for o in obs]}

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        if self.writer is not None:
            self.writer.close()
        if self.annotator is not None:
            self.annotator.close()

    def summary(self) -> dict:
        return {"frames": self.frames, "read": self.read, "failed": self.failed, "with_targets": self.with_targets,
                "targets": self.targets}

    def report(self, interrupted: bool = False) -> None:
        args, base = self.args, self.base
        camera = {"fx": base.fx, "fy": base.fy, "cx": base.cx, "cy": base.cy, "width": base.width,
                  "height": base.height, "dist": list(base.dist)}
        if self.writer is None and args.json:
            emit_json({"ok": not self.failed and not interrupted, "method": args.method, "camera": camera,
                       **({"interrupted": True} if interrupted else {}), "summary": self.summary(),
                       "results": self.results})
        if interrupted:
            return
        if self.only_images and self.writer is None:
            if self.failed:
                log(f"agvsim localize: {self.failed} of {len(self.inputs)} images could not be read")
            return
        log(f"agvsim localize: {plural(self.frames, 'frame')}: {self.read} read, {self.failed} failed, "
            f"{self.with_targets} with targets ({plural(self.targets, 'target')})"
            + (f"; {plural(self.writer.rows, 'row')} in {args.out}" if self.writer and args.out else "")
            + (f"; {plural(self.annotator.frames, 'annotated frame')} in {self.annotator.out}"
               if self.annotator else ""))
        if self.writer is not None and args.json:
            emit_json({"ok": not self.failed, "method": args.method, "camera": camera, "out": args.out,
                       "rows": self.writer.rows, **self.summary(), "failures": self.failures,
                       "inputs": [{"path": i.path, "kind": i.kind, "frames": i.count, "skipped": i.skipped}
                                  for i in self.inputs]})


_TABLE_HEADER = (f"{'image':<28} {'#':>2} {'d (m)':>8} {'alpha':>7} {'beta':>7} {'sd d':>7} {'sd a':>6} "
                 f"{'polarity':>9} {'ms':>6}")


def _table_lines(r: dict, label: str) -> list[str]:
    """The human table's lines for one frame's result (degrees)."""
    import math

    name = label[-28:]
    if "error" in r:
        return [f"{name:<28} {'-':>2} error: {r['error']}"]
    if not r["targets"]:
        return [f"{name:<28} {'-':>2} {'no target':>8} {'':>7} {'':>7} {'':>7} {'':>6} {'':>9} "
                f"{r['ms_per_frame']:6.2f}"]
    return [f"{name:<28} {k + 1:>2} {t['distance_m']:8.3f} {t['alpha_deg']:7.2f} {t['beta_deg']:7.2f} "
            f"{t['sigma']['distance_m']:7.3f} {math.degrees(t['sigma']['alpha_rad']):6.2f} {t['polarity']:>9} "
            f"{r['ms_per_frame']:6.2f}" for k, t in enumerate(r["targets"])]
