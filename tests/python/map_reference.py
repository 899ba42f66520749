"""How the reference libraries read map files, as JSON for cpmx's tests.

Lanelet2 maps (``.osm``) are read with the ``lanelet2`` package as a vehicle under
German rules reads them: every lanelet the traffic rules let a vehicle pass, and the
inverse of each that may also be driven backwards (cpmx numbers the inverse of lanelet
``N`` as ``-N-1``), with the orientation Lanelet2 gives its bounds, its successors and
neighbours in the routing graph and the length of its centre line.

Coordinates are lat/lon projected by Lanelet2's ``UtmProjector`` at the south-west
corner of the file's nodes, or the nodes' ``local_x``/``local_y`` tags where the file
has them, as cpmx reads them. Then the map is loaded from a copy whose lat/lon are the
inverse projection of the local coordinates, so that Lanelet2 orients its lanelets in
them, and the points are set to them exactly.

CommonRoad maps (``.xml``) are read with ``commonroad-io``: every lanelet's types and
users, successors, neighbours and centre-line length.

Usage: ``python map_reference.py MAP...``; prints one JSON object keyed by the paths.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import os
import sys
import tempfile
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.etree import ElementTree

if TYPE_CHECKING:
    from lanelet2.core import ConstLanelet
    from lanelet2.projection import UtmProjector
    from lanelet2.routing import RoutingGraph

Entry = dict[str, Any]


def cpmx_id(lanelet: ConstLanelet) -> int:
    """Return the id cpmx gives a lanelet: its own, or ``-id-1`` for its inverse."""
    return -int(lanelet.id) - 1 if lanelet.inverted() else int(lanelet.id)


def polyline_length_m(points: list[tuple[float, float]]) -> float:
    """Return the 2D length of a polyline [m]."""
    return sum(math.dist(a, b) for a, b in itertools.pairwise(points))


def nodes(path: str) -> list[ElementTree.Element]:
    """Return the file's nodes, those marked deleted left out (as Lanelet2 does)."""
    root = ElementTree.parse(path).getroot()
    return [n for n in root.iter("node") if n.get("action") != "delete"]


def tags(element: ElementTree.Element) -> dict[str, str]:
    """Return an element's tags."""
    return {t.get("k", ""): t.get("v", "") for t in element.iter("tag")}


def south_west_corner(path: str) -> tuple[float, float]:
    """Return the smallest latitude and longitude of the nodes (empty values read 0)."""
    lats = [float(n.get("lat") or 0) for n in nodes(path)]
    lons = [float(n.get("lon") or 0) for n in nodes(path)]
    return min(lats), min(lons)


def local_coordinates(path: str) -> dict[str, tuple[float, float]] | None:
    """Return every node's ``local_x``/``local_y`` when the file has them."""
    local = {}
    for node in nodes(path):
        t = tags(node)
        if "local_x" in t:
            local[node.get("id", "")] = (float(t["local_x"]), float(t["local_y"]))
    return local or None


def write_with_local_coordinates(path: str, projector: UtmProjector, out: Path) -> None:
    """Write the map to ``out``, each node's lat/lon its local x/y unprojected."""
    from lanelet2.core import BasicPoint3d

    tree = ElementTree.parse(path)
    for node in tree.getroot().iter("node"):
        t = tags(node)
        if "local_x" not in t:
            continue
        local = BasicPoint3d(float(t["local_x"]), float(t["local_y"]), 0.0)
        gps = projector.reverse(local)
        node.set("lat", repr(gps.lat))
        node.set("lon", repr(gps.lon))
    tree.write(out)


def neighbour(graph: RoutingGraph, lanelet: ConstLanelet, side: str) -> Entry | None:
    """Return the lanelet beside ``lanelet``, and whether a change to it is allowed."""
    changeable = getattr(graph, side)(lanelet)
    if changeable is not None:
        return {"id": cpmx_id(changeable), "lane_change": True}
    adjacent = getattr(graph, "adjacent" + side.capitalize())(lanelet)
    if adjacent is not None:
        return {"id": cpmx_id(adjacent), "lane_change": False}
    return None


