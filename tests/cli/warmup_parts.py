"""Two cheap parts for the warmup tests: each compiles one small localizer kernel."""
import numpy as np


def inverse() -> None:
    from localizer.smallmat import inverse as kernel

    kernel(np.eye(3) * 2.0)


def solve() -> None:
    from localizer.smallmat import solve as kernel

    kernel(np.eye(2), np.ones(2))
