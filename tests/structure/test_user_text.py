"""User-facing text (help, docstrings, messages, maps, the README) names no issue-tracker
numbers: ``issue 12``, ``issue-4 renderer``, ``the issue's floors`` mean nothing to a user.
(BENCHMARKS.md keeps its history as written.)"""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TRACKER = re.compile(r"\bissue[ -]?#?\d+|\bthe issue's\b|\(issue\b", re.IGNORECASE)


def _files():
    for pkg in ("agvsim", "envs", "localizer", "maps"):
        for path in sorted((ROOT / pkg).rglob("*")):
            if path.suffix in (".py", ".yaml", ".md"):
                yield path
    yield ROOT / "README.md"


def test_no_issue_numbers_in_user_facing_text():
    hits = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
            for path in _files()
            for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1) if TRACKER.search(line)]
    assert not hits, "\n".join(hits)
