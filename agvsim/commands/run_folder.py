"""A folder of per-seed results that survives interruption: atomic writes, resume, restart.

``agvsim drift --out DIR`` keeps, in ``DIR``:

* ``run.json``: the run's settings (what makes two runs the same run), written first;
* ``seeds/seed_NNN.json`` and ``seeds/seed_NNN.npz``: one seed's figures and per-step arrays,
  each written the moment the seed finishes;
* the summary, plots and ``drift.json`` at the end.

Every file is written to a temporary name in the same folder and renamed over its final name
(:func:`atomic_write`): a kill at any moment leaves either the old file, the new file or a
temporary one (ignored and cleaned up), never a half-written file under a final name.
Running the same command again resumes: the seeds whose two files are there and readable are
loaded, not computed again. Other settings in the same folder are refused (nothing written
before is lost) unless ``restart`` is given, which deletes the old seeds first.
"""
from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from agvsim.files import TMP_PREFIX as _TMP_PREFIX, atomic_write, read_record, write_json

__all__ = ["RunFolder", "atomic_write"]


class RunFolder:
    """The output folder of one run over seeds (module docstring).

    Args:
        out: the folder.
        settings: JSON-ready dict of what defines the run (a resumed run must have the same).
        restart: start over: delete the seeds of an earlier run in ``out``.
    Raises:
        ValueError: ``out`` holds a run with other settings and ``restart`` is False.
    """

    def __init__(self, out: str | os.PathLike, settings: dict[str, Any], restart: bool = False):
        self.out = Path(out)
        self.seeds_dir = self.out / "seeds"
        self.settings = json.loads(json.dumps(settings))  # (as it reads back)
        if self.out.exists() and not self.out.is_dir():
            raise ValueError(f"--out {str(self.out)!r}: a file, expected a folder")
        self.seeds_dir.mkdir(parents=True, exist_ok=True)
        for stale in self.out.rglob(_TMP_PREFIX + "*"):  # an interrupted write's leftovers
            stale.unlink(missing_ok=True)
        before = None if restart else read_record(
            self.out / "run.json", "--out", "the settings of an earlier run (a JSON object): use --restart to "
            "replace that run, or another --out")
        if before is not None and before != self.settings:
            differ = sorted(k for k in set(before) | set(self.settings) if before.get(k) != self.settings.get(k))
            raise ValueError(f"--out {str(self.out)!r} holds a run with other settings ({', '.join(differ)}); "
                             "use --restart to replace it, or another --out")
        if restart:
            for old in list(self.seeds_dir.glob("seed_*")):
                old.unlink()
        self.write_json("run.json", self.settings)

    def _paths(self, seed: int) -> tuple[Path, Path]:
        return self.seeds_dir / f"seed_{seed:03d}.json", self.seeds_dir / f"seed_{seed:03d}.npz"

    def finished(self, seeds: list[int]) -> dict[int, tuple[dict, SimpleNamespace]]:
        """The seeds of ``seeds`` already finished here: ``{seed: (metrics, log)}``, the log a
        namespace of the saved per-step arrays (a seed whose files are missing or unreadable is
        not finished)."""
        done = {}
        for seed in seeds:
            meta, arrays = self._paths(seed)
            if not (meta.is_file() and arrays.is_file()):
                continue
            try:
                metrics = json.loads(meta.read_text(encoding="utf-8"))
                with open(arrays, "rb") as f, np.load(f) as data:  # (closed also when not a zip)
                    log = SimpleNamespace(**{k: data[k] for k in data.files})
            except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
                continue
            if metrics.get("seed") == seed and len(getattr(log, "time", ())) > 0:
                done[seed] = (metrics, log)
        return done

    def save_seed(self, seed: int, metrics: dict, arrays: dict[str, np.ndarray]) -> None:
        """Write one finished seed: its arrays, then its figures (the figures mark it finished)."""
        meta, npz = self._paths(seed)
        with atomic_write(npz) as tmp:
            np.savez_compressed(tmp, **arrays)
        write_json(meta, metrics, indent=1)

    def write_json(self, name: str, obj: Any) -> Path:
        """``obj`` as JSON in ``out/name``, atomically."""
        return write_json(self.out / name, obj)
