"""``agvsim bench filter-soak``: the pose filter under ``--increments`` odometry increments and
hostile frames.

A vehicle drives laps of an oval (two 30 m straights, two half circles of 6 m radius, 1 m/s,
control steps of 20 ms) in a 50 m x 24 m hall whose walls carry targets at irregular places
(no two stretches alike). Its odometry is the true arc plus noise drawn from the filter's own
model; a frame is captured every ``increments // frames`` steps and fused ``LATENCY_STEPS``
later. Everything random comes from ``numpy.random.default_rng(seed)``.

Frames (:data:`FRAME_KINDS`): consistent observations of the targets in view (the localizer's
scale of σ plus the filter's floor), far-off garbage (tight or as loose as the limits allow),
covariances scaled by 10^3 ... 10^300, near-singular covariances, covariances that are not
positive semi-definite, NaN / inf fields, empty frames, NaN / inf / decreasing time stamps, and
frames mixing kinds. Besides each real increment, bogus ones (:data:`ODOMETRY_GARBAGE`: NaN,
inf and decreasing time stamps, NaN / inf / huge steps and turns, a contact flag that is not a
bool) are offered now and then, and spells of bumper contact. Now and then the vehicle is
carried elsewhere on the oval: told (``declare_lost``) or silently (the filter must find out).

Each call that must be refused is checked to raise, to add exactly one to the count of its
reason in ``PoseEKF.diagnostics()`` and to leave the state as it was; each uninformative
observation of a fused frame to be counted. After every fused frame: filterpy's ``P`` finite,
symmetric, positive definite, position σ within ``MAX_POSITION_SIGMA``; the position error while
the filter says ``tracking`` (apart from a silent kidnap's window before it finds itself lost);
every confirmed re-localization within 1 m of the truth. The refusal counts reported are the
filter's own. Floors: P always finite, symmetric and positive definite, its position σ never
above ``MAX_POSITION_SIGMA``, 0 wrong confirmed re-localizations, every refusal counted, nothing
half-applied, no crash. Progress goes to stderr; Ctrl-C stops the run and reports the steps done.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from agvsim.bench.floors import floor_line, verdict
from agvsim.bench.soak_inputs import (DT, FRAME_KINDS, LAP, ODOMETRY_GARBAGE, SPEED, Frames, in_hall,
                                      odometry_garbage, oval, turn, world)
from agvsim.commands._args import number

LATENCY_STEPS = 2  # control steps from capture to fusion
WRONG_RELOCALIZATION = 1.0  # m: a confirmed pose further than this from the truth is wrong
#: frames a silent kidnap has to be found in; after them its error counts as tracking error
DETECT_WITHIN = 400
ODOMETRY_GARBAGE_RATE = 0.002  # per control step
CONTACT_RATE, CONTACT_STEPS = 1e-4, 10  # spells of bumper contact: per step, and how long


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--increments", type=number(100, integer=True), default=1_000_000,
                   help="odometry increments (control steps of 20 ms; default 1000000)")
    p.add_argument("--frames", type=number(1, integer=True), default=40_000,
                   help="camera frames over the run (default 40000)")
    p.add_argument("--kidnaps", type=number(0, integer=True), default=40,
                   help="times the vehicle is carried elsewhere, half of them silently (default 40)")
    p.add_argument("--seed", type=number(0, integer=True), default=0, help="run seed (default 0)")


class Soak:
    """One run (:func:`measure`): the truth, the filter, the hostile inputs and the figures."""

    def __init__(self, increments: int, frames: int, kidnaps: int, seed: int) -> None:
        from localizer.filter import PoseEKF

        self.rng = np.random.default_rng(seed)
        self.targets, self.mount, self.config = world(seed)
        self.increments, self.every = increments, max(increments // frames, LATENCY_STEPS + 1)
        self.kidnaps, self.kidnap_every = kidnaps, increments // (kidnaps + 1)
        self.s = 0.0  # m along the oval
        self.truth = np.array(oval(0.0))
        P0 = np.diag([1e-4, 1e-4, 1e-6])
        self.ekf = PoseEKF(self.truth.copy(), P0, self.targets, self.mount, self.config, free_space=in_hall)
        self.frames = Frames(self.rng, self.targets, self.mount, self.config)
        self.kinds = list(FRAME_KINDS)
        self.p = np.array(list(FRAME_KINDS.values()))
        self.p /= self.p.sum()
        f = self.figures = {
            "frames_fused": 0, "frames_refused": 0, "frame_kinds": {k: 0 for k in FRAME_KINDS},
            "odometry_garbage": {name: 0 for name, _ in ODOMETRY_GARBAGE}, "contact_steps": 0,
            "P_max_eigenvalue": 0.0, "P_min_eigenvalue": math.inf, "P_max_asymmetry": 0.0,
            "P_not_finite": 0, "P_not_symmetric": 0, "P_not_positive_definite": 0,
            "max_position_sigma_m": 0.0, "max_heading_sigma_rad": 0.0,
            "max_error_tracking_m": 0.0, "max_error_tracking_frame": None, "max_heading_error_tracking_rad": 0.0,
            "frames_tracking": 0, "frames_beyond_3_sigma": 0,
            "relocalizations": 0, "wrong_relocalizations": 0, "max_relocalization_error_m": 0.0,
            "wrong_cases": [], "kidnaps_told": 0, "kidnaps_silent": 0, "silent_found": 0,
            "max_frames_to_find": 0, "max_error_before_found_m": 0.0,
            "refusals_expected": {}, "uncounted_refusals": 0, "not_refused": 0, "half_applied": 0,
            "crashes": 0, "crash_cases": [], "accepted_updates": 0, "nis_sum": 0.0}
        self.window = None  # a silent kidnap not yet found (:meth:`kidnap`)
        f["targets"] = len(self.targets)

    # ------------------------------------------------------------ hostile calls
    def refused(self, reason: str, fn, *args) -> None:
        """Call ``fn(*args)``, which must raise ``ValueError`` counted once under ``reason`` and
        change nothing."""
        f, ekf = self.figures, self.ekf
        f["refusals_expected"][reason] = f["refusals_expected"].get(reason, 0) + 1
        before = dict(ekf.diagnostics()["refusals"])
        state = (ekf.pose(), ekf.covariance(), ekf.time, ekf.status, ekf.lost_events)
        try:
            fn(*args)
        except ValueError:
            pass
        except Exception as exc:  # noqa: BLE001 - counted as a crash
            self.crash(exc, f"refusing {reason}")
            return
        else:
            f["not_refused"] += 1
        after = ekf.diagnostics()["refusals"]
        diff = {k: after.get(k, 0) - before.get(k, 0) for k in after}
        if {k: v for k, v in diff.items() if v} != {reason: 1}:
            f["uncounted_refusals"] += 1
        now = (ekf.pose(), ekf.covariance(), ekf.time, ekf.status, ekf.lost_events)
        if not (np.array_equal(state[0], now[0]) and np.array_equal(state[1], now[1]) and state[2:] == now[2:]):
            f["half_applied"] += 1

    def crash(self, exc: BaseException, where: str) -> None:
        self.figures["crashes"] += 1
        if len(self.figures["crash_cases"]) < 5:
            self.figures["crash_cases"].append({"where": where, "error": type(exc).__name__,
                                                "message": str(exc)[:200]})

    def odometry_garbage(self, t: float) -> None:
        name, reason = ODOMETRY_GARBAGE[int(self.rng.integers(len(ODOMETRY_GARBAGE)))]
        self.figures["odometry_garbage"][name] += 1
        self.refused(reason, self.ekf.add_odometry, *odometry_garbage(name, t))

    def fuse(self, t: float, x_cap: np.ndarray, step: int) -> None:
        """Fuse the frame captured at ``t`` at the true pose ``x_cap``; check and record."""
        from localizer.filter import TRACKING
        from localizer.filter.limits import UNINFORMATIVE

        f, ekf, rng = self.figures, self.ekf, self.rng
        kind = self.kinds[int(rng.choice(len(self.kinds), p=self.p))]
        f["frame_kinds"][kind] += 1
        if kind == "bad_time":
            bad_t = [math.nan, math.inf, -math.inf, ekf.time - 0.5 - rng.random()][int(rng.integers(4))]
            self.refused("frame_time", ekf.process_frame, bad_t, self.frames.consistent(x_cap))
            kind = "consistent"
        obs, reason = self.frames.hostile(kind, x_cap)
        if reason is not None:
            self.refused(reason, ekf.process_frame, t, obs)
            f["frames_refused"] += 1
            return
        before = ekf.diagnostics()["refusals"].get("measurement_uninformative", 0)
        try:
            res = ekf.process_frame(t, obs)
        except Exception as exc:  # noqa: BLE001 - a valid frame must be fused
            self.crash(exc, f"fusing a {kind} frame at step {step}")
            return
        f["frames_fused"] += 1
        uninformative = sum(a.status == UNINFORMATIVE for a in res.associations)
        f["refusals_expected"]["measurement_uninformative"] = (
            f["refusals_expected"].get("measurement_uninformative", 0) + uninformative)
        if ekf.diagnostics()["refusals"].get("measurement_uninformative", 0) - before != uninformative:
            f["uncounted_refusals"] += 1
        f["accepted_updates"] += res.accepted
        f["nis_sum"] += float(np.sum(res.nis))
        self.check_covariance(ekf.P)
        err = math.hypot(*(ekf.x[:2] - x_cap[:2]))
        if res.relocalized:
            f["relocalizations"] += 1
            f["max_relocalization_error_m"] = max(f["max_relocalization_error_m"], err)
            if err > WRONG_RELOCALIZATION:
                f["wrong_relocalizations"] += 1
                if len(f["wrong_cases"]) < 5:
                    f["wrong_cases"].append({"step": step, "error_m": err, "x": ekf.x.tolist(),
                                             "truth": x_cap.tolist(), "sigma_m": ekf.position_sigma()})
        if self.window is not None:
            self.window[0] += 1
            found = ekf.lost_events > self.window[1] or res.relocalized or ekf.status != TRACKING
            if found or self.window[0] > DETECT_WITHIN:
                f["silent_found"] += found
                f["max_frames_to_find"] = max(f["max_frames_to_find"], self.window[0])
                self.window = None
            else:
                f["max_error_before_found_m"] = max(f["max_error_before_found_m"], err)
                return
        if ekf.status == TRACKING:
            f["frames_tracking"] += 1
            if err > f["max_error_tracking_m"]:
                f["max_error_tracking_m"], f["max_error_tracking_frame"] = err, step // self.every
            dth = abs(math.remainder(float(ekf.x[2] - x_cap[2]), 2 * math.pi))
            f["max_heading_error_tracking_rad"] = max(f["max_heading_error_tracking_rad"], dth)
            f["frames_beyond_3_sigma"] += err > 3.0 * ekf.position_sigma()

    def check_covariance(self, P: np.ndarray) -> None:
        from localizer.filter import position_sigma

        f = self.figures
        if not np.isfinite(P).all():
            f["P_not_finite"] += 1
            return
        scale = float(np.abs(P).max())
        asym = float(np.abs(P - P.T).max()) / scale if scale > 0 else 0.0
        f["P_max_asymmetry"] = max(f["P_max_asymmetry"], asym)
        f["P_not_symmetric"] += asym > 1e-9
        eig = np.linalg.eigvalsh(0.5 * (P + P.T))
        f["P_not_positive_definite"] += eig[0] <= 0.0
        f["P_max_eigenvalue"] = max(f["P_max_eigenvalue"], float(eig[-1]))
        f["P_min_eigenvalue"] = min(f["P_min_eigenvalue"], float(eig[0]))
        f["max_position_sigma_m"] = max(f["max_position_sigma_m"], position_sigma(P))
        f["max_heading_sigma_rad"] = max(f["max_heading_sigma_rad"], math.sqrt(max(P.item(2, 2), 0.0)))

    def kidnap(self, step: int) -> None:
        """Carry the vehicle at least 10 m along the oval; tell the filter every other time."""
        old = self.truth
        while True:
            s = float(self.rng.uniform(0.0, LAP))
            new = np.array(oval(s))
            if math.hypot(*(new[:2] - old[:2])) >= 10.0:
                break
        self.s, self.truth = s, new
        if (self.figures["kidnaps_told"] + self.figures["kidnaps_silent"]) % 2:
            self.figures["kidnaps_told"] += 1
            self.ekf.declare_lost("kidnapped (told)")
        else:
            self.figures["kidnaps_silent"] += 1
            self.window = [0, self.ekf.lost_events]  # frames since, lost events before

    # ------------------------------------------------------------ the run
    def run(self, progress: bool = True) -> int:
        from tqdm import tqdm

        from localizer.filter import OdometryNoise, arc_motion, compose

        rng, ekf = self.rng, self.ekf
        noise: OdometryNoise = self.config.noise
        ds = SPEED * DT
        contact_left, in_flight, done = 0, None, 0
        next_kidnap = self.kidnap_every if self.kidnaps else self.increments + 1
        bar = tqdm(total=self.increments, desc="filter soak", unit=" steps", file=sys.stderr, disable=not progress,
                   leave=False, mininterval=1.0)
        normals, i = rng.standard_normal((10_000, 2)), 0  # the odometry noise, drawn in blocks
        try:
            for k in range(1, self.increments + 1):
                t = k * DT
                dth = turn(self.s, ds)
                self.s += ds
                self.truth = compose(self.truth, arc_motion(ds, dth))
                if i == len(normals):
                    normals, i = rng.standard_normal((10_000, 2)), 0
                e0, e1 = normals[i].tolist()
                i += 1
                vs, cov, vt = noise.covariance(ds, dth)
                l00 = math.sqrt(vs)
                l10 = cov / l00
                l11 = math.sqrt(max(vt - l10 * l10, 0.0))
                if contact_left == 0 and rng.random() < CONTACT_RATE:
                    contact_left = CONTACT_STEPS
                touching = contact_left > 0
                contact_left -= touching
                self.figures["contact_steps"] += touching
                try:
                    ekf.add_odometry(t, ds + l00 * e0, dth + l10 * e0 + l11 * e1, touching)
                except Exception as exc:  # noqa: BLE001 - a valid increment must be queued
                    self.crash(exc, f"odometry at step {k}")
                if rng.random() < ODOMETRY_GARBAGE_RATE:
                    self.odometry_garbage(t)
                if in_flight is not None and k >= in_flight[0]:
                    self.fuse(in_flight[1], in_flight[2], k)
                    in_flight = None
                if k % self.every == 0:
                    in_flight = (k + LATENCY_STEPS, t, self.truth.copy())
                elif k >= next_kidnap and in_flight is None:
                    self.kidnap(k)
                    done_kidnaps = self.figures["kidnaps_told"] + self.figures["kidnaps_silent"]
                    next_kidnap += self.kidnap_every if done_kidnaps < self.kidnaps else self.increments
                done = k
                if k % 1000 == 0:
                    bar.update(1000)
        except KeyboardInterrupt:
            pass
        finally:
            bar.close()
        return done


def measure(increments: int = 1_000_000, frames: int = 40_000, kidnaps: int = 40, seed: int = 0,
            progress: bool = True) -> dict:
    """Run the soak (module docstring) and return its figures, floors included."""
    from localizer.filter.limits import MAX_POSITION_SIGMA, REFUSAL_REASONS

    soak = Soak(increments, frames, kidnaps, seed)
    t0 = time.perf_counter()
    done = soak.run(progress)
    wall = time.perf_counter() - t0
    f = soak.figures
    d = soak.ekf.diagnostics()
    f["P_min_eigenvalue"] = None if math.isinf(f["P_min_eigenvalue"]) else f["P_min_eigenvalue"]
    f["mean_nis"] = f.pop("nis_sum") / f["accepted_updates"] if f["accepted_updates"] else None
    refusals = {r: d["refusals"].get(r, 0) for r in REFUSAL_REASONS}
    refusals.update({r: n for r, n in d["refusals"].items() if r not in refusals})
    f["floors"] = {
        "P_not_finite": verdict(f["P_not_finite"], "<=", 0),
        "P_not_symmetric": verdict(f["P_not_symmetric"], "<=", 0),
        "P_not_positive_definite": verdict(f["P_not_positive_definite"], "<=", 0),
        "max_position_sigma": verdict(f["max_position_sigma_m"], "<=", MAX_POSITION_SIGMA, "m"),
        "wrong_relocalizations": verdict(f["wrong_relocalizations"], "<=", 0),
        "uncounted_refusals": verdict(f["uncounted_refusals"] + f["not_refused"], "<=", 0),
        "half_applied": verdict(f["half_applied"], "<=", 0),
        "crashes": verdict(f["crashes"], "<=", 0),
        "relocalizations_counted": verdict(abs(d["relocalizations"] - f["relocalizations"]), "<=", 0)}
    return {"increments_requested": increments, "increments": done, "interrupted": done < increments,
            "frames_requested": frames, "seed": seed, "wall_s": wall, "lost_events": d["lost_events"],
            "status_at_end": d["status"], "refusals": refusals, **f}


def run(args) -> dict:
    return measure(args.increments, args.frames, args.kidnaps, args.seed, progress=True)


def format_table(result: dict) -> str:
    r = result
    lines = [f"filter soak: {r['increments']:,} of {r['increments_requested']:,} odometry increments, "
             f"{r['frames_fused']:,} frames fused and {r['frames_refused']:,} refused whole, {r['targets']} targets, "
             f"seed {r['seed']}, {r['wall_s']:.0f} s" + (" (INTERRUPTED)" if r["interrupted"] else ""),
             "frames: " + ", ".join(f"{k} {n:,}" for k, n in r["frame_kinds"].items()),
             "bogus odometry: " + ", ".join(f"{k} {n:,}" for k, n in r["odometry_garbage"].items())
             + f"; contact steps {r['contact_steps']:,}",
             f"P: largest eigenvalue {r['P_max_eigenvalue']:.4g}, smallest {r['P_min_eigenvalue'] or math.nan:.3g}, "
             f"largest relative asymmetry {r['P_max_asymmetry']:.2g}; largest position sigma "
             f"{r['max_position_sigma_m']:.4g} m, heading sigma {r['max_heading_sigma_rad']:.3g} rad",
             f"tracking: {r['frames_tracking']:,} frames, largest position error {r['max_error_tracking_m']:.3f} m "
             f"(frame {r['max_error_tracking_frame']}), heading {r['max_heading_error_tracking_rad']:.4f} rad, "
             f"{r['frames_beyond_3_sigma']:,} frames beyond 3 sigma; mean NIS {r['mean_nis'] or math.nan:.2f} over "
             f"{r['accepted_updates']:,} updates",
             f"lost: {r['lost_events']:,} times; kidnaps told {r['kidnaps_told']}, silent {r['kidnaps_silent']} "
             f"(found {r['silent_found']}, at most {r['max_frames_to_find']} frames, error before "
             f"{r['max_error_before_found_m']:.1f} m); relocalizations {r['relocalizations']:,}, "
             f"largest error {r['max_relocalization_error_m']:.3f} m, wrong {r['wrong_relocalizations']}",
             "refusals (the filter's counts): " + ", ".join(f"{k} {n:,}" for k, n in r["refusals"].items())]
    for c in r["wrong_cases"]:
        lines.append(f"  wrong relocalization at step {c['step']}: {c['error_m']:.2f} m off, sigma {c['sigma_m']:.3f} m")
    for c in r["crash_cases"]:
        lines.append(f"  crash {c['where']}: {c['error']} {c['message']}")
    fl = r["floors"]
    lines += [floor_line("P not finite (frames)", fl["P_not_finite"], "d"),
              floor_line("P not symmetric (frames)", fl["P_not_symmetric"], "d"),
              floor_line("P not positive definite (frames)", fl["P_not_positive_definite"], "d"),
              floor_line("position sigma", fl["max_position_sigma"], ".4g"),
              floor_line("wrong confirmed relocalizations", fl["wrong_relocalizations"], "d"),
              floor_line("refusals not counted (or bogus input accepted)", fl["uncounted_refusals"], "d"),
              floor_line("refused calls that changed the state", fl["half_applied"], "d"),
              floor_line("crashes", fl["crashes"], "d"),
              floor_line("relocalizations miscounted", fl["relocalizations_counted"], "d")]
    return "\n".join(lines)
