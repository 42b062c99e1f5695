"""Files written whole or not at all, for every layer of :mod:`agvsim`.

:func:`atomic_write` yields a temporary name beside the file (the same suffix, so writers that
go by it still work) and renames it over the file when the block ends without an error: a kill
at any moment leaves the old file, the new one, or a temporary one (``.tmp-*``, which the run
folders clean up), never a half-written file under the final name.
"""
from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

__all__ = ["TMP_PREFIX", "atomic_write", "read_record", "write_json"]

#: the prefix of the temporary names
TMP_PREFIX = ".tmp-"


@contextmanager
def atomic_write(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix) to write; on success it is renamed
    over ``path`` (atomic on POSIX within one file system); on an error it is removed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=TMP_PREFIX + path.stem + "-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_json(path: str | os.PathLike, obj: Any, indent: int = 2) -> Path:
    """``obj`` as JSON (UTF-8) at ``path``, atomically (:func:`atomic_write`); returns the path."""
    path = Path(path)
    with atomic_write(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=indent), encoding="utf-8")
    return path


def read_record(path: str | os.PathLike, flag: str, what: str) -> dict[str, Any] | None:
    """A run folder's record (``run.json``, ``sweep.json``): the JSON object at ``path``, or None
    when there is no such file.

    Raises ``ValueError`` in one line when the file is there but is not a JSON object (cut off,
    not text, unreadable, another type): ``"<flag> '<folder>': its <name> cannot be read (<reason>);
    expected <what>"``, so that the command refuses the folder without touching what it holds.
    """
    path = Path(path)
    if not path.is_file():
        return None
    where = f"{flag} {str(path.parent)!r}: its {path.name}"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        reason = f"cut off or not JSON: {exc}"
    except UnicodeDecodeError:
        reason = "not text"
    except OSError as exc:
        reason = exc.strerror or str(exc)
    else:
        if isinstance(data, dict):
            return data
        reason = f"it holds a {type(data).__name__}, not a JSON object"
    raise ValueError(f"{where} cannot be read ({reason}); expected {what}")
