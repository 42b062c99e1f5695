"""The plant floor as data: walls, obstacles, stations, routes, lighting, targets.

Maps are hand-written YAML files (schema: ``maps/README.md``), read and
checked by :func:`load_map`. Modules, one job each:

- :mod:`agvsim.world.map`: the data model.
- :mod:`agvsim.world.loader`: reading and checking YAML maps (:func:`load_map`).
- :mod:`agvsim.world.fields`: reading YAML values with precise errors (:class:`MapError`).
- :mod:`agvsim.world.checks`: whole-map checks (targets, stations, routes).
- :mod:`agvsim.world.spatial`: clearance and line of sight against walls and obstacles.
- :mod:`agvsim.world.geometry`: plane geometry helpers (pure numpy).
"""
from agvsim.world.loader import MapError, load_map, map_from_dict, maps_dir, shipped_maps
from agvsim.world.map import LightingZone, Map, MapTarget, Obstacle, Station, Wall

__all__ = [
    "LightingZone", "Map", "MapError", "MapTarget", "Obstacle", "Station", "Wall",
    "load_map", "map_from_dict", "maps_dir", "shipped_maps",
]
