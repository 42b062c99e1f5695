"""Cold start: the compile notice, the kernel cache (also with a read-only package) and
``agvsim warmup``."""
import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

import localizer
from agvsim.commands import warmup

ROOT = Path(__file__).resolve().parents[2]
PROBE = "import numpy as np; from localizer.smallmat import inverse; print(inverse(np.eye(3) * 2.0)[0, 0])"


def _python(code: str, env: dict, *flags: str) -> subprocess.CompletedProcess:
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_CACHE_DIR", "AGVSIM_QUIET"))}
    return subprocess.run([sys.executable, *flags, "-c", code], env={**clean, **env}, capture_output=True,
                          text=True, timeout=120, cwd=env.get("XDG_CACHE_HOME", ROOT))


def test_first_compilation_says_so_once_and_the_second_process_loads_the_cache(tmp_path):
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(ROOT)}
    first = _python(PROBE + "; from localizer.smallmat import solve; solve(np.eye(2), np.ones(2))", env)
    assert first.returncode == 0, first.stderr
    from localizer._jit import COMPILE_NOTICE

    assert first.stderr.strip() == COMPILE_NOTICE  # one line, for two kernels compiled
    assert first.stdout.strip() == "0.5"
    second = _python(PROBE, env)
    assert second.returncode == 0 and second.stdout.strip() == "0.5"
    assert second.stderr == ""  # loaded from the cache: nothing compiled, nothing said
    quiet = _python(PROBE, {**env, "NUMBA_CACHE_DIR": str(tmp_path / "other"), "AGVSIM_QUIET_COMPILE": "1"})
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_kernels_are_cached_when_the_package_directory_cannot_be_written(tmp_path):
    site = tmp_path / "site"
    shutil.copytree(Path(localizer.__file__).parent, site / "localizer",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for folder in [site / "localizer", *(p for p in (site / "localizer").rglob("*") if p.is_dir())]:
        # as for a user who cannot write there (root can: a file where numba's cache folder goes)
        (folder / "__pycache__").write_text("")
    for path in sorted(site.rglob("*"), reverse=True):
        path.chmod(0o555 if path.is_dir() else 0o444)
    # -S: no site hooks (the editable install's finder would import this checkout's localizer)
    env = {"PYTHONPATH": os.pathsep.join([str(site), sysconfig.get_paths()["purelib"]]),
           "XDG_CACHE_HOME": str(tmp_path / "home-cache")}
    (tmp_path / "home-cache").mkdir()
    try:
        first = _python(PROBE + "; import localizer; print(localizer.__file__)", env, "-S")
        assert first.returncode == 0, first.stderr
        assert str(site) in first.stdout  # (the read-only copy ran)
        cached = list((tmp_path / "home-cache" / "numba").rglob("*.nbi"))
        assert cached, "no kernel cached in the user's cache directory"
        second = _python(PROBE, env, "-S")
        assert second.returncode == 0 and second.stderr == ""  # loaded from there
    finally:
        for path in site.rglob("*"):
            path.chmod(0o755)
        site.chmod(0o755)


def test_the_parts_name_every_kernel_family_and_resolve():
    import importlib

    names = warmup.parts()
    assert {"raycaster", "detector", "thesis"} <= set(names)
    for spec in names.values():
        module, function = spec.split(":")
        assert callable(getattr(importlib.import_module(module), function))


@pytest.mark.slow
def test_warmup_compiles_on_parallel_workers_then_only_loads(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))  # (the spawned workers read it)
    monkeypatch.setattr(warmup, "parts", lambda: {"inverse": "tests.cli.warmup_parts:inverse",
                                                  "solve": "tests.cli.warmup_parts:solve"})
    from agvsim.cli import main

    runs = []
    for _ in range(2):
        assert main(["warmup", "--jobs", "2", "--json"]) == 0
        out, err = capsys.readouterr()
        runs.append(json.loads(out))
        assert "2 parts (inverse, solve) on 2 processes" in err
    first, second = runs
    assert set(first["parts"]) == {"inverse", "solve"} and first["jobs"] == 2
    assert all(part["compiled"] >= 1 for part in first["parts"].values())
    assert second["compiled"] == 0  # every kernel from the cache the first run wrote


def test_a_part_that_calls_another_parts_kernels_starts_after_it():
    from localizer.warmup import AFTER

    names = list(warmup.parts())
    index = {name: i for i, name in enumerate(names)}
    assert AFTER and set(AFTER) <= set(names)
    order = warmup.waits(names)
    for name, before in AFTER.items():
        assert order[index[name]] == {index[b] for b in before}
        assert all(index[b] < index[name] for b in before)
    assert order[index["raycaster"]] == set()
    assert warmup.waits(["thesis"]) == [set()]  # (a part not run is not waited for)


def test_a_unit_never_waits_for_a_later_one():
    from agvsim.commands.workers import run_after

    with pytest.raises(ValueError):
        run_after(lambda args: (), [{}, {}], [{1}, set()], 2, lambda: None)
