#!/usr/bin/env python3
"""Standalone reimplementation of SigmaRL's ParseOSM (bassamlab/SigmaRL @ 4c8032d,
sigmarl/parse_osm.py) for one scenario, numpy only. See research/sigmarl-osm-maps.md.

Usage:
    python sigmarl_osm_reference.py SCENARIO [--lane-width W] [--maps DIR] [--boundaries]

SCENARIO is a key of scenarios.json (e.g. intersection_2). --lane-width overrides the table's
lane_width, as SigmaRL's env does with `parameters.lane_width` (0.25 by default at 4c8032d).

Prints, per lanelet (index = lanes tag - 1) and per reference path (index = position in
reference_paths_ids): number of points, first/last centre-line point, total length (f64 sum of
f64 hypot over the float32 points, as cpmx's Polyline::length_m), SigmaRL's
center_line_vec_mean_length (float32), and with --boundaries the first/last left/right boundary
points. Numbers are the float32 values widened to float64 and printed with repr() (exact).

numpy float32 reproduces torch's float32 arithmetic for -, *, /, sqrt exactly; torch's atan2,
norm are emulated exactly (glibc atan2f; sqrt(fma(v1, v1, v0*v0))); torch.mean's summation
order is not (center_line_vec_mean_length may differ by 1 ulp; SigmaRL's env never reads it).
Checked bit for bit against SigmaRL's ParseOSM (4c8032d, torch 2.15 CPU): see the note.
"""
import argparse
import json
import math
import os
import sys
import xml.etree.ElementTree as ET

import ctypes
import ctypes.util

import numpy as np

F32 = np.float32
DEFAULT_MAPS = "../shared/reference/sigmarl-published/maps"

# torch.atan2 on float32 CPU tensors (strided slices, as SigmaRL calls it) equals glibc's atan2f
# bit for bit (checked on all 2698 segments); numpy's float32 arctan2 does not (SIMD code).
try:
    _libm = ctypes.CDLL(ctypes.util.find_library("m") or "libm.so.6")
    _libm.atan2f.restype = ctypes.c_float
    _libm.atan2f.argtypes = [ctypes.c_float, ctypes.c_float]

    def atan2_f32(y, x):
        return np.array([_libm.atan2f(float(b), float(a)) for b, a in zip(y, x)], dtype=F32)
except (OSError, AttributeError):  # no C libm: numpy (may differ by 1 ulp)
    def atan2_f32(y, x):
        return np.arctan2(y, x)


def _fma_f32(a, b, c):
    """f32(a * b + c) with one rounding (a, b, c float32). The f64 sum a*b + c can itself
    round, so this is exact except for rare double-rounding cases (none on these maps)."""
    return F32(float(a) * float(b) + float(c))


def norm2_f32(v0, v1):
    """torch.norm of a float32 2-vector (v0, v1) on CPU, as observed with torch 2.x x86-64
    (both `torch.norm(t, dim=1)` rows and `torch.norm(t)` of a 2-element t):
    sqrt(fma(v1, v1, f32(v0 * v0))). A plain sqrt(v0*v0 + v1*v1) differs in ~6% of cases."""
    return F32(np.sqrt(_fma_f32(v1, v1, F32(v0 * v0))))


def parse(osm_path, scale, width):
    """_parse_map_file (parse_osm.py:67-107). Returns {lanes_tag: float32 (n,2) centre line}."""
    root = ET.parse(osm_path).getroot()
    node_data = {}
    min_lat = min_lon = float("inf")
    for node in root.findall("node"):  # every <node>, referenced or not; <bounds> ignored
        lat = float(node.get("lat"))
        lon = float(node.get("lon"))
        node_data[int(node.get("id"))] = (lat, lon)
        min_lat = min(min_lat, lat)
        min_lon = min(min_lon, lon)
    nodes = {}
    for nid, (lat, lon) in node_data.items():
        # float64 arithmetic, same operation order as SigmaRL: (d * scale) + (width * 1.2)
        x = (lat - min_lat) * scale + width * 1.2  # x from LATITUDE
        y = (lon - min_lon) * scale + width * 1.2  # y from LONGITUDE
        nodes[nid] = (x, y)
    lanes = {}
    for way in root.findall("way"):
        tag = way.find("tag[@k='lanes']")
        if tag is None:
            continue  # untagged ways are skipped (a message is printed by SigmaRL)
        lid = int(tag.get("v"))
        pts = [nodes[int(nd.get("ref"))] for nd in way.findall("nd")]
        lanes[lid] = np.array(pts, dtype=np.float64).astype(F32)  # torch.tensor(..., float32)
    return lanes


