"""The progress bars of ``demo`` and ``drift``: metres, a rate that reads as one (m/s), and an
end at their total."""
from __future__ import annotations

import re

from agvsim.commands._output import DistanceBar
from agvsim.cli import main


def test_the_rate_is_metres_per_second_even_below_one():
    bar = DistanceBar(186.0, disable=True)
    text = bar.bar.format_meter(n=12.0, total=186.0, elapsed=13.3, bar_format=DistanceBar.FORMAT, unit=" m",
                                prefix="driving")
    assert "12/186 m" in text and "0.90 m/s" in text and "s/m" not in text


def test_the_bar_ends_at_what_was_covered():
    bar = DistanceBar(186.0, disable=True)
    for s in range(182):
        bar.to(s + 0.8)
    assert 180.8 <= bar.n <= 181.8  # redrawn once a metre or more was covered
    bar.finish(181.8)
    assert bar.n == bar.total == 181.8
    drift = DistanceBar(100.0, disable=True)
    drift.add(60.0)
    drift.add(40.0)
    drift.finish()
    assert drift.n == drift.total == 100.0


def test_demo_bar_ends_at_its_total(tmp_path, capsys):
    assert main(["demo", "--route", "receiving_to_m1", "--no-vision", "--frames", "0", "--odometry", "ideal",
                 "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    counts = re.findall(r"(\d+)/(\d+) m \[", captured.err)
    assert counts, captured.err
    n, total = counts[-1]
    assert n == total
    assert "s/m" not in captured.err
    driven = re.search(r"Drove (\d+\.\d) m", captured.out).group(1)
    assert int(total) == round(float(driven))


def test_drift_bar_log_and_a_short_run(tmp_path, capsys):
    """One seed, one worker (said so), a bar that ends at its total, and no ``nan`` arrival error
    on a run too short to reach a station."""
    argv = ["drift", "--map", "corridor", "--observations", "geometric", "--distance", "3", "--seeds", "1",
            "--workers", "1", "--no-plots", "--out", str(tmp_path)]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "x 1 seed," in captured.err and "1 worker" in captured.err and "1 workers" not in captured.err
    n, total = re.findall(r"(\d+)/(\d+) m \[", captured.err)[-1]
    assert n == total == "3" and "s/m" not in captured.err
    assert "nan" not in captured.out and "no station reached" in captured.out


def test_a_long_drift_prints_an_estimate_from_short_drives(monkeypatch):
    """The estimate is timed, not assumed: with drives that cost 0.5 s once, 0.25 s per seed and
    2 ms per metre, 20 seeds of 1000 m on 2 workers come to 0.5 + 10 x (0.25 + 2) = 23 s."""
    import agvsim.commands.drift as drift

    clock = [0.0]
    loaded = [False]

    def fake_job(args):
        clock[0] += (0.0 if loaded[0] else 0.5) + 0.25 + 0.002 * args["distance"]
        loaded[0] = True
        return args["seed"], None

    monkeypatch.setattr(drift, "_job", fake_job)
    monkeypatch.setattr(drift.time, "perf_counter", lambda: clock[0])
    line = drift._estimate({"distance": 1000.0}, list(range(20)), 2)
    assert line.startswith("estimate: about 23 s (2 ms of wall time per metre per worker")
    assert drift._duration(30) == "30 s" and drift._duration(600) == "10 min" and drift._duration(3 * 3600) == "3.0 h"
