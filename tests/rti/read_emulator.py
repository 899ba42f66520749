"""An RTI Connext DDS bystander on the planners' domain while `cpmx lab emulate` plays the lab
for a planner (the cpmx lab driver): reads what the emulator publishes (SystemTrigger,
VehicleStateList) and what the planner publishes (ReadyStatus, VehicleCommandTrajectory), and
checks that the values are sane:

- the start trigger is a wall-clock stamp (ns since 1970), the stop trigger is 2^64 - 1;
- the lists arrive for every tick 0..ticks-1, on the period's grid from the start, each with
  one state per active vehicle, stamped as the lab stamps (valid_after = create + 60 ms, valid at the tick), on the map, at µCar speeds, moving
  continuously from tick to tick; the period is --period-ms;
- what it sees of the planner (announcements, trajectories) passes the lab's checks; it
  need not see any (see below).

Once its readers matched the emulator's writers it creates --ready-file (so that the planner
can be started without the start trigger being missed). Prints a JSON summary on stdout;
exits 1 with a message on stderr on any failure or when the time budget runs out.

    read_emulator.py --domain 1 --vehicle-ids 1,2 --ticks 30 --period-ms 100 --ready-file F
"""

import argparse
import json
import math
import time

import lab_rti
from lab_rti import Deadline, fail, log

NAME = "read_emulator"
# Largest plausible µCar speed [m/s] and the largest step between two ticks it allows.
MAX_SPEED_MPS = 2.0
# A start stamp farther than this from this machine's clock is not a wall-clock stamp.
CLOCK_SLACK_NS = 600 * 10**9


def run():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--vehicle-ids", required=True, help="comma-separated, e.g. 1,2")
    parser.add_argument("--ticks", type=int, required=True, help="ticks the emulator plays")
    parser.add_argument("--period-ms", type=int, default=100)
    parser.add_argument("--timeout-s", type=float, default=45.0)
    parser.add_argument("--ready-file", help="created once the readers matched the emulator")
    args = parser.parse_args()
    ids = [int(i) for i in args.vehicle_ids.split(",")]
    deadline = Deadline(args.timeout_s)

    connector = lab_rti.open_connector("Listener", args.domain)
    try:
        summary = listen(connector, ids, args, deadline)
    finally:
        connector.close()
    print(json.dumps(summary), flush=True)


def listen(connector, ids, args, deadline):
    lists_in = connector.get_input("Subscriber::VehicleStateList")
    triggers_in = connector.get_input("Subscriber::SystemTrigger")
    ready_in = connector.get_input("Subscriber::ReadyStatus")
    commands_in = connector.get_input("Subscriber::VehicleCommandTrajectory")
    period_ns = args.period_ms * 1_000_000

    lab_rti.wait_matched(lists_in, "publications", "the emulator's vehicleStateList writer", deadline)
    lab_rti.wait_matched(triggers_in, "publications", "the emulator's systemTrigger writer", deadline)
    log(NAME, "matched the emulator's writers")
    if args.ready_file:
        with open(args.ready_file, "w") as f:
            f.write("matched\n")

    # Collect until the stop trigger.
    lists, starts, announced, commands = {}, set(), {}, []
    stop = None
    while stop is None:
        deadline.check(f"the stop trigger (ticks seen: {len(lists)})")
        try:
            connector.wait(deadline.left_ms(50))
        except Exception:
            pass
        for trigger in lab_rti.take(triggers_in):
            stamp = trigger["next_start"]["nanoseconds"]
            if stamp == lab_rti.STOP_NS:
                stop = stamp
            else:
                starts.add(stamp)
        for state_list in lab_rti.take(lists_in):
            lists.setdefault(state_list["t_now"], state_list)
        for status in lab_rti.take(ready_in):
            announced[status["source_id"]] = status["next_start_stamp"]["nanoseconds"]
        commands.extend(lab_rti.take(commands_in))
    # Lists and commands sent just before the stop may still be in flight.
    time.sleep(0.2)
    for state_list in lab_rti.take(lists_in):
        lists.setdefault(state_list["t_now"], state_list)
    commands.extend(lab_rti.take(commands_in))
    log(NAME, f"stop trigger received; {len(lists)} ticks, {len(commands)} trajectories")

    # The triggers.
    if len(starts) != 1:
        fail(f"expected one start stamp (re-sent unchanged), got {sorted(starts)}")
    (start_ns,) = starts
    if abs(start_ns - time.time_ns()) > CLOCK_SLACK_NS:
        fail(f"start trigger {start_ns} is not a stamp of this machine's clock ({time.time_ns()})")

    # The lists: every tick, on the grid, sane states.
    expected = [start_ns + k * period_ns for k in range(args.ticks)]
    if sorted(lists) != expected:
        missing = [(t - start_ns) / period_ns for t in expected if t not in lists]
        extra = [(t - start_ns) / period_ns for t in lists if t not in expected]
        fail(f"ticks (in periods from the start) missing: {missing}, unexpected: {extra}")
    previous = None
    for k, t_now in enumerate(expected):
        poses = check_list(lists[t_now], k, t_now, ids, args.period_ms)
        if previous is not None:
            for vid in ids:
                step = math.hypot(poses[vid][0] - previous[vid][0], poses[vid][1] - previous[vid][1])
                if step > MAX_SPEED_MPS * period_ns / 1e9:
                    fail(f"tick {k}: vehicle {vid} jumped {step:.3f} m in one period")
        previous = poses

    # What the planner published, as far as it was seen: the emulator's lock-step run can end
    # before this participant has discovered the planner's participant, which joined later.
    for source, stamp in announced.items():
        if not source.startswith("hlc_") or not isinstance(stamp, int):
            fail(f"ReadyStatus {source!r} with next_start_stamp {stamp!r}")
    answered = set()
    for command in commands:
        t_now = command["header"]["create_stamp"]["nanoseconds"]
        if t_now not in lists:
            fail(f"trajectory of vehicle {command['vehicle_id']} for {t_now}, which was no tick")
        lab_rti.check_trajectory(command, t_now, period_ns, set(ids))
        answered.add((t_now, command["vehicle_id"]))

    return {
        "start_ns": start_ns,
        "stop_ns": stop,
        "ticks_ns": expected,
        "announced": announced,
        "trajectories": len(answered),
        # x, y [m], speed [m/s] and the state's age at the last tick [s]: the driver records
        # each state moved by its velocity over its age.
        "final_poses": {str(v): previous[v] for v in ids},
    }


