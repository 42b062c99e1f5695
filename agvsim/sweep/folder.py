"""A sweep's results folder: the spec beside the rows, each run written the moment it ends.

``agvsim sweep SPEC --out DIR`` keeps, in ``DIR``:

* ``sweep.json``: what makes the sweep this sweep (base, points, seeds), the spec as read, the
  software's version; ``spec.yaml``: the spec file as given. Written first.
* ``runs/pNNNN_sNNNN.json``: one run's row (:func:`agvsim.sweep.runs.run_unit`), written
  atomically when it ends (:func:`agvsim.files.atomic_write`): a kill at any
  moment leaves no half-written file. A run whose row is there with status ``ok`` is finished
  and not run again; a failed run is run again by the next invocation.
* the table, the summary and the plots (:mod:`agvsim.sweep.report`), written at the end and by
  ``agvsim sweep report DIR``.

Another spec in the same folder is refused (nothing written before is lost) unless
``restart``, which deletes the old runs and outputs first.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

from agvsim.files import atomic_write, read_record, write_json

__all__ = ["SweepFolder", "read_rows", "software_version"]


def software_version() -> dict:
    """``{"agvsim": version, "commit": git commit or None}`` of the running code."""
    import subprocess
    from importlib import metadata

    try:
        version = metadata.version("agvsim")
    except metadata.PackageNotFoundError:
        version = None
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True,
                                text=True, timeout=5).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"agvsim": version, "commit": commit}


class SweepFolder:
    """The results folder of one sweep (module docstring).

    Args:
        out: the folder.
        spec: the :class:`~agvsim.sweep.spec.SweepSpec`.
        restart: delete an earlier sweep's runs and outputs in ``out`` first.
    Raises:
        ValueError: ``out`` is a file, or holds another sweep and ``restart`` is False.
    """

    RECORD = "sweep.json"

    def __init__(self, out: str | Path, spec, restart: bool = False):
        self.out = Path(out)
        self.runs_dir = self.out / "runs"
        if self.out.exists() and not self.out.is_dir():
            raise ValueError(f"--out {str(self.out)!r}: a file; expected a folder")
        identity = json.loads(json.dumps(spec.identity()))
        before = None if restart else self.read_record(self.out, "--out")
        if before is not None and before.get("identity") != identity:
            raise ValueError(f"--out {str(self.out)!r} holds a sweep of another spec; use --restart to replace it, "
                             "or another --out")
        if restart and self.out.is_dir():
            for name in ("runs", "plots"):
                shutil.rmtree(self.out / name, ignore_errors=True)
            for old in self.out.glob("results.*"):
                old.unlink()
            for old in self.out.glob("summary.*"):
                old.unlink()
        self.runs_dir.mkdir(parents=True, exist_ok=True)
        for stale in self.out.rglob(".tmp-*"):  # an interrupted write's leftovers
            stale.unlink(missing_ok=True)
        with atomic_write(self.out / "spec.yaml") as tmp:
            tmp.write_text(spec.path.read_text())
        self.write_json(self.RECORD, {"identity": identity, "spec": spec.data, "spec_file": str(spec.path),
                                      "software": software_version()})

    @staticmethod
    def read_record(out: str | Path, flag: str) -> dict | None:
        """``out/sweep.json`` as data, None if there is none; ``ValueError`` naming ``flag`` (the
        command's argument that named ``out``) when it is there but cannot be read
        (:func:`agvsim.files.read_record`)."""
        hint = ": use --restart to replace that sweep, or another --out" if flag == "--out" else ""
        return read_record(Path(out) / SweepFolder.RECORD, flag, f"the record of an earlier sweep (a JSON object){hint}")

    def finished(self) -> dict[str, dict]:
        """The runs finished here: ``{key: row}`` of the readable rows with status ``ok``."""
        return {k: r for k, r in read_rows(self.out).items() if r.get("status") == "ok"}

    def save(self, key: str, row: dict) -> None:
        """Write one run's row, atomically."""
        write_json(self.runs_dir / f"{key}.json", row, indent=1)

    def write_json(self, name: str, obj: Any) -> Path:
        """``obj`` as JSON in ``out/name``, atomically."""
        return write_json(self.out / name, obj)


def read_rows(out: str | Path) -> dict[str, dict]:
    """Every readable run row in ``out/runs`` (ok and failed): ``{key: row}``, sorted by key."""
    rows = {}
    for path in sorted((Path(out) / "runs").glob("p*_s*.json")):
        try:
            row = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(row, dict) and "point" in row and "seed" in row:
            rows[path.stem] = row
    return rows
