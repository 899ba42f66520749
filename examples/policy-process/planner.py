#!/usr/bin/env python3
"""A reference client of cpmx's policy-process protocol (`cpmx-policy`, version 1).

cpmx starts this program once per run (in the spec's folder) and writes one JSON object per
line to its stdin; the program answers each with one JSON line on stdout. Anything printed to
stderr is shown by cpmx when the run fails. The protocol is documented in
docs/policy-process.md.

This planner keeps every agent on its reference path with pure pursuit at a target speed: it
reads the paths' centre lines from the hello and answers each step with
[speed_mps, steering_rad] per agent. Predicted steps (the planner's look-ahead in trajectory
fidelities) are answered the same way but must not change the planner's memory.

Flags:
  --speed V                 target speed [m/s] (default 0.5)
  --look-ahead M            pure-pursuit look-ahead [m] (default 0.25)
  --require-observation     fail unless every step carries observations of the announced size
  --exit-at-step K          (for tests) print to stderr and exit with status 3 at step K
Only the Python standard library is used.
"""

import argparse
import json
import math
import sys

PROTOCOL = 1


def send(message):
    sys.stdout.write(json.dumps(message) + "\n")
    sys.stdout.flush()


def nearest_index(points, x, y):
    best, best_d = 0, float("inf")
    for i, (px, py) in enumerate(points):
        d = (px - x) ** 2 + (py - y) ** 2
        if d < best_d:
            best, best_d = i, d
    return best


def look_ahead_point(path, x, y, distance):
    """The centre-line point `distance` metres ahead of the nearest one (wrapping on loops)."""
    points = path["center_line"]
    i = nearest_index(points, x, y)
    travelled = 0.0
    n = len(points)
    while travelled < distance:
        j = i + 1
        if j >= n:
            if not path["is_loop"]:
                break
            j = 1  # the last point repeats the first
        travelled += math.dist(points[i], points[j])
        i = j
    return points[i]


def pure_pursuit(agent, path, vehicle, speed, look_ahead):
    tx, ty = look_ahead_point(path, agent["x_m"], agent["y_m"], look_ahead)
    dx, dy = tx - agent["x_m"], ty - agent["y_m"]
    alpha = math.atan2(dy, dx) - agent["yaw_rad"]
    distance = max(math.hypot(dx, dy), 1e-6)
    steering = math.atan2(2.0 * vehicle["wheelbase_m"] * math.sin(alpha), distance)
    limit = vehicle["max_steering_rad"]
    return [min(speed, vehicle["max_speed_mps"]), max(-limit, min(limit, steering))]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=0.5)
    parser.add_argument("--look-ahead", type=float, default=0.25)
    parser.add_argument("--require-observation", action="store_true")
    parser.add_argument("--exit-at-step", type=int, default=None)
    args = parser.parse_args()

    hello = None
    for line in sys.stdin:
        message = json.loads(line)
        kind = message.get("type")
        if kind == "hello":
            if message.get("protocol") != PROTOCOL:
                print(f"planner.py speaks protocol {PROTOCOL}, cpmx sent {message.get('protocol')}", file=sys.stderr)
                return 2
            hello = message
            hello["paths_by_id"] = {p["id"]: p for p in message["paths"]}
            send({"type": "ready", "protocol": PROTOCOL})
        elif kind == "step":
            if args.exit_at_step is not None and message["step"] >= args.exit_at_step:
                print(f"planner.py: giving up at step {message['step']} (--exit-at-step)", file=sys.stderr)
                return 3
            if args.require_observation:
                size = hello["observation_size"]
                rows = message.get("observations")
                if size is None or rows is None or any(len(r) != size for r in rows):
                    print(f"planner.py: expected observations of {size} values", file=sys.stderr)
                    return 4
            paths = hello["paths_by_id"]
            actions = [
                pure_pursuit(a, paths[a["ref_path"]], hello["vehicle"], args.speed, args.look_ahead)
                for a in message["agents"]
            ]
            send({"actions": actions})
        elif kind == "end":
            return 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
