"""How the reference libraries read map files, as JSON for cpmx's tests.

Lanelet2 maps (``.osm``) are read with the ``lanelet2`` package as a vehicle under German
rules reads them: every lanelet the traffic rules let a vehicle pass, and the inverse of each
that may also be driven backwards (cpmx numbers the inverse of lanelet ``N`` as ``-N-1``),
with the orientation Lanelet2 gives its bounds, its successors and neighbours in the routing
graph and the length of its centre line. Coordinates are lat/lon projected by Lanelet2's
``UtmProjector`` at the south-west corner of the file's nodes, or the nodes' ``local_x`` and
``local_y`` tags where the file has them (as cpmx reads them: the map is then loaded from a copy
whose lat/lon are the inverse projection of the local coordinates, so that Lanelet2 orients
its lanelets in them, and the points are set to them exactly).

CommonRoad maps (``.xml``) are read with ``commonroad-io``: every lanelet's successors,
neighbours and centre-line length.

Usage: ``python map_reference.py MAP...``; prints one JSON object with a key per map file.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import tempfile
import warnings
from typing import Any
from xml.etree import ElementTree

Lanelet2Entry = dict[str, Any]


def cpmx_id(lanelet: Any) -> int:
    """The id cpmx gives a lanelet: its own, or ``-id-1`` for its inverse."""
    return -lanelet.id - 1 if lanelet.inverted() else int(lanelet.id)


def polyline_length_m(points: list[tuple[float, float]]) -> float:
    """The 2D length of a polyline [m]."""
    return sum(math.dist(a, b) for a, b in zip(points, points[1:]))


def south_west_corner(path: str) -> tuple[float, float]:
    """The smallest latitude and longitude of the file's nodes (deleted ones left out, an empty value read as 0 as Lanelet2 reads it)."""
    lats, lons = [], []
    for node in ElementTree.parse(path).getroot().iter("node"):
        if node.get("action") == "delete":
            continue
        lats.append(float(node.get("lat") or 0))
        lons.append(float(node.get("lon") or 0))
    return min(lats), min(lons)


def local_coordinates(path: str) -> dict[str, tuple[float, float]] | None:
    """Every node's ``local_x``/``local_y`` when the file has them (deleted nodes left out)."""
    local = {}
    for node in ElementTree.parse(path).getroot().iter("node"):
        if node.get("action") == "delete":
            continue
        tags = {t.get("k"): t.get("v") for t in node.iter("tag")}
        if "local_x" in tags:
            local[node.get("id", "")] = (float(tags["local_x"]), float(tags["local_y"]))
    return local or None


def with_local_coordinates(path: str, projector: Any, out: str) -> None:
    """Writes the map to ``out`` with each node's lat/lon the inverse projection of its local
    coordinates, so that Lanelet2 loads (and orients) the lanelets in local coordinates."""
    from lanelet2.core import BasicPoint3d

    tree = ElementTree.parse(path)
    for node in tree.getroot().iter("node"):
        tags = {t.get("k"): t.get("v") for t in node.iter("tag")}
        if "local_x" not in tags:
            continue
        gps = projector.reverse(BasicPoint3d(float(tags["local_x"]), float(tags["local_y"]), 0.0))
        node.set("lat", repr(gps.lat))
        node.set("lon", repr(gps.lon))
    tree.write(out)


def neighbour(graph: Any, lanelet: Any, side: str) -> dict[str, Any] | None:
    """The lanelet beside ``lanelet`` on ``side`` and whether a lane change to it is allowed."""
    changeable = getattr(graph, side)(lanelet)
    if changeable is not None:
        return {"id": cpmx_id(changeable), "lane_change": True}
    adjacent = getattr(graph, "adjacent" + side.capitalize())(lanelet)
    if adjacent is not None:
        return {"id": cpmx_id(adjacent), "lane_change": False}
    return None


def lanelet2_map(path: str) -> dict[str, Any]:
    """Lanelet2's reading of a Lanelet2 OSM file."""
    import lanelet2
    from lanelet2.io import Origin
    from lanelet2.projection import UtmProjector

    local = local_coordinates(path)
    if local is None:
        lat, lon = south_west_corner(path)
        lanelet_map, errors = lanelet2.io.loadRobust(path, UtmProjector(Origin(lat, lon)))
    else:
        # Local coordinates: any origin will do; the points are moved to them exactly after
        # loading.
        lat, lon = 45.0, 9.0
        projector = UtmProjector(Origin(lat, lon))
        with tempfile.TemporaryDirectory() as tmp:
            local_path = os.path.join(tmp, "local.osm")
            with_local_coordinates(path, projector, local_path)
            lanelet_map, errors = lanelet2.io.loadRobust(local_path, projector)
        for point in lanelet_map.pointLayer:
            point.x, point.y = local[str(point.id)]
    rules = lanelet2.traffic_rules.create(
        lanelet2.traffic_rules.Locations.Germany,
        lanelet2.traffic_rules.Participants.Vehicle,
    )
    graph = lanelet2.routing.RoutingGraph(lanelet_map, rules)
    entries: list[Lanelet2Entry] = []
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
                }
            )
    return {
        "format": "lanelet2",
        "origin": [lat, lon],
        "local_coordinates": local is not None,
        "load_errors": len(errors),
        "lanelets": entries,
    }


def commonroad_map(path: str) -> dict[str, Any]:
    """commonroad-io's reading of a CommonRoad XML file."""
    from commonroad.common.file_reader import CommonRoadFileReader

    # The lanelet network alone (a scenario also checks that intersection, sign and lanelet ids
    # are distinct, which the CPM Lab map's are not); what the reader prints goes to stderr.
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
            sides[side] = None if other is None else {"id": int(other), "same_direction": bool(same)}
        entries.append(
            {
                "id": int(lanelet.lanelet_id),
                "following": sorted(int(s) for s in lanelet.successor),
                "left": sides["left"],
                "right": sides["right"],
                "centre_length_m": polyline_length_m(centre),
                "centre_points": len(centre),
            }
        )
    return {"format": "commonroad", "lanelets": entries}


def main(paths: list[str]) -> None:
    """Prints every map's reading as one JSON object keyed by the paths given."""
    out = {}
    for path in paths:
        out[path] = lanelet2_map(path) if path.endswith(".osm") else commonroad_map(path)
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1:])
