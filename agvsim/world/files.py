"""Where map files are: the shipped maps folder and name-or-path resolution."""
from __future__ import annotations

import difflib
import os
import sys
from pathlib import Path

__all__ = ["MAP_SUFFIXES", "maps_dir", "resolve_map_path", "shipped_maps"]

MAP_SUFFIXES: tuple[str, ...] = (".yaml", ".yml")


def maps_dir() -> Path:
    """The folder of shipped maps: ``$AGVSIM_MAPS_DIR`` if set, else the repo's
    ``maps/`` (editable install), else ``<prefix>/share/agvsim/maps`` (wheel)."""
    override = os.environ.get("AGVSIM_MAPS_DIR")
    if override:
        return Path(override)
    repo = Path(__file__).resolve().parents[2] / "maps"
    if repo.is_dir():
        return repo
    # a non-editable install ships the maps as data files under the prefix
    return Path(sys.prefix) / "share" / "agvsim" / "maps"


def shipped_maps() -> list[str]:
    """Names of the maps in :func:`maps_dir`, sorted."""
    folder = maps_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.iterdir() if p.suffix in MAP_SUFFIXES and p.is_file())


def resolve_map_path(name_or_path: str | os.PathLike) -> Path:
    """A shipped map name (``"corridor"``) or a path -> the file's path.

    Anything with a directory part or a ``.yaml``/``.yml`` suffix is a path.

    Raises:
        FileNotFoundError: no such file or shipped map.
    """
    text = os.fspath(name_or_path)
    looks_like_path = (isinstance(name_or_path, os.PathLike) or os.sep in text or "/" in text
                       or text.endswith(MAP_SUFFIXES))
    if looks_like_path:
        path = Path(text)
        if path.is_file():
            return path
        shipped = maps_dir() / path.name
        if path.name == text and shipped.is_file():  # "corridor.yaml" from any directory
            return shipped
        raise FileNotFoundError(f"no map file {text!r}")
    for suffix in MAP_SUFFIXES:
        candidate = maps_dir() / f"{text}{suffix}"
        if candidate.is_file():
            return candidate
    names = tuple(shipped_maps())
    close = difflib.get_close_matches(text, names, n=1)
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise FileNotFoundError(f"no shipped map {text!r} in {maps_dir()} ({hint}shipped: {', '.join(names) or 'none found'}; "
                            "or give a path to a .yaml file)")
