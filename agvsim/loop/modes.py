"""The loop's choice lists, defined once (CLI choices, env validation and docs read them).

Light on purpose: no NumPy, so ``agvsim --help`` can list them.
"""
from __future__ import annotations

__all__ = ["LOCALIZATION_MODES", "STEER_ON"]

#: Pose the agent (or follower) is given: ``ekf`` the filter's estimate (dead reckoning
#: corrected by the camera), ``odometry`` dead reckoning with its motion-model covariance,
#: ``truth`` the true pose (covariance zero).
LOCALIZATION_MODES: tuple[str, ...] = ("ekf", "odometry", "truth")

#: Pose the mission's path follower steers on: the filter's ``estimate`` (a real AGV)
#: or the ``truth`` (the world-only demo; errors then do not feed back into the path).
STEER_ON: tuple[str, ...] = ("estimate", "truth")
