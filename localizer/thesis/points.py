"""The thesis's experimental test points (Tables 5.1-5.4) and their reproduction on
synthetic frames.

:data:`THESIS_POINTS` holds the 18 points of Tables 5.1 (16 mm lens) and 5.2 (50 mm):
the measured distance and orientation of the target and what the thesis computed
from its images (Tables 5.3-5.4 give the same points' errors). :func:`reproduce_thesis`
renders each point as an exact synthetic frame (:mod:`localizer.tools.synthetic`) and runs both
methods of :func:`localizer.detect_targets` on it; ``agvsim reproduce thesis`` prints it.
"""
from __future__ import annotations

__all__ = ["THESIS_POINTS", "reproduce_thesis"]

#: (lens mm, measured d mm, computed d mm, measured alpha deg, computed alpha deg), Tables 5.1 and 5.2
THESIS_POINTS: tuple[tuple[float, float, float, float, float], ...] = (
    (16, 1410, 1362, 0.0, 4.4), (16, 1990, 1905, 43.0, 45.8), (16, 2030, 1975, 5.0, 13.0),
    (16, 3240, 3164, -23.0, -20.0), (16, 3710, 3584, -50.0, -46.4), (16, 4060, 3913, 51.0, 48.1),
    (16, 4380, 4109, 42.0, 40.0), (16, 4400, 4126, 30.0, 28.3), (16, 5720, 5341, 70.0, 71.8),
    (50, 4910, 4881, 37.0, 38.8), (50, 5910, 5714, -40.0, -37.6), (50, 5940, 5929, 10.0, 14.5),
    (50, 6330, 6103, 65.0, 61.7), (50, 6370, 6281, 46.0, 43.0), (50, 6540, 6318, 57.0, 53.1),
    (50, 7330, 7410, 60.0, 57.3), (50, 8150, 8074, -20.0, -17.2), (50, 9520, 9334, 0.0, 6.8),
)


def reproduce_thesis(seed: int = 0, noise: float = 1.0, blur: float = 0.5, column: float = 40.0) -> dict:
    """The 18 points of :data:`THESIS_POINTS` on synthetic frames: thesis camera with the
    point's lens, target centre ``column`` px right of the principal point, positive
    target, normal lighting, ``blur`` px blur and ``noise`` grey levels of noise (seed
    ``seed``) on a flat background.

    Returns ``{"conditions": ..., "points": [...], "means": ...}``: per point the thesis's
    published figures and those of ``method="thesis"`` and ``method="exact"`` (distance
    mm, error %, orientation and error deg, standard deviations), and the mean absolute
    errors per lens.
    """
    import math

    import numpy as np

    from localizer import Camera, TargetSpec, detect_targets
    from localizer.tools.synthetic import pose_at_column, render_frame

    rng = np.random.default_rng(seed)
    target = TargetSpec()
    rows = []
    for i, (lens, d_m, d_c, a_m, a_c) in enumerate(THESIS_POINTS):
        cam = Camera.thesis(lens)
        pose = pose_at_column(cam, d_m / 1000.0, math.radians(a_m), cam.cx + column)
        img = render_frame(cam, pose, target, "positive", "normal", blur, noise, 0.55, rng)
        row = {"point": i + 1, "lens_mm": lens, "d_measured_mm": d_m, "alpha_measured_deg": a_m,
               "thesis": {"d_mm": d_c, "d_error_pct": 100.0 * (d_m - d_c) / d_m,
                          "alpha_deg": a_c, "alpha_error_deg": a_m - a_c}}
        for method in ("thesis", "exact"):
            obs = detect_targets(img, cam, target, method=method)
            if obs:
                o = obs[0]
                row[method + "_method"] = {
                    "d_mm": 1000.0 * o.distance, "d_error_pct": 100.0 * (d_m / 1000.0 - o.distance) / (d_m / 1000.0),
                    "alpha_deg": math.degrees(o.alpha), "alpha_error_deg": a_m - math.degrees(o.alpha),
                    "sigma_d_mm": 1000.0 * float(o.sigma[0]), "sigma_alpha_deg": math.degrees(float(o.sigma[2]))}
            else:
                row[method + "_method"] = None
        rows.append(row)
    means = {}
    for key in ("thesis", "thesis_method", "exact_method"):
        for lens in (16, 50):
            sel = [r[key] for r in rows if r["lens_mm"] == lens and r[key] is not None]
            means[f"{key}_{lens}mm"] = {
                "n": len(sel),
                "mean_abs_d_error_pct": float(np.mean([abs(s["d_error_pct"]) for s in sel])) if sel else None,
                "mean_abs_alpha_error_deg": float(np.mean([abs(s["alpha_error_deg"]) for s in sel])) if sel else None}
    return {"conditions": {"lighting": "normal", "blur_px": blur, "noise_grey": noise, "seed": seed,
                           "column_offset_px": column, "polarity": "positive"},
            "points": rows, "means": means}
