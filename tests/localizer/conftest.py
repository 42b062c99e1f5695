import numpy as np
import pytest

from localizer import Camera


@pytest.fixture
def cam16():
    return Camera.thesis(16.0)


@pytest.fixture
def cam50():
    return Camera.thesis(50.0)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
