"""The mount scan behind each map's recommended camera mount (and ``agvsim map mounts``)."""
from __future__ import annotations

import json
import math

import pytest

from agvsim.analysis.mount_scan import candidate_mounts, scan_mounts
from agvsim.cli import main
from agvsim.world import load_map
from localizer.model.mount import CameraMount


@pytest.fixture(scope="module")
def corridor():
    return load_map("corridor")


def test_the_corridors_mount_is_among_the_best_of_the_scan(corridor):
    yaws = [math.radians(d) for d in range(-90, 91, 10)]
    ranked = scan_mounts(corridor, candidate_mounts(yaws, (-0.3, 0.0, 0.3)), step=0.5)
    assert [r.longest_gap for r in ranked] == sorted(r.longest_gap for r in ranked)
    mine = scan_mounts(corridor, [corridor.camera_mount], step=0.5)[0]
    assert mine.longest_gap <= ranked[0].longest_gap + 0.5
    forward = scan_mounts(corridor, [CameraMount.forward_looking()], step=0.5)[0]
    plant = scan_mounts(corridor, [load_map("plant_floor").camera_mount], step=0.5)[0]
    assert mine.longest_gap < 0.5 * forward.longest_gap and mine.coverage > 3 * plant.coverage


def test_map_mounts_cli(capsys):
    assert main(["map", "mounts", "corridor", "--step", "1.0", "--top", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["ranked"]) == 3 and out["recommended"]["mount"]["yaw"] == pytest.approx(math.radians(30.0))
    with pytest.raises(SystemExit) as info:  # argparse: one line naming --step, exit status 2
        main(["map", "mounts", "corridor", "--step", "0"])
    assert info.value.code == 2
    assert "--step: expected a finite number > 0 (m), got '0'" in capsys.readouterr().err
