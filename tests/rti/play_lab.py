"""Plays the CPM Lab's middleware with RTI Connext DDS against a planner (the cpmx lab
driver): waits for `hlc_<id>` ReadyStatus of every vehicle, sends the start SystemTrigger,
ticks VehicleStateList in simulated time (lock-step, as the lab's --simulated_time mode),
reads the planner's VehicleCommandTrajectory for each tick and checks them as the lab's
vehicles would (points, lead time), and finally sends the stop trigger (2^64 - 1).

The vehicles are ideal followers: at each tick a vehicle reports the point of its last
trajectory at that time (cubic Hermite, as the vehicles interpolate). Before its first
trajectory a vehicle stands at its start (`--starts`, as the planner's preflight wants it);
without starts the list carries default-constructed entries (create_stamp 0), as the real
middleware sends for ids without data.

A fault can be played: `--ips-stall-after K --ips-stall-vehicle ID` makes vehicle ID's
positioning fixes stop after tick K (its IPS_update_age_nanoseconds grows by a period each
tick). A command with no point after its valid_after is the planner's stop: the vehicle stands
where it is. Once the planner has stopped every vehicle and falls silent, the script ends the
run early (stop trigger) and reports the stops. `--stuck-after K` makes the middleware's clock
stick after tick K: it sends that tick's list again every 0.2 s, whatever the planner answers,
until the planner has stopped every vehicle and left.

Prints a JSON summary on stdout (announced stamps, start, every tick's t_now, the ticks at
which each vehicle was commanded to stop); exits 1 with a message on stderr on any failure or
when the time budget runs out.

    play_lab.py --domain 1 --vehicle-ids 1,2 --ticks 30 --period-ms 100 --timeout-s 45 \
        --starts '[[0.1, 2.0, 0.0], [2.0, 0.1, 1.57]]'
"""

import argparse
import json
import math
import time

import lab_rti
from lab_rti import Deadline, fail, log

NAME = "play_lab"
# An unanswered list is sent again after this long (best-effort topic).
RESEND_S = 0.2
# The µCar's wheelbase and steering limit, for the reported servo (reference §7).
WHEELBASE_M = 0.15
MAX_STEERING_RAD = math.radians(31)
# A planner that stopped every vehicle and stays silent this long has left the run.
LEFT_S = 2.0


def hermite(points, t_ns):
    """Position, velocity and acceleration of the trajectory at `t_ns` (held at the ends)."""
    t_ns = min(max(t_ns, points[0]["t"]["nanoseconds"]), points[-1]["t"]["nanoseconds"])
    for a, b in zip(points, points[1:]):
        t0, t1 = a["t"]["nanoseconds"], b["t"]["nanoseconds"]
        if t_ns <= t1:
            break
    dt = (t1 - t0) / 1e9
    tau = (t_ns - t0) / (t1 - t0)
    basis = (
        (2 * tau**3 - 3 * tau**2 + 1, tau**3 - 2 * tau**2 + tau, -2 * tau**3 + 3 * tau**2, tau**3 - tau**2),
        (6 * tau**2 - 6 * tau, 3 * tau**2 - 4 * tau + 1, -6 * tau**2 + 6 * tau, 3 * tau**2 - 2 * tau),
        (12 * tau - 6, 6 * tau - 4, -12 * tau + 6, 6 * tau - 2),
    )
    out = []
    for order, (h00, h10, h01, h11) in enumerate(basis):
        scale = dt**order
        out.append(
            tuple(
                (h00 * a[p] + h10 * dt * a[v] + h01 * b[p] + h11 * dt * b[v]) / scale
                for p, v in (("px", "vx"), ("py", "vy"))
            )
        )
    return out