def center_line_info(c):
    """_compute_center_line_info (parse_osm.py:264-281), float32."""
    vec = np.diff(c, axis=0)
    length = np.array([norm2_f32(a, b) for a, b in vec], dtype=F32)
    # torch.mean's summation order is not reproduced (may differ by 1 ulp; unused by the env)
    mean_length = F32(np.mean(length, dtype=F32))
    vec_norm = vec / length[:, None]
    yaw = atan2_f32(vec[:, 1], vec[:, 0])
    return yaw, vec_norm, mean_length


def boundaries(c, width):
    """_compute_boundaries (parse_osm.py:283-306), float32; normal = left normal of segment i."""
    half = F32(width / 2)
    left, right = [], []
    perp = None
    for i in range(len(c) - 1):
        d = c[i + 1] - c[i]
        perp = np.array([-d[1], d[0]], dtype=F32)
        n = norm2_f32(perp[0], perp[1])
        if n != 0:
            perp = perp / n
        left.append(c[i] + perp * half)
        right.append(c[i] - perp * half)
    left.append(c[-1] + perp * half)  # last point reuses the last segment's normal
    right.append(c[-1] - perp * half)
    return np.array(left, dtype=F32), np.array(right, dtype=F32)


def reference_path(lanelets_all, ids):
    """_get_reference_paths (parse_osm.py:197-254)."""
    is_loop = len(ids) > 1 and ids[0] == ids[-1]
    pts = []
    for k, sid in enumerate(ids):
        c = lanelets_all[int(sid) - 1]
        pts.extend(list(c if k == 0 else c[1:]))  # drop the joint point of later lanelets
    if is_loop and pts:
        pts.pop()
    return np.array(pts, dtype=F32), is_loop


def length_f64(c):
    c = c.astype(np.float64)
    return sum(math.hypot(*(c[i + 1] - c[i])) for i in range(len(c) - 1))


def fmt(p):
    return "(%r, %r)" % (float(p[0]), float(p[1]))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario")
    ap.add_argument("--lane-width", type=float, default=None)
    ap.add_argument("--maps", default=DEFAULT_MAPS)
    ap.add_argument("--boundaries", action="store_true")
    a = ap.parse_args()
    with open(os.path.join(a.maps, "scenarios.json")) as f:
        table = json.load(f)
    table = table.get("scenarios", table)
    sc = table[a.scenario]
    width = sc["lane_width"] if a.lane_width is None else a.lane_width
    scale = sc["scale"]
    lanes = parse(os.path.join(a.maps, sc["map_path"]), scale, width)
    # lanelets_all[i] = lanelet with lanes tag i + 1 (parse_osm.py:168-172); KeyError if a gap
    lanelets_all = [lanes[i + 1] for i in range(max(lanes))]
    print("scenario %s map %s scale %r lane_width %r n_agents %d" % (
        a.scenario, sc["map_path"], scale, width, sc["n_agents"]))

    def report(tag, c):
        yaw, _, mean_len = center_line_info(c)
        print("%s n=%d first=%s last=%s length_f64=%r mean_seg_f32=%r yaw0=%r yawN=%r" % (
            tag, len(c), fmt(c[0]), fmt(c[-1]), length_f64(c), float(mean_len),
            float(yaw[0]), float(yaw[-1])))
        if a.boundaries:
            lb, rb = boundaries(c, width)
            print("    left first=%s last=%s | right first=%s last=%s" % (
                fmt(lb[0]), fmt(lb[-1]), fmt(rb[0]), fmt(rb[-1])))
        return boundaries(c, width)

    for i, c in enumerate(lanelets_all):
        report("lanelet idx %d (lanes=%d)" % (i, i + 1), c)
    xs, ys = [], []
    for j, ids in enumerate(sc["reference_paths_ids"]):
        c, is_loop = reference_path(lanelets_all, ids)
        lb, rb = report("path %d lanelets=%s is_loop=%s" % (j, ",".join(ids), is_loop), c)
        for arr in (c, lb, rb):
            xs.extend(arr[:, 0].tolist())
            ys.extend(arr[:, 1].tolist())
    # _get_map_dimension (parse_osm.py:308-336): over reference paths' centre and boundaries
    print("bounds min_x %r max_x %r min_y %r max_y %r world_x_dim %r world_y_dim %r" % (
        min(xs), max(xs), min(ys), max(ys), max(xs) + min(xs), max(ys) + min(ys)))


if __name__ == "__main__":
    sys.exit(main())
