"""The filter's limits against what the detector reports at its envelope's edges.

Frames are rendered (``localizer.tools.synthetic``) at far range, grazing angles and small target
images, with the 16 mm and 50 mm lenses; ``detect_targets`` measures them and the filter, whose
state is the truth, fuses the observation of a map target placed where the frame shows it.

- In the localizer's envelope (16 mm 1-10 m, 50 mm 4-20 m, |α| <= 70°, bars >= 5 px wide and
  16 rows tall) a detection is accepted: neither ``MAX_MEASUREMENT_SIGMA`` nor the view
  prediction (``ViewLimits.max_incidence``) refuses it, whatever its σ_α (up to 1.4 rad for
  ``exact`` and 4.4 rad for ``thesis`` on small saturated or far targets).
- Beyond it a detection is used or refused with a counted reason, and never moves the state
  by more than its covariance allows: an EKF update moves the state by ``Δx`` with
  ``Δxᵀ P⁻¹ Δx <= D²`` (the update's NIS), which the χ² gate bounds.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from localizer import Camera, detect_targets
from localizer.filter import ACCEPTED, FilterConfig, GateConfig, PoseEKF, TargetMap, ViewLimits, predict_measurement
from localizer.filter.limits import UNINFORMATIVE
from localizer.filter.measurement import MAX_MEASUREMENT_SIGMA
from localizer.model.geometry import TargetPose
from localizer.model.mount import CameraMount
from localizer.tools.synthetic import in_envelope, pose_at_column, render_frame

MOUNT = CameraMount(forward=0.3, lateral=-0.3, yaw=-math.pi / 2)
X0 = np.array([1.0, 2.0, 0.3])  # the vehicle's true pose, the filter's state
P0 = np.diag([0.02, 0.02, math.radians(0.2)]) ** 2


#: the documented ranges (m) of the lenses
RANGES = {16.0: (1.0, 10.0), 50.0: (4.0, 20.0)}


def documented(cam: Camera, focal: float, pose: TargetPose) -> bool:
    """In the localizer's documented envelope: the lens's range, |α| <= 70° and the image
    criteria of ``in_envelope``."""
    lo, hi = RANGES[focal]
    return lo <= pose.distance <= hi and abs(pose.alpha) <= math.radians(70.0) and in_envelope(cam, pose)


def limits(focal: float, **kw) -> ViewLimits:
    """The lens's view: the default limits with its half angle of view (and ``kw``)."""
    cam = Camera.thesis(focal)
    return ViewLimits(**{"half_fov": math.atan(0.5 * cam.width / cam.fx), "max_range": 22.0, **kw})


def target_at(pose: TargetPose, x=X0, mount=MOUNT) -> TargetMap:
    """One positive target where a camera on the vehicle at ``x`` sees ``pose``."""
    th = float(x[2])
    c = np.array([x[0] + math.cos(th) * mount.forward - math.sin(th) * mount.lateral,
                  x[1] + math.sin(th) * mount.forward + math.cos(th) * mount.lateral])
    phi = th + mount.yaw
    lam = phi - pose.beta
    t = c + pose.distance * np.array([math.cos(lam), math.sin(lam)])
    yaw = phi - pose.alpha - math.pi
    np.testing.assert_allclose(predict_measurement(x, t, yaw, mount),
                               [pose.distance, pose.beta, pose.alpha], atol=1e-12)
    return TargetMap(("T",), t.reshape(1, 2), [yaw], ("positive",))


def detect(focal, d, alpha_deg, col, lighting, method):
    cam = Camera.thesis(focal)
    pose = pose_at_column(cam, d, math.radians(alpha_deg), col)
    img = render_frame(cam, pose, lighting=lighting, noise=2.0, blur=0.5, rng=np.random.default_rng(7))
    return cam, pose, detect_targets(img, cam, method=method)


def fuse(obs, pose, view: ViewLimits, x0=X0, P0=P0):
    """A filter at ``x0`` (the truth: ``X0``) fed the one observation; returns it, the result,
    and the move of the state."""
    ekf = PoseEKF(x0, P0, target_at(pose), MOUNT, FilterConfig(gate=GateConfig(view=view)))
    res = ekf.process_frame(0.0, [obs])
    return ekf, res, ekf.x - x0


def moved_within_covariance(dx, P, nis: float, gate: float) -> None:
    dx = dx.copy()
    dx[2] = math.remainder(dx[2], 2 * math.pi)
    m2 = float(dx @ np.linalg.solve(P, dx))
    assert m2 <= nis * (1 + 1e-9) + 1e-12, (m2, nis)
    assert nis <= gate


# (focal mm, d m, α deg, image column (None: the centre), lighting, method, what makes it extreme)
ENVELOPE = [
    (16.0, 1.0, 70, 49, "normal", "exact"),  # grazing at the image's edge: γ = α - β = 82.6°
    (16.0, 1.0, 70, 49, "normal", "thesis"),
    (16.0, 10.0, 0, None, "normal", "exact"),  # far, frontal
    (16.0, 10.0, -40, None, "saturated", "exact"),  # σ_α 0.99 rad
    (16.0, 8.0, -40, 470, "normal", "thesis"),  # σ_α 0.93 rad, α on its other root
    (50.0, 20.0, 55, 40, "saturated", "exact"),  # σ_α 1.39 rad
    (50.0, 20.0, -60, 40, "saturated", "exact"),  # σ_α 1.18 rad
    (50.0, 18.0, -60, None, "normal", "thesis"),  # σ_α 4.27 rad
    (50.0, 4.0, 70, None, "normal", "exact"),  # near, grazing
    (50.0, 18.0, 65, None, "dim", "exact"),  # far and grazing: a small target image
]


