"""What play_lab.py and read_emulator.py share: opening an RTI Connector on the lab's
types (lab_types.xml) and participants (lab_participants.xml), exact 64-bit integers,
bounded waits, and the checks of a VehicleCommandTrajectory.

RTI Connector keeps numbers as IEEE doubles: a uint64 set with set_number, or read with
get_number, is rounded beyond 2^53, and set_dictionary/`instance[...] = ` refuse values from
2^63 on (its JSON parser is int64). Every uint64 is therefore written with set_string (exact
over the whole range, up to the stop stamp 2^64 - 1) and read from get_dictionary(), which
hands back Python ints.
"""

import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))

# Values from this size on lose precision as doubles.
EXACT_DOUBLE_LIMIT = 2**53
# The stop trigger's stamp (u64::MAX).
STOP_NS = 2**64 - 1
# The vehicles' MPC samples its reference up to 360 ms after the vehicle's clock and rejects a
# trajectory whose first point is not before t_now + 110 ms (cpm-lab-interface.md §3.3/§3.4).
VEHICLE_LEAD_NS = 360_000_000
FIRST_POINT_LIMIT_NS = 110_000_000
# The middleware warns about trajectories with fewer points.
MIN_POINTS = 3
# The lab's driving surface is 4.5 m x 4.0 m; generous margins for sanity checks.
MAP_X = (-0.5, 5.0)
MAP_Y = (-0.5, 4.5)


class Failure(Exception):
    """A check failed; the script exits non-zero with this message."""


def fail(message):
    raise Failure(message)


def main(run, name):
    """Runs `run()` and exits 0, or 1 with a clear message on any failure."""
    try:
        run()
    except Failure as e:
        print(f"{name}: FAILED: {e}", file=sys.stderr)
        sys.exit(1)
    except Exception as e:  # the connector's errors included
        print(f"{name}: FAILED with {type(e).__name__}: {e}", file=sys.stderr)
        sys.exit(1)


def log(name, message):
    print(f"{name}: {message}", file=sys.stderr, flush=True)


def open_connector(participant, domain):
    """The RTI Connector of `CpmxRti::<participant>` on `domain`."""
    os.environ["CPMX_RTI_DOMAIN"] = str(domain)
    import rticonnextdds_connector as rti

    url = ";".join(os.path.join(HERE, f) for f in ("lab_types.xml", "lab_participants.xml"))
    return rti.Connector(f"CpmxRti::{participant}", url)


class Deadline:
    """The script's time budget."""

    def __init__(self, seconds):
        self.end = time.monotonic() + seconds
        self.seconds = seconds

    def left_ms(self, cap_ms=None):
        left = max(0, int((self.end - time.monotonic()) * 1000))
        return left if cap_ms is None else min(left, cap_ms)

    def check(self, what):
        if time.monotonic() >= self.end:
            fail(f"{what} did not happen within the script's {self.seconds} s")


def wait_matched(endpoint, kind, what, deadline):
    """Waits until `endpoint` (an Output: kind "subscriptions", an Input: "publications")
    has matched at least one remote endpoint."""
    while True:
        matched = getattr(endpoint, f"matched_{kind}")
        if len(matched) > 0:
            return
        deadline.check(f"matching {what}")
        try:
            getattr(endpoint, f"wait_for_{kind}")(deadline.left_ms(200))
        except Exception:  # the connector's TimeoutError: poll again
            pass


def write(output, value):
    """Writes `value` (a dict) exactly: integers that doubles cannot hold go through
    set_string after the rest was set with set_dictionary."""
    big = []

    def strip(v, path):
        if isinstance(v, dict):
            return {k: strip(x, f"{path}.{k}" if path else k) for k, x in v.items()}
        if isinstance(v, list):
            return [strip(x, f"{path}[{i}]") for i, x in enumerate(v)]
        if isinstance(v, int) and not isinstance(v, bool) and abs(v) >= EXACT_DOUBLE_LIMIT:
            big.append((path, v))
            return 0
        return v

    output.clear_members()
    output.instance.set_dictionary(strip(value, ""))
    for path, v in big:
        output.instance.set_string(path, str(v))
    readback = output.instance.get_dictionary()
    for path, v in big:
        got = lookup(readback, path)
        if got != v:
            fail(f"RTI holds {path} = {got}, not {v}")
    output.write()


def lookup(value, path):
    for part in path.replace("[", ".[").split("."):
        value = value[int(part[1:-1])] if part.startswith("[") else value[part]
    return value


def take(input_):
    """Takes every sample in the reader's cache as dicts (exact integers)."""
    input_.take()
    return [s.get_dictionary() for s in input_.samples.valid_data_iter]


def finite(*values):
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def check_trajectory(command, t_now, period_ns, vehicle_ids):
    """Checks one VehicleCommandTrajectory made for the tick `t_now` as the lab's vehicles and
    middleware would; returns the points."""
    vid = command["vehicle_id"]
    if vid not in vehicle_ids:
        fail(f"trajectory for vehicle {vid}, not one of {sorted(vehicle_ids)}")
    header = command["header"]
    if header["valid_after_stamp"]["nanoseconds"] != t_now:
        fail(f"vehicle {vid}: valid_after_stamp {header['valid_after_stamp']} for the tick {t_now}")
    points = command["trajectory_points"]
    if len(points) < MIN_POINTS:
        fail(f"vehicle {vid}: {len(points)} trajectory points, the lab needs at least {MIN_POINTS}")
    times = [p["t"]["nanoseconds"] for p in points]
    if any(b <= a for a, b in zip(times, times[1:])):
        fail(f"vehicle {vid}: point times not strictly increasing: {times}")
    if times[0] >= t_now + FIRST_POINT_LIMIT_NS:
        fail(
            f"vehicle {vid}: first point {(times[0] - t_now) / 1e6:.1f} ms after the tick: "
            "the vehicle's MPC rejects it (first trajectory point is in the future)"
        )
    needed = t_now + period_ns + VEHICLE_LEAD_NS
    if times[-1] < needed:
        fail(
            f"vehicle {vid}: insufficient lead time: the last point is "
            f"{(times[-1] - t_now) / 1e6:.1f} ms after the tick, the vehicle follows it until "
            f"{(needed - t_now) / 1e6:.0f} ms (next tick + 360 ms)"
        )
    for p in points:
        if not finite(p["px"], p["py"], p["vx"], p["vy"]):
            fail(f"vehicle {vid}: non-finite point {p}")
        if not (MAP_X[0] <= p["px"] <= MAP_X[1] and MAP_Y[0] <= p["py"] <= MAP_Y[1]):
            fail(f"vehicle {vid}: point ({p['px']:.3f}, {p['py']:.3f}) off the lab's map")
        if math.hypot(p["vx"], p["vy"]) > 5.0:
            fail(f"vehicle {vid}: point velocity {p['vx']:.2f}, {p['vy']:.2f} m/s beyond a µCar's")
    return points
