"""The README's Python example runs as written, with nothing but ``import agvsim``."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


@pytest.mark.slow
def test_readme_agvsim_example_runs(capsys):
    block = next(b for b in _python_blocks() if "agvsim.run_mission" in b)
    assert "from agvsim." not in block  # no deep imports
    exec(compile(block, str(README), "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert "m after" in out[0] and "worst estimate error" in out[1]
    assert float(out[1].split()[0]) < 0.5
