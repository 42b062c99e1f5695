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
