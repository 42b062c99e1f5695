"""A sweep end to end on the local pool: the example spec's table, summary and plots; the
figures follow the axes; every run is written the moment it ends and the same command skips
it; a failed run is recorded with its error, the sweep goes on and the next invocation runs
it again; ``report`` redraws from the rows; CSV on request."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.csv as pcsv
import pyarrow.parquet as pq
import pytest

from agvsim.cli import main
from agvsim.sweep.folder import read_rows

EXAMPLE = Path(__file__).parents[2] / "examples" / "sweep_small.yaml"


def _sweep(capsys, *args) -> tuple[int, dict]:
    code = main(["sweep", *map(str, args), "--no-progress", "--json"])
    out = capsys.readouterr().out
    return code, json.loads(out) if out.strip() else {}


@pytest.mark.slow
def test_example_spec_gives_table_summary_and_plots(tmp_path, capsys):
    out = tmp_path / "small"
    code, result = _sweep(capsys, EXAMPLE, "--out", out, "--workers", 2)
    assert code == 0
    assert {k: result[k] for k in ("points", "finished", "failed", "skipped")} == \
        {"points": 6, "finished": 12, "failed": 0, "skipped": 0}
    table = pq.read_table(result["results"]).to_pydict()
    assert table["point"] == [p for p in range(6) for _ in range(2)] and table["seed"] == [0, 1] * 6
    assert set(table["status"]) == {"ok"} and all(d > 95.0 for d in table["distance_m"])
    rmse = np.array(table["position_rmse_m"])
    worn = np.array(table["odometry"]) == "worn"
    assert rmse[worn].mean() > rmse[~worn].mean()  # worn odometry drifts more between targets
    full, half = np.array(table["targets_removed"]) == 0.0, np.array(table["targets_removed"]) == 0.5
    assert rmse[half].mean() > rmse[full].mean()  # half the targets: longer blind stretches
    summary = pq.read_table(result["summary"]).to_pydict()
    assert summary["point"] == list(range(6)) and summary["seeds"] == [2] * 6
    np.testing.assert_allclose(summary["position_rmse_m_mean"], rmse.reshape(6, 2).mean(axis=1))
    np.testing.assert_allclose(summary["position_max_m_max"], np.array(table["position_max_m"]).reshape(6, 2).max(1))
    meta = json.loads(pq.read_schema(result["results"]).metadata[b"agvsim.sweep"])
    assert meta["spec"]["grid"]["odometry"] == ["typical", "worn"] and meta["software"]["agvsim"]
    assert sorted(Path(p).name for p in result["plots"]) == ["odometry.png", "targets_removed.png"]
    assert all(Path(p).stat().st_size > 20_000 for p in result["plots"])
    assert (out / "spec.yaml").read_text() == EXAMPLE.read_text()

    # the same command again: every run skipped, nothing run; the rows untouched
    stamps = {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir()}
    code, again = _sweep(capsys, EXAMPLE, "--out", out, "--workers", 2)
    assert code == 0 and (again["finished"], again["skipped"]) == (0, 12)
    assert stamps == {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir()}

    # report redraws from the rows, here as CSV
    assert main(["sweep", "report", str(out), "--format", "csv", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    csv = pcsv.read_csv(report["results"]).to_pydict()
    np.testing.assert_array_equal(csv["position_rmse_m"], rmse)


def test_a_failed_run_is_recorded_and_run_again_next_time(tmp_path, capsys, monkeypatch):
    spec = tmp_path / "spec.yaml"
    spec.write_text("base: {distance: 15, observations: geometric}\ngrid: {odometry: [typical, worn]}\nseeds: 2\n")
    import agvsim.loop.drive as drive

    real = drive.drive_seed

    def flaky(settings, seed, progress=None, world_map=None):
        if settings.odometry == "worn" and seed == 1:
            raise RuntimeError("the disk is full")
        return real(settings, seed, progress, world_map)

    monkeypatch.setattr(drive, "drive_seed", flaky)  # (one worker: the runs run in this process)
    code, result = _sweep(capsys, spec, "--out", tmp_path / "o", "--workers", 1)
    assert code == 1 and (result["finished"], result["failed"]) == (3, 1)
    rows = read_rows(tmp_path / "o")
    assert rows["p0001_s0001"]["status"] == "failed"
    assert rows["p0001_s0001"]["error"] == "RuntimeError: the disk is full"
    table = pq.read_table(result["results"]).to_pydict()
    assert table["status"] == ["ok", "ok", "ok", "failed"] and np.isnan(table["position_rmse_m"][3])
    assert pq.read_table(result["summary"]).to_pydict()["failed"] == [0, 1]

    monkeypatch.setattr(drive, "drive_seed", real)
    code, result = _sweep(capsys, spec, "--out", tmp_path / "o", "--workers", 1)
    assert code == 0 and (result["finished"], result["failed"], result["skipped"]) == (1, 0, 3)
    assert read_rows(tmp_path / "o")["p0001_s0001"]["status"] == "ok"


def test_another_spec_in_the_same_folder_is_refused(tmp_path, capsys):
    spec = tmp_path / "spec.yaml"
    spec.write_text("base: {distance: 10, observations: geometric}\ngrid: {odometry: [typical]}\nseeds: 1\n")
    assert _sweep(capsys, spec, "--out", tmp_path / "o", "--workers", 1, "--no-plots")[0] == 0
    spec.write_text("base: {distance: 12, observations: geometric}\ngrid: {odometry: [typical]}\nseeds: 1\n")
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o")]) == 2
    assert "holds a sweep of another spec; use --restart" in capsys.readouterr().err
    assert len(read_rows(tmp_path / "o")) == 1  # nothing lost
    code, result = _sweep(capsys, spec, "--out", tmp_path / "o", "--workers", 1, "--no-plots", "--restart")
    assert code == 0 and result["finished"] == 1
    assert read_rows(tmp_path / "o")["p0000_s0000"]["distance_m"] > 11.0
