"""The named camera conditions of ``agvsim bench envelope`` (the one list: the CLI's
``--conditions`` choices, the report's rows and their order) and the floors they are held to.

Each condition changes one thing from ``baseline`` (the thesis camera, 512 x 480, a sharp
lens: Gaussian sd 0.5 px, linear 8-bit response, mild noise), except ``webcam`` (a cheap
colour camera's whole chain) and ``hires_*`` (the baseline on a larger sensor with the same
field of view and the same angular blur)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from agvsim.bench.envelope_sensor import FrameSettings


@dataclass(frozen=True)
class Condition:
    """One named camera condition."""

    name: str
    help: str  # one line for the report and the CLI
    settings: FrameSettings  # the camera


CONDITIONS: tuple[Condition, ...] = (
    Condition("baseline", "512x480, Gaussian sd 0.5 px, linear, noise sd ~2.5 codes on the paper", FrameSettings()),
    Condition("blur1", "Gaussian sd 1 px", FrameSettings(blur=1.0)),
    Condition("blur2", "Gaussian sd 2 px", FrameSettings(blur=2.0)),
    Condition("blur3", "Gaussian sd 3 px", FrameSettings(blur=3.0)),
    Condition("defocus", "defocus disc of radius 2 px", FrameSettings(psf="disc", blur=2.0)),
    Condition("motion", "horizontal motion streak of 3 px", FrameSettings(psf="streak", blur=3.0)),
    Condition("motion_diag", "motion streak of 4 px at 30 deg", FrameSettings(psf="streak", blur=4.0,
                                                                            streak_angle=math.radians(30.0))),
    Condition("gamma", "sRGB-encoded 8 bits", FrameSettings(encoding="srgb")),
    Condition("vignette", "vignetting to 40 % at the corners", FrameSettings(vignette=0.4)),
    Condition("jpeg70", "JPEG at quality 70", FrameSettings(jpeg_quality=70)),
    Condition("bayer", "RGGB Bayer mosaic, OpenCV demosaicing", FrameSettings(bayer=True)),
    Condition("dim", "quarter exposure at 4x gain (paper at ~55 codes)",
              FrameSettings(white_level=0.25, full_well=2000.0, read_noise=2.0)),
    Condition("noisy", "noise sd ~5 codes on the paper (2000 e- at full scale, read noise 2 codes)",
              FrameSettings(full_well=2000.0, read_noise=2.0)),
    Condition("very_noisy", "noise sd ~8 codes on the paper (1000 e- at full scale, read noise 4 codes)",
              FrameSettings(full_well=1000.0, read_noise=4.0)),
    Condition("flare", "veiling glare of 20 % of full scale", FrameSettings(flare=0.2)),
    Condition("saturated", "overexposed: paper clipped", FrameSettings(white_level=1.5)),
    Condition("webcam", "sRGB, Bayer, JPEG 80, vignetting to 60 %, Gaussian sd 0.8 px",
              FrameSettings(blur=0.8, encoding="srgb", bayer=True, jpeg_quality=80, vignette=0.6)),
    Condition("hires_1280", "baseline at 1280x1024 (same view, same angular blur)",
              FrameSettings(width=1280, height=1024)),
    Condition("hires_1920", "baseline at 1920x1200 (same view, same angular blur)",
              FrameSettings(width=1920, height=1200)),
    Condition("hires_2448", "baseline at 2448x2048 (same view, same angular blur)",
              FrameSettings(width=2448, height=2048)),
    Condition("blur3_1280", "blur3's angular blur at 1280x1024 (Gaussian sd 7.5 px)",
              FrameSettings(width=1280, height=1024, blur=3.0)),
    Condition("blur3_2448", "blur3's angular blur at 2448x2048 (Gaussian sd 14 px)",
              FrameSettings(width=2448, height=2048, blur=3.0)),
)
NAMES: tuple[str, ...] = tuple(c.name for c in CONDITIONS)
BY_NAME: dict[str, Condition] = {c.name: c for c in CONDITIONS}

#: floors: figure -> (op, limit, unit, what)
FLOORS: dict[str, tuple[str, float, str, str]] = {
    "detection_pct": (">=", 99.0, "%", "target found"),
    "d_error_pct_mean": ("<=", 0.5, "%", "d error mean"),
    "d_error_pct_max": ("<=", 2.0, "%", "d error max"),
    "alpha_error_deg_mean": ("<=", 1.0, "deg", "alpha error mean (bars >= 60 rows at 512x480, scaled)"),
    "alpha_error_deg_max": ("<=", 3.0, "deg", "alpha error max (bars >= 60 rows at 512x480, scaled)"),
    "within_3sigma_pct": (">=", 99.0, "%", "errors within 3 sigma (worst of d, beta, alpha, 3-D)"),
    "false_detections": ("<=", 0.0, "", "false detections on target frames"),
    "ms_median": ("<=", 0.5, "ms", "median ms per 512x480 frame"),
    "ms_p99": ("<=", 3.0, "ms", "p99 ms per 512x480 frame"),
    "ms_median_2448": ("<=", 2.0, "ms", "median ms per 2448x2048 frame"),
    "peer_ratio": (">=", 3.0, "x", "times faster than ArUco+solvePnP and AprilTag 3 on the same frames (medians; "
                                    "--peers)"),
}
#: the speed floors apply to conditions of this size (width, height)
SPEED_SIZE = {"ms_median": (512, 480), "ms_p99": (512, 480), "ms_median_2448": (2448, 2048)}
#: the alpha floors count targets whose shorter bar is at least this tall at 512 x 480 (rows;
#: scaled by the camera's fy, i.e. the same angular size)
ALPHA_MIN_ROWS = 60.0
#: chi-square with 3 degrees of freedom at the two-sided 3-sigma probability (0.99730)
CHI2_3D_3SIGMA = 14.156
#: a detection is the target when its bearing is within this of the truth (rad) and its
#: distance within this share of the true distance; everything else is a false detection
GATE_BETA, GATE_DISTANCE = math.radians(2.0), 0.2


def parse_conditions(text: str) -> tuple[Condition, ...]:
    """``a,b,...`` (or ``all``) -> the conditions, in the list's order; a ``ValueError`` naming
    ``--conditions``, the bad name, the choices and the nearest."""
    from localizer.numeric import check_choice

    if text.strip() == "all":
        return CONDITIONS
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ValueError(f"--conditions: expected a comma-separated list of {', '.join(NAMES)} or all, got {text!r}")
    chosen = {check_choice("--conditions", n, NAMES) for n in names}
    return tuple(c for c in CONDITIONS if c.name in chosen)
