"""Observation sources: one registry, one protocol, no probing."""
from __future__ import annotations

import numpy as np
import pytest

from agvsim.sensors import SOURCES, ObservationSource, VisionConfig, make_source, source_class
from agvsim.sensors.registry import SOURCE_HELP
from agvsim.world import load_map


@pytest.fixture(scope="module")
def corridor():
    return load_map("corridor")


def test_every_registered_source_satisfies_the_protocol(corridor):
    assert SOURCES == ("rendered", "synthetic", "geometric")
    assert set(SOURCE_HELP) == set(SOURCES)
    for name in SOURCES:
        src = make_source(name, corridor)  # builds no renderer yet (no GL context)
        assert isinstance(src, ObservationSource)
        assert src.name == name and source_class(name) is type(src)
        assert src.vision.mount == corridor.camera_mount  # the map's recommended mount
        assert src.last_frame is None


def test_unknown_source_is_one_clear_error(corridor):
    with pytest.raises(ValueError, match=r"observation source must be one of rendered, synthetic, geometric; "
                                         r"got 'geometrc' \(did you mean 'geometric'\?\)"):
        make_source("geometrc", corridor)


def test_geometric_source_sees_targets_and_ignores_exposure(corridor):
    src = make_source("geometric", corridor)
    rng = np.random.default_rng(0)
    seen = [src.observe((x, 0.3, 0.0), rng) for x in np.linspace(1.0, 39.0, 40)]
    assert any(seen) and src.draws_frames is False and src.has_exposure is False
    before = src.observe((8.8, 0.3, 0.0), np.random.default_rng(1))
    src.set_exposure(2.0)  # documented no-op
    after = src.observe((8.8, 0.3, 0.0), np.random.default_rng(1))
    assert before and [(o.distance, o.beta, o.alpha) for o in before] == [(o.distance, o.beta, o.alpha) for o in after]


def test_synthetic_source_exposure_changes_the_frame(corridor):
    src = make_source("synthetic", corridor)
    pose = (3.0, 0.3, 0.0)
    src.observe(pose, np.random.default_rng(0))
    nominal = src.last_frame.astype(float)
    src.set_exposure(0.5)
    src.observe(pose, np.random.default_rng(0))
    assert src.last_frame.mean() < 0.8 * nominal.mean()
    with pytest.raises(ValueError, match="exposure must be a finite number > 0"):
        src.set_exposure(0.0)


def test_vision_config_validates_its_fields():
    with pytest.raises(ValueError, match="VisionConfig.focal_mm must be one of 16, 50"):
        VisionConfig(focal_mm=25.0)
    with pytest.raises(ValueError, match="VisionConfig.detector must be one of thesis, exact"):
        VisionConfig(detector="fast")
    with pytest.raises(ValueError, match="VisionConfig.mount must be a localizer.model.mount.CameraMount"):
        VisionConfig(mount=(0.4, 0.0, 1.2, 0.0))