@pytest.mark.parametrize("focal, d, alpha, col, lighting, method", ENVELOPE)
def test_detections_in_the_envelope_are_fused(focal, d, alpha, col, lighting, method):
    cam, pose, obs = detect(focal, d, alpha, col, lighting, method)
    assert documented(cam, focal, pose)
    assert len(obs) == 1
    (o,) = obs
    view = limits(focal)
    ekf, res, dx = fuse(o, pose, view)
    (a,) = res.associations
    assert a.status == ACCEPTED, (a, o.sigma)
    assert ekf.diagnostics()["refusals"] == {}
    assert (o.sigma <= np.array(MAX_MEASUREMENT_SIGMA)).all()
    moved_within_covariance(dx, P0, float(res.nis[0]), GateConfig().gate)


def test_the_envelope_cases_reach_what_the_old_limits_refused():
    """The cases above are the ones that matter: σ_α beyond the old 0.5 rad and incidences
    beyond the old 75°, all in the envelope. (The thesis method's σ_α beyond π, the spread of
    its two roots when the bar heights tied, is gone since it measures the heights to a
    fraction of a pixel: its α is on the right root in these cases; the exact method's small
    saturated targets still reach 1-1.4 rad.)"""
    sig, gamma = [], []
    for focal, d, alpha, col, lighting, method in ENVELOPE:
        _, pose, (o,) = detect(focal, d, alpha, col, lighting, method)
        sig.append(o.sigma[2])
        gamma.append(abs(pose.alpha - pose.beta))
    assert sum(s > 0.5 for s in sig) >= 4 and max(sig) > 1.0
    assert max(gamma) > math.radians(80.0)
    assert GateConfig().view.max_incidence >= math.radians(70.0 + 15.4)


# beyond the envelope: too far, too grazing, too small, the thesis method's other root
#: (the detector finds nothing beyond about 12 m with the 16 mm lens and 35 m with the 50 mm one,
#: where its σ_d is 0.7 m: no real detection reaches MAX_MEASUREMENT_SIGMA's 1 m)
BEYOND = [
    (16.0, 12.0, 45, None, "normal", "exact"),
    (16.0, 12.0, 60, 482, "normal", "thesis"),
    (16.0, 5.0, -78, None, "normal", "thesis"),  # α on its other root
    (16.0, 8.0, 78, 482, "normal", "exact"),
    (50.0, 25.0, 45, None, "normal", "exact"),
    (50.0, 30.0, 45, 482, "saturated", "exact"),
    (50.0, 30.0, 0, None, "dim", "thesis"),
    (50.0, 35.0, 45, None, "saturated", "exact"),
    (50.0, 35.0, 0, None, "normal", "thesis"),
]
#: the filter's prior: the truth, or 0.3 m and 2° off with a covariance that says so
PRIORS = {"truth": (X0, P0),
          "off": (X0 + [0.3, -0.2, math.radians(2.0)], np.diag([0.3, 0.3, math.radians(3.0)]) ** 2)}


@pytest.mark.parametrize("prior", sorted(PRIORS))
@pytest.mark.parametrize("focal, d, alpha, col, lighting, method", BEYOND)
def test_detections_beyond_the_envelope_are_used_honestly_or_refused_and_counted(focal, d, alpha, col, lighting,
                                                                                   method, prior):
    cam, pose, obs = detect(focal, d, alpha, col, lighting, method)
    assert not documented(cam, focal, pose) and len(obs) == 1
    x0, P = PRIORS[prior]
    view = limits(focal, max_range=40.0, max_incidence=math.radians(89.0))
    for o in obs:
        ekf, res, dx = fuse(o, pose, view, x0, P)
        (a,) = res.associations
        d = ekf.diagnostics()
        if a.status == ACCEPTED:
            moved_within_covariance(dx, P, float(res.nis[0]), GateConfig().gate)
            assert d["refusals"] == {} and d["rejections"] == 0
        elif a.status == UNINFORMATIVE:
            assert d["refusals"] == {"measurement_uninformative": 1} and not np.any(dx)
        else:  # gated, ambiguous, no candidate: counted as rejected, the state unmoved
            assert d["rejections"] == 1 and not np.any(dx)
        assert np.isfinite(ekf.P).all() and np.linalg.eigvalsh(ekf.P)[0] > 0


def test_an_alpha_on_its_other_root_does_not_drag_the_heading():
    """The thesis method's α on its other root (1.85 rad off) comes with a σ_α that covers it: the
    observation is fused for its d and β, and the heading stays with the truth.

    The detector now measures the sign of α here; its answer where it cannot (the bar heights
    equal within their noise: ``localizer.thesis.pose``) is made from its detection: the other
    root of eq A.14, its variance widened by the two roots' spread."""
    _, pose, (o,) = detect(16.0, 8.0, -40, 470, "normal", "thesis")
    (other,) = [a for a in o.alpha_candidates if abs(a - o.alpha) > 0.5]
    cov = o.covariance.copy()
    cov[2, 2] += (other - o.alpha) ** 2
    o = dataclasses.replace(o, alpha=other, covariance=cov, alpha_ambiguous=True)
    assert abs(o.alpha - pose.alpha) > 1.5 and o.sigma[2] > 0.9
    P = np.diag([0.1, 0.1, math.radians(3.0)]) ** 2
    x0 = X0 + [0.05, -0.05, math.radians(2.0)]
    ekf, res, dx = fuse(o, pose, limits(16.0), x0, P)
    assert res.accepted == 1
    moved_within_covariance(dx, P, float(res.nis[0]), GateConfig().gate)
    assert abs(math.remainder(ekf.x[2] - X0[2], 2 * math.pi)) < math.radians(2.0)  # towards the truth