def lanelet2_map(path: str) -> Entry:
    """Return Lanelet2's reading of a Lanelet2 OSM file."""
    import lanelet2
    from lanelet2.io import Origin
    from lanelet2.projection import UtmProjector

    local = local_coordinates(path)
    if local is None:
        lat, lon = south_west_corner(path)
        projector = UtmProjector(Origin(lat, lon))
        lanelet_map, errors = lanelet2.io.loadRobust(path, projector)
    else:
        # Any origin will do: the points are moved to their local coordinates.
        lat, lon = 45.0, 9.0
        projector = UtmProjector(Origin(lat, lon))
        with tempfile.TemporaryDirectory() as tmp:
            local_path = Path(tmp) / "local.osm"
            write_with_local_coordinates(path, projector, local_path)
            lanelet_map, errors = lanelet2.io.loadRobust(str(local_path), projector)
        for point in lanelet_map.pointLayer:
            point.x, point.y = local[str(point.id)]
    rules = lanelet2.traffic_rules.create(
        lanelet2.traffic_rules.Locations.Germany,
        lanelet2.traffic_rules.Participants.Vehicle,
    )
    graph = lanelet2.routing.RoutingGraph(lanelet_map, rules)
    entries: list[Entry] = []
    for forward in sorted(lanelet_map.laneletLayer, key=lambda ll: ll.id):
        if not rules.canPass(forward):
            continue
        directions = [forward]
        if rules.canPass(forward.invert()):
            directions.append(forward.invert())
        for lanelet in directions:
            centre = [(p.x, p.y) for p in lanelet.centerline]
            entries.append(
                {
                    "id": cpmx_id(lanelet),
                    "left_way": int(lanelet.leftBound.id),
                    "left_inverted": bool(lanelet.leftBound.inverted()),
                    "right_way": int(lanelet.rightBound.id),
                    "right_inverted": bool(lanelet.rightBound.inverted()),
                    "following": sorted(cpmx_id(f) for f in graph.following(lanelet)),
                    "left": neighbour(graph, lanelet, "left"),
                    "right": neighbour(graph, lanelet, "right"),
                    "centre_length_m": polyline_length_m(centre),
                    "centre_points": len(centre),
                },
            )
    return {
        "format": "lanelet2",
        "origin": [lat, lon],
        "local_coordinates": local is not None,
        "load_errors": len(errors),
        "lanelets": entries,
    }


def commonroad_map(path: str) -> Entry:
    """Return commonroad-io's reading of a CommonRoad XML file."""
    # commonroad-io's generated protobuf code (its protobuf reader, unused here) needs
    # protobuf 3.20's pure-Python descriptors when a newer protobuf is installed beside it.
    os.environ.setdefault("PROTOCOL_BUFFERS_PYTHON_IMPLEMENTATION", "python")
    from commonroad.common.file_reader import (  # type: ignore[import-untyped]
        CommonRoadFileReader,
    )

    # The lanelet network alone: a scenario also requires intersection, sign and
    # lanelet ids to be distinct, which the CPM Lab map's are not. What the reader
    # prints goes to stderr.
    with warnings.catch_warnings(), contextlib.redirect_stdout(sys.stderr):
        warnings.simplefilter("ignore")
        network = CommonRoadFileReader(path).open_lanelet_network()
    entries = []
    for lanelet in sorted(network.lanelets, key=lambda ll: ll.lanelet_id):
        centre = [(float(x), float(y)) for x, y in lanelet.center_vertices]
        sides = {}
        for side in ("left", "right"):
            other = getattr(lanelet, f"adj_{side}")
            same = getattr(lanelet, f"adj_{side}_same_direction")
            sides[side] = (
                None if other is None else {"id": int(other), "same_direction": bool(same)}
            )
        entries.append(
            {
                "id": int(lanelet.lanelet_id),
                "types": sorted(t.value for t in lanelet.lanelet_type),
                "users": sorted(u.value for u in lanelet.user_one_way),
                "following": sorted(int(s) for s in lanelet.successor),
                "left": sides["left"],
                "right": sides["right"],
                "centre_length_m": polyline_length_m(centre),
                "centre_points": len(centre),
            },
        )
    return {"format": "commonroad", "lanelets": entries}


def main(paths: list[str]) -> None:
    """Print every map's reading as one JSON object keyed by the paths given."""
    out = {}
    for path in paths:
        osm = path.endswith(".osm")
        out[path] = lanelet2_map(path) if osm else commonroad_map(path)
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1:])
