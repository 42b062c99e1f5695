"""Hostile map files: each refused quickly, in little memory, with one line naming the file."""
from __future__ import annotations

import random
import time
import tracemalloc
import warnings

import numpy as np
import pytest

from agvsim.world import MapError, load_map
from agvsim.world import yamlread

WALL = "{id: w, points: [[0, 0], [4, 0]], thickness: 0.2}"


def _refused(tmp_path, text: str | bytes, name: str = "bad.yaml", seconds: float = 10.0) -> MapError:
    """Load the file; it must fail within ``seconds`` and 100 MB, with a one-line message naming it."""
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    tracemalloc.start()
    start = time.perf_counter()
    try:
        with pytest.raises(MapError) as err:
            load_map(path)
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    # a guard against runaway work (the alias bomb took minutes and gigabytes), not the speed
    # floor: the seconds on an idle machine (0.45-0.6 s against 1 s) are BENCHMARKS.md's
    assert time.perf_counter() - start < seconds
    assert peak < 100e6
    message = str(err.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and len(message) < 600
    return err.value


def _bomb(levels: int = 9) -> str:
    """A flow list of anchored lists, each holding 9 aliases of the one before: 9**levels strings."""
    items = ["&a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    items += [f"&a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, levels)]
    return f"[{', '.join(items)}]"


@pytest.mark.parametrize("field", ["name", "description"])
def test_alias_bomb_is_refused_quickly(tmp_path, field):
    text = f"walls: [{WALL}]\n{field}: {_bomb()}\n"
    assert len(text) < 600
    err = _refused(tmp_path, text)
    assert "aliases expand to more than" in str(err) and "line 2" in str(err)


def test_small_aliases_and_merge_keys_are_supported(tmp_path):
    path = tmp_path / "merge.yaml"
    path.write_text("walls:\n"
                    "  - &base {id: a, points: [[0, 0], [4, 0]], thickness: 0.3, height: 2.5}\n"
                    "  - {<<: *base, id: b, points: [[0, 5], [4, 5]]}\n"
                    "  - {<<: [{surface: door}, *base], id: c, points: &p [[9, 0], [9, 4]], thickness: 0.1}\n")
    floor = load_map(path)
    b, c = floor.wall("b"), floor.wall("c")
    assert (b.thickness, b.height) == (0.3, 2.5)
    assert (c.thickness, c.height, c.surface) == (0.1, 2.5, "door")


def test_duplicate_key_next_to_a_merge_key_is_still_refused(tmp_path):
    err = _refused(tmp_path, f"walls:\n  - &w {WALL}\n  - {{<<: *w, id: v, id: u}}\n")
    assert "duplicate key" in str(err) and "line 3" in str(err)


@pytest.mark.parametrize("text", [
    "walls: " + "[" * 5000 + "]" * 5000 + "\n",
    "walls: " + "[" * 200 + "]" * 200 + "\n",
    "walls:\n" + "".join("  " * i + "-\n" for i in range(300)),
    "walls:\n" + "".join("  " * i + f"k{i}:\n" for i in range(1, 300)),
])
def test_deep_nesting_is_refused(tmp_path, text):
    err = _refused(tmp_path, text)
    assert "nest" in str(err) and "line " in str(err)


def test_recursive_alias_is_refused(tmp_path):
    assert "contains it" in str(_refused(tmp_path, f"walls: &w [{WALL}, *w]\n"))


def test_huge_integer_names_the_field(tmp_path):
    err = _refused(tmp_path, "walls: [{id: w, points: [[0, 0], [1" + "0" * 400 + ", 0]], thickness: 0.2}]\n")
    assert err.path == "walls[0].points[1][0]" and "out of range" in str(err)
    assert "about 401 digits" in str(err)
    err = _refused(tmp_path, "walls: [{id: w, points: [[0, 0], [1" + "0" * 3000 + ", 0]], thickness: 0.2}]\n")
    assert "line 1" in str(err) and "characters" in str(err)


@pytest.mark.parametrize("data, problem", [
    ("walls: []\n".encode("utf-16"), "UTF-16"),
    (b"\x1f\x84\x00\x01\x02" * 10, "byte 0x84 at offset 1"),
    (b"walls: [\x00]\n", "not a text file"),
])
def test_binary_or_utf16_file_is_named(tmp_path, data, problem):
    assert problem in str(_refused(tmp_path, data))


def test_world_far_from_the_origin_is_refused(tmp_path):
    err = _refused(tmp_path, "walls: [{id: w, points: [[0, 0], [1e12, 0]], thickness: 0.2}]\n")
    assert err.path == "walls[0].points[1][0]" and "10000" in str(err)
    err = _refused(tmp_path, "walls: [{id: w, points: [[0, 0], [9999, 0]], thickness: 5}]\n")
    assert err.path == "walls[0]" and "10000" in str(err)