# The lab's vehicles stamp their states valid_after = create + 60 ms; the middleware lists
# only valid ones.
STATE_VALID_AFTER_NS = 60_000_000


def check_list(state_list, k, t_now, ids, period_ms):
    """Checks one VehicleStateList; returns each vehicle's (x, y, speed, age at the tick [s])."""
    where = f"tick {k}"
    if state_list["period_ms"] != period_ms:
        fail(f"{where}: period_ms {state_list['period_ms']}, expected {period_ms}")
    if list(state_list["active_vehicle_ids"]) != ids:
        fail(f"{where}: active_vehicle_ids {state_list['active_vehicle_ids']}, expected {ids}")
    states = state_list["state_list"]
    if sorted(s["vehicle_id"] for s in states) != sorted(ids):
        fail(f"{where}: states of vehicles {[s['vehicle_id'] for s in states]}, expected {ids}")
    poses = {}
    for s in states:
        vid = s["vehicle_id"]
        header, pose = s["header"], s["pose"]
        create, valid_after = header["create_stamp"]["nanoseconds"], header["valid_after_stamp"]["nanoseconds"]
        if valid_after != create + STATE_VALID_AFTER_NS or valid_after > t_now:
            fail(f"{where}: vehicle {vid} stamped {header}: not valid_after = create + 60 ms <= the tick {t_now}")
        if not lab_rti.finite(pose["x"], pose["y"], pose["yaw"], s["speed"], s["steering_servo"]):
            fail(f"{where}: vehicle {vid}: non-finite state {s}")
        if not (lab_rti.MAP_X[0] <= pose["x"] <= lab_rti.MAP_X[1] and lab_rti.MAP_Y[0] <= pose["y"] <= lab_rti.MAP_Y[1]):
            fail(f"{where}: vehicle {vid} at ({pose['x']:.3f}, {pose['y']:.3f}), off the lab's map")
        if abs(s["speed"]) > MAX_SPEED_MPS:
            fail(f"{where}: vehicle {vid} at {s['speed']:.2f} m/s")
        if abs(s["steering_servo"]) > 1.0:
            fail(f"{where}: vehicle {vid} steering servo {s['steering_servo']} outside [-1, 1]")
        if s["is_real"]:
            fail(f"{where}: vehicle {vid} claims to be a real vehicle")
        poses[vid] = (pose["x"], pose["y"], s["speed"], (t_now - create) / 1e9)
    return poses


if __name__ == "__main__":
    lab_rti.main(run, NAME)
