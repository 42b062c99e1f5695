"""The example scripts run, with small arguments, and say something true."""
import importlib.util
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_odometry_drift_orders_the_presets(capsys):
    results = load("odometry_drift").main("corridor", laps=1.0, seeds=2)
    assert results["ideal"] < 1e-3
    assert results["ideal"] < results["typical"] < results["worn"]
    assert "typical" in capsys.readouterr().out


def test_random_agent_runs_and_reports(capsys):
    result = load("random_agent").main("agvsim/Corridor-v2", steps=40, localization="odometry")
    assert result["episodes"] >= 1
    assert result["final_position_error_m"] >= 0.0
    assert "random steps" in capsys.readouterr().out


def test_pure_pursuit_planner_reaches_the_goal_on_the_ekf_estimate():
    result = load("pure_pursuit_planner").main("agvsim/Corridor-v2", seed=0, localization="ekf",
                                               observations="geometric")
    assert result["path_length_m"] > 30
    assert result["reached"] and result["collisions"] == 0
    assert result["final_position_error_m"] < 0.05


def test_drift_through_env_ekf_beats_dead_reckoning(capsys):
    table = load("drift_through_env").main("agvsim/PlantFloor-v2", episodes=1, odometry="worn",
                                           observations="geometric")
    assert table["ekf"]["reached"] == 1.0
    assert table["ekf"]["final_position_error_m"] < table["odometry"]["final_position_error_m"]
    assert "goals reached" in capsys.readouterr().out
