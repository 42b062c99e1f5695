"""No text in the project names an entry of an issue tracker or of a work log.

A reader of the help, a docstring, a comment, a test, a map, the Makefile or a document has
no tracker and no log to look the number up in: a sentence says what it means instead
("the localizer's speed floor", not the number of the ticket that asked for it). Every file
``git ls-files`` lists is scanned, binaries skipped; without git (an unpacked tarball) the
tree is walked instead. BENCHMARKS.md states the present in at most
:data:`MAX_BENCHMARK_LINES` lines; its history is in git.
"""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: a tracker's entries (an issue by its number, the issue as a possessive, a parenthesis opening
#: on the word) and a work log's (a numbered session or stop)
TRACKER = re.compile(
    r"\bissues?[ -]?#?\d+"
    r"|\bthe issue[']s\b"
    r"|[(]issue\b"
    r"|\bsessions? \d+"
    r"|\bstop \d+",
    re.IGNORECASE)
#: folders never scanned when the tree is walked (no git)
SKIP_DIRS = {".git", ".venv", "out", "__pycache__", ".pytest_cache"}
MAX_BENCHMARK_LINES = 400


def _tracked() -> list[Path]:
    """The files git tracks, or, where git or the repository is missing, every file of the tree
    outside :data:`SKIP_DIRS`."""
    try:
        listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], capture_output=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        listed = None
    if listed is not None and listed.returncode == 0 and listed.stdout:
        return [ROOT / name for name in listed.stdout.decode("utf-8", "surrogateescape").split("\0") if name]
    paths = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = sorted(d for d in dirs if d not in SKIP_DIRS and not d.endswith(".egg-info"))
        paths += [Path(folder) / f for f in sorted(files)]
    return paths


def _text(path: Path) -> str | None:
    """The file's text, or None for a binary file (a NUL byte) or one that is gone."""
    try:
        data = path.read_bytes()
    except (FileNotFoundError, IsADirectoryError):
        return None
    if b"\0" in data:
        return None
    return data.decode("utf-8", errors="replace")


def _hits(paths) -> list[str]:
    hits = []
    for path in paths:
        text = _text(path)
        if text is None:
            continue
        hits += [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
                 for n, line in enumerate(text.splitlines(), 1) if TRACKER.search(line)]
    return hits


def test_no_tracker_or_work_log_numbers_in_any_file():
    paths = _tracked()
    names = {p.relative_to(ROOT).as_posix() for p in paths}
    assert {"BENCHMARKS.md", "ARCHITECTURE.md", "README.md", "Makefile", "pyproject.toml"} <= names
    assert any(n.startswith("tests/") for n in names) and any(n.startswith("examples/") for n in names)
    hits = _hits(paths)
    assert not hits, "\n".join(hits)


def test_the_pattern_catches_what_it_is_for():
    # built from pieces, so that this file holds none of them whole
    bad = ["issue " + "14's floor", "the " + "issue's floors", "issue" + "-4 renderer", "(" + "issue owner)",
           "Issue " + "#12", "session " + "41", "sessions " + "38-40", "stop " + "41"]
    assert all(TRACKER.search(text) for text in bad), [t for t in bad if not TRACKER.search(t)]
    good = ["a pytest session", "one GL context per test session", "start_new_session=True",
            "the localizer's speed floor", "greedy rounds", "numba#4807", "a non-issue"]
    assert not any(TRACKER.search(text) for text in good), [t for t in good if TRACKER.search(t)]


def test_binaries_are_skipped(tmp_path):
    (tmp_path / "image.png").write_bytes(b"\x89PNG\r\n\x1a\n\0\0" + ("session " + "41").encode())
    (tmp_path / "notes.txt").write_text("as session " + "41 found\n", encoding="utf-8")
    assert _text(tmp_path / "image.png") is None and _text(tmp_path / "gone.txt") is None
    assert len(TRACKER.findall(_text(tmp_path / "notes.txt"))) == 1


def test_without_git_the_tree_is_walked(monkeypatch):
    def no_git(*args, **kwargs):
        raise FileNotFoundError("git")

    monkeypatch.setattr(subprocess, "run", no_git)
    names = {p.relative_to(ROOT).as_posix() for p in _tracked()}
    assert {"BENCHMARKS.md", "Makefile", "tests/structure/test_user_text.py"} <= names
    assert not any(n.startswith((".git/", ".venv/", "out/")) or "/__pycache__/" in n for n in names)


def test_benchmarks_states_the_present_in_few_lines():
    lines = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_BENCHMARK_LINES, f"BENCHMARKS.md has {len(lines)} lines (at most {MAX_BENCHMARK_LINES})"