class Vehicle:
    """An ideal follower of its last trajectory."""

    def __init__(self, vid, start=None):
        self.vid = vid
        self.points = None
        self.yaw = start[2] if start else None
        self.odometer = 0.0
        self.last = (start[0], start[1]) if start else None
        self.ips_age_ns = 0

    def stand(self):
        """Stops where the vehicle is (the planner's stop command)."""
        self.points = None

    def state(self, t_now):
        """The VehicleState at `t_now`: on its trajectory, standing where it is, or a
        default-constructed entry while unknown."""
        empty = {"vehicle_id": self.vid}
        if self.points is None:
            if self.last is None or self.yaw is None:
                return empty
            (x, y), (vx, vy), (ax, ay) = self.last, (0.0, 0.0), (0.0, 0.0)
        else:
            (x, y), (vx, vy), (ax, ay) = hermite(self.points, t_now)
        speed = math.hypot(vx, vy)
        if speed > 1e-3:
            self.yaw = math.atan2(vy, vx)
        if self.yaw is None:
            return empty
        curvature = (vx * ay - vy * ax) / speed**3 if speed > 1e-3 else 0.0
        servo = max(-1.0, min(1.0, math.atan(WHEELBASE_M * curvature) / MAX_STEERING_RAD))
        if self.last is not None:
            self.odometer += math.hypot(x - self.last[0], y - self.last[1])
        self.last = (x, y)
        return {
            "vehicle_id": self.vid,
            "header": {"create_stamp": {"nanoseconds": t_now}, "valid_after_stamp": {"nanoseconds": t_now}},
            "pose": {"x": x, "y": y, "yaw": self.yaw},
            "IPS_update_age_nanoseconds": self.ips_age_ns,
            "odometer_distance": self.odometer,
            "speed": speed,
            "battery_voltage": 7.8,
            "steering_servo": servo,
            "is_real": False,
        }


def run():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--vehicle-ids", required=True, help="comma-separated, e.g. 1,2")
    parser.add_argument("--ticks", type=int, required=True, help="ticks to send before the stop trigger")
    parser.add_argument("--period-ms", type=int, default=100)
    parser.add_argument("--timeout-s", type=float, default=45.0)
    parser.add_argument("--starts", help="JSON list of [x, y, yaw] per vehicle, in the order of --vehicle-ids")
    parser.add_argument("--ips-stall-after", type=int, help="tick after which a vehicle's fixes stop")
    parser.add_argument("--ips-stall-vehicle", type=int, help="the vehicle whose fixes stop")
    parser.add_argument("--stuck-after", type=int, help="tick after which the lists repeat that tick")
    args = parser.parse_args()
    ids = [int(i) for i in args.vehicle_ids.split(",")]
    period_ns = args.period_ms * 1_000_000
    deadline = Deadline(args.timeout_s)
    starts = json.loads(args.starts) if args.starts else [None] * len(ids)
    stall = (args.ips_stall_after, args.ips_stall_vehicle) if args.ips_stall_after is not None else None

    connector = lab_rti.open_connector("Middleware", args.domain)
    try:
        summary = play(connector, ids, args.ticks, period_ns, deadline, starts, stall, args.stuck_after)
    finally:
        connector.close()
    print(json.dumps(summary), flush=True)


def is_stop(command):
    """Whether a command has no point after its valid_after (the planner's stop)."""
    valid_after = command["header"]["valid_after_stamp"]["nanoseconds"]
    return all(p["t"]["nanoseconds"] <= valid_after for p in command["trajectory_points"])


