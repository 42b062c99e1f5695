"""The agvsim command: help, the demo, the sim benchmark, JSON output."""
import json
import subprocess
import sys

import pytest

from agvsim.cli import main


def test_help_lists_the_subcommands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name in ("demo", "map", "localize", "reproduce", "bench"):
        assert name in out


@pytest.mark.parametrize("argv", [["demo", "--help"], ["bench", "--help"], ["bench", "sim", "--help"]])
def test_every_subcommand_has_help(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    assert "usage:" in capsys.readouterr().out


@pytest.mark.render  # the demo saves a rendered camera strip
@pytest.mark.slow
def test_demo_json_reports_drift_and_writes_pictures(tmp_path, capsys):
    code = main(["demo", "--json", "--no-progress", "--out", str(tmp_path), "--seed", "3", "--frames", "2",
                 "--observations", "geometric"])
    assert code == 0
    captured = capsys.readouterr()
    result = json.loads(captured.out)  # exactly one JSON object on stdout
    assert result["completed"] is True
    assert result["collisions"] == 0
    assert result["distance_m"] > 100
    # typical odometry drifts: clearly nonzero, roughly a percent of distance
    assert 0.001 < result["final_error_share_of_distance"] < 0.05
    assert len(result["table"]) == 10
    distances = [row["distance_m"] for row in result["table"]]
    assert distances == sorted(distances)
    assert len(result["camera_frames"]) == 2
    # the camera keeps the estimate within centimetres of the truth; dead reckoning drifts further
    assert result["vision"] is True
    assert result["estimate_rmse_m"] < 0.05
    assert result["final_position_error_m"] > result["final_estimate_error_m"]
    assert all("estimate_error_m" in row for row in result["table"])
    for key in ("topdown", "error_plot", "camera_strip"):
        path = tmp_path / result["files"][key].rsplit("/", 1)[-1]
        assert path.exists() and path.stat().st_size > 1000
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demo_table_output(tmp_path, capsys):
    assert main(["demo", "--no-progress", "--out", str(tmp_path), "--odometry", "ideal", "--frames", "0",
                 "--no-vision"]) == 0
    out = capsys.readouterr().out
    assert "dead reckoning (m)" in out and "Wrote the top-down view" in out
    # ideal odometry: every row of the table shows a zero error at this precision
    rows = [line.split() for line in out.splitlines() if line.strip() and line.strip()[0].isdigit()]
    assert len(rows) == 10
    assert all(float(r[1]) < 0.001 for r in rows)


def test_demo_bad_map_is_a_clear_error(tmp_path, capsys):
    code = main(["demo", "--map", str(tmp_path / "nope.yaml"), "--out", str(tmp_path)])
    assert code == 2
    assert "nope.yaml" in capsys.readouterr().err


def test_bench_sim_json(capsys):
    assert main(["bench", "sim", "--json", "--laps", "0.1", "--repeats", "1"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["physics_steps"] > 0
    # the speed itself (floor 500x real time) is the benchmark's figure, not a test's: only that it is reported
    assert result["real_time_factor"] > 0 and result["floor_real_time_factor"] > 0
    assert result["peer"]["physics_steps_per_second"] > 0
    assert "cpu_count" in result["machine"]


def test_console_script_runs_as_a_module():
    out = subprocess.run([sys.executable, "-m", "agvsim", "--help"], capture_output=True, text=True, check=True)
    assert "demo" in out.stdout


def test_importing_packages_opens_no_gl():
    code = ("import sys, agvsim, localizer, envs, agvsim.cli, agvsim.vehicle.simulation, agvsim.analysis.topdown; "
            "agvsim.cli.build_parser(); "
            "bad = [m for m in sys.modules if m.split('.')[0] in ('pyrender', 'OpenGL')]; "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_importing_the_env_and_filter_stack_imports_no_gl_or_opencv():
    """What an env process imports (memory per env process); the run itself is
    ``tests/envs/test_env_process.py``."""
    code = ("import sys, envs, localizer, localizer.filter, agvsim.sensors.rendered, agvsim.sensors.render.renderer, "
            "agvsim.sensors.render.raycast, agvsim.sensors.render.textures; "
            "bad = sorted({m for m in sys.modules if m.split('.')[0] in ('pyrender', 'OpenGL', 'trimesh', 'cv2', "
            "'matplotlib', 'pandas', 'ray')}); "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_every_option_with_a_default_says_it_in_its_help():
    """``--help`` shows every option's default: an option that has one (not None, not off) names
    it in its help text, and an optional value without one says what happens without it."""
    import argparse

    from agvsim.cli import build_parser

    silent = []

    def walk(parser, name):
        for a in parser._actions:
            if isinstance(a, argparse._SubParsersAction):
                for sub, p in a.choices.items():
                    walk(p, f"{name} {sub}")
            elif (a.option_strings and a.help not in (None, argparse.SUPPRESS) and not a.required
                  and a.nargs != 0 and a.default is not False and "default" not in a.help):
                silent.append(f"{name} {'/'.join(a.option_strings)}")

    walk(build_parser(), "agvsim")
    outputs = {"--out", "--annotate", "--truth", "--save-frames", "--bar-width", "--map", "--address"}
    assert [s for s in silent if s.split()[-1] not in outputs] == []
