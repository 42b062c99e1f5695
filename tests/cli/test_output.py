"""JSON output: measurements print as the numbers they are (no binary noise such as
40.400000000000006), without losing real precision."""
from __future__ import annotations

import json
import math

import numpy as np

from agvsim.commands._output import clean_json, plural


def test_floats_are_rounded_to_twelve_significant_digits():
    assert clean_json({"size": [40.2 - (-0.2), 0.1 + 0.2]}) == {"size": [40.4, 0.3]}
    assert clean_json(np.float64(1.2345678901234567e-7)) == 1.23456789012e-7  # small values keep their digits
    assert clean_json(123456.78901234) == 123456.789012
    assert clean_json([math.nan, math.inf, 3, True, "x"]) == [None, None, 3, True, "x"]
    assert json.dumps(clean_json(np.array([1 / 3]))) == "[0.333333333333]"


def test_map_check_json_prints_the_corridors_size(capsys):
    from agvsim.cli import main

    assert main(["map", "check", "corridor", "--json"]) == 0
    out = capsys.readouterr().out
    assert json.loads(out)["size"] == [40.4, 3.6] and "40.400000000000006" not in out


def test_plural():
    assert plural(1, "seed") == "1 seed" and plural(2, "seed") == "2 seeds" and plural(0, "worker") == "0 workers"
    assert plural(3, "frame", "frames") == "3 frames"