def play(connector, ids, ticks, period_ns, deadline, starts, stall, stuck_after=None):
    trigger = connector.get_output("Publisher::SystemTrigger")
    lists = connector.get_output("Publisher::VehicleStateList")
    ready = connector.get_input("Subscriber::ReadyStatus")
    commands = connector.get_input("Subscriber::VehicleCommandTrajectory")

    # 1. Every vehicle's planner announces itself.
    log(NAME, f"waiting for ReadyStatus hlc_<id> for vehicles {ids}")
    announced = {}
    while not all(f"hlc_{i}" in announced for i in ids):
        deadline.check(f"ReadyStatus hlc_<id> for every vehicle of {ids} (seen: {sorted(announced)})")
        try:
            ready.wait(deadline.left_ms(200))
        except Exception:
            continue
        for status in lab_rti.take(ready):
            stamp = status["next_start_stamp"]["nanoseconds"]
            if not isinstance(stamp, int) or not 0 <= stamp < 2**64:
                fail(f"ReadyStatus {status['source_id']!r}: next_start_stamp {stamp!r} is not a uint64")
            announced[status["source_id"]] = stamp
    log(NAME, f"ready: {announced}")

    # 2. The start trigger, once the planner's trigger and list readers are matched.
    lab_rti.wait_matched(trigger, "subscriptions", "the planner's systemTrigger reader", deadline)
    lab_rti.wait_matched(lists, "subscriptions", "the planner's vehicleStateList reader", deadline)
    lab_rti.wait_matched(commands, "publications", "the planner's vehicleCommandTrajectory writer", deadline)
    start_ns = time.time_ns() // 1_000_000 * 1_000_000
    lab_rti.write(trigger, {"next_start": {"nanoseconds": start_ns}})
    log(NAME, f"start trigger sent: {start_ns}")

    # 3. Ticks in lock-step: a list, then one trajectory per vehicle made for it.
    vehicles = {i: Vehicle(i, s) for i, s in zip(ids, starts)}
    sent = []
    stopped = {}
    left = False
    for k in range(ticks):
        stuck = stuck_after is not None and k > stuck_after
        t_now = start_ns + (min(k, stuck_after) if stuck else k) * period_ns
        if stall is not None and k > stall[0]:
            vehicles[stall[1]].ips_age_ns = (k - stall[0]) * period_ns + 20_000_000
        state_list = {
            "t_now": t_now,
            "period_ms": period_ns // 1_000_000,
            "state_list": [vehicles[i].state(t_now) for i in ids],
            "vehicle_observation_list": [],
            "active_vehicle_ids": ids,
        }
        answers = {}
        resend_at = 0.0
        heard = time.monotonic()
        while stuck or len(answers) < len(ids):
            if len(stopped) == len(ids) and time.monotonic() - heard > LEFT_S:
                left = True
                break
            deadline.check(f"trajectories of vehicles {ids} for tick {k} (got {sorted(answers)})")
            if time.monotonic() >= resend_at:
                if k == 0:
                    lab_rti.write(trigger, {"next_start": {"nanoseconds": start_ns}})
                lab_rti.write(lists, state_list)
                resend_at = time.monotonic() + RESEND_S
            try:
                commands.wait(deadline.left_ms(20))
            except Exception:
                continue
            for command in lab_rti.take(commands):
                heard = time.monotonic()
                if is_stop(command):
                    stopped.setdefault(command["vehicle_id"], t_now)
                    if command["header"]["create_stamp"]["nanoseconds"] >= t_now:
                        answers[command["vehicle_id"]] = None
                    continue
                if command["header"]["create_stamp"]["nanoseconds"] != t_now:
                    continue  # an answer to an earlier tick, sent again
                points = lab_rti.check_trajectory(command, t_now, period_ns, set(ids))
                answers[command["vehicle_id"]] = points
        if left:
            log(NAME, f"the planner stopped every vehicle and left at tick {k}")
            break
        for i in ids:
            if answers[i] is None:
                vehicles[i].stand()
            else:
                vehicles[i].points = answers[i]
        sent.append(t_now)
    log(NAME, f"{len(sent)} ticks answered")

    # 4. The stop trigger (u64::MAX), delivered reliably (to a planner still there).
    lab_rti.write(trigger, {"next_start": {"nanoseconds": lab_rti.STOP_NS}})
    if not left:
        try:
            trigger.wait(deadline.left_ms(5000))
        except Exception:
            fail("the planner did not acknowledge the stop trigger")
        log(NAME, "stop trigger sent and acknowledged")
    return {
        "announced": announced,
        "start_ns": start_ns,
        "ticks_ns": sent,
        "stopped": {str(i): t for i, t in stopped.items()},
    }


if __name__ == "__main__":
    lab_rti.main(run, NAME)