def test_huge_coordinates_print_no_numpy_warnings(tmp_path):
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        err = _refused(tmp_path, "walls: [{id: w, points: [[0, 0], [1e300, -1e300]], thickness: 0.2}]\n")
    assert err.path == "walls[0].points[1][0]"


def test_file_over_the_size_limit_is_refused_before_parsing(tmp_path, monkeypatch):
    monkeypatch.setattr(yamlread, "MAX_MAP_BYTES", 1000)
    err = _refused(tmp_path, f"walls: [{WALL}]\n# " + "x" * 2000 + "\n")
    assert "file too large" in str(err) and "1000 bytes" in str(err)


def test_huge_values_are_shown_short(tmp_path):
    big = ", ".join(["lol"] * 10_000)
    err = _refused(tmp_path, f"walls: [{WALL}]\nname: [{big}]\n")
    assert err.path == "name" and len(str(err)) < 400


def test_second_document_and_odd_tags_are_refused(tmp_path):
    assert "second YAML document" in str(_refused(tmp_path, f"walls: [{WALL}]\n---\nwalls: []\n"))
    assert "unsupported tag" in str(_refused(tmp_path, f"walls: [{WALL}]\nname: !!python/name:os.system x\n"))


def test_pure_python_parser_refuses_the_same_files(tmp_path, monkeypatch):
    import yaml

    monkeypatch.setattr(yamlread, "_PARSER", yaml.SafeLoader)
    # (the pure-Python parser is about 20x slower: 5 s here, not 1 s)
    assert "nested more than" in str(_refused(tmp_path, "walls: " + "[" * 5000 + "]" * 5000 + "\n", seconds=5))
    assert "aliases expand" in str(_refused(tmp_path, f"walls: [{WALL}]\nname: {_bomb()}\n", seconds=5))


def _walls_map(path, size: int) -> int:
    rng = random.Random(1)
    lines, total = ["walls:"], 0
    while total < size:
        x, y = round(rng.uniform(-900, 900), 3), round(rng.uniform(-900, 900), 3)
        lines.append(f"  - {{id: w{len(lines)}, points: [[{x}, {y}], [{x + 1.5}, {y + 0.25}]], thickness: 0.2}}")
        total += len(lines[-1]) + 1
    path.write_text("\n".join(lines) + "\n")
    return len(lines) - 1


def _load_seconds(path, walls: int) -> float:
    """Seconds to load the map at ``path``, which must have ``walls`` walls."""
    start = time.perf_counter()
    m = load_map(path)
    seconds = time.perf_counter() - start
    assert len(m.walls) == walls
    return seconds


@pytest.mark.slow
def test_a_map_of_walls_loads_in_time_linear_in_its_size(tmp_path):
    """50 KB, 500 KB and 5 MB of walls: each ten times larger loads in about ten times the time
    (quadratic work would be a hundred; the seconds themselves are a benchmark's: BENCHMARKS.md,
    4.3-4.9 s for the 5 MB map on an idle 2-core machine)."""
    sizes = (50_000, 500_000, 5_000_000)
    counts = [_walls_map(tmp_path / f"walls{k}.yaml", size) for k, size in enumerate(sizes)]
    seconds = [min(_load_seconds(tmp_path / f"walls{k}.yaml", n) for _ in range(2 if k < 2 else 1))
               for k, n in enumerate(counts)]
    assert seconds[1] < 30 * seconds[0] and seconds[2] < 30 * seconds[1], seconds


def test_plain_numbers_read_as_the_resolvers_read_them(monkeypatch):
    """The reader's fast path for plain decimal numbers gives what YAML 1.1's resolvers give
    (ints, floats, octal 010 and -010, 1_000, 0x1F, sexagesimal, .5, inf, huge ints)."""
    from agvsim.world import yamlread

    vals = ["1", "-1", "+1", "0", "-0", "010", "-010", "1.5", "-0.5", "10.", "1e3", "-1e-3", "1.5e3", "1_000", "0x1F",
            "1:20", ".5", "+.5", "-.inf", "12345678901234567890", "-7.250", "3.0E+2", "+12.5"]
    text = "\n".join(f"k{i}: {v}" for i, v in enumerate(vals))
    fast = yamlread.read_yaml(text)
    monkeypatch.setattr(yamlread, "_NUMBER_FIRST", frozenset())  # every scalar through the resolvers
    slow = yamlread.read_yaml(text)
    assert [(type(fast[k]), repr(fast[k])) for k in fast] == [(type(slow[k]), repr(slow[k])) for k in slow]
    assert fast["k5"] == 8 and fast["k6"] == -8 and isinstance(fast["k10"], float)
