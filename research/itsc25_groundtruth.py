# Q2: the cpmx-comparable rollout in SigmaRL 1.4.0's OWN environment, policy and CBF filter.
#
# Env/policy/filter are built exactly as evaluation_itsc25.py builds them (CBF_MARL_Evaluation(...).parameters ->
# mappo_cavs(parameters) -> env.rollout(..., cbf_controllers=...), break_when_any_done=False), with the published
# itsc25 checkpoint. Differences, all outside SigmaRL's algorithmic code:
#   * start: SigmaRL's own `ref_path_idx` parameter fixes the reference path (0..9, index into
#     map.parser.reference_paths = long_term_all); `ScenarioRoadTraffic._reset_init_state` is WRAPPED (the original
#     runs first) and, at the very first reset only, the agent's pos/rot/speed/vel/steering are overwritten with the
#     centre-line point at arc length 0.5 m (linear interpolation between the parsed centre-line vertices), heading =
#     direction of that centre-line segment, speed 0, steering 0 (cpmx's default start). "First reset" = the reset
#     env.rollout() does itself (the one at env construction is left random); the script asserts the logged
#     initial pos equals the placed one. Everything derived from the
#     pose (distances, vertices, short-term path, observations, CBF observation) is then computed by SigmaRL's reset.
#   * variant "noreset" (cpmx-comparable): parameters.reset_agent_fixed_duration = 0 (no 15-s env reset),
#     parameters.max_steps = 1000 (so the 600-step rollout never hits SigmaRL's max-steps reset) and
#     `reset_world_at` is WRAPPED to drop single-agent resets (the testing-mode reset on collision).
#   * variant "sigmarl": SigmaRL's evaluation settings untouched (15-s env reset, agent reset on collision,
#     max_steps 600 -> resets at step 599); only the first start is placed as above. Later resets are SigmaRL's
#     random ones (random point on path `ref_path_idx`, random speed).
#   * rendering/video off (is_save_simulation_video False, no callback).
# Per step the post-step ("next") info is logged: SigmaRL's is_collision_with_lanelets (interX of the car's rectangle
# with the path's left/right_boundary_shared), pos, rot, vel, nominal and filtered action. num_fail per run is read from
# the controller.
#
# Run: cd /tmp/gt_eval && nice -n 10 /work/main/target/python-venv/bin/python research/itsc25_groundtruth.py \
#          [--variants noreset,sigmarl] [--paths 0-9] [--cbf 1] [--radius 0.05] [--out /work/notes/itsc25_groundtruth.json]
import os, sys, json, time, argparse, math

DEPS = os.environ.get("SIGMARL_PYDEPS", "/tmp/sigmarl-pydeps")
SRC = os.environ.get("SIGMARL_SRC", "/tmp/gt140")
PINS = os.environ.get("SIGMARL_PINS", "/tmp/sigmarl-pins")
sys.path[:0] = [PINS, DEPS, SRC]
import torch

torch.set_num_threads(1)
torch.set_num_interop_threads(1)
import matplotlib

matplotlib.use("Agg")
import pyglet

pyglet.options["headless"] = True
import numpy as np

import sigmarl.evaluation_itsc25 as ev
from sigmarl.mappo_cavs import mappo_cavs
from sigmarl.scenarios.road_traffic import ScenarioRoadTraffic
from sigmarl.cbf_qp import CBFQP
import cvxpy as cp

ap = argparse.ArgumentParser()
ap.add_argument("--variants", default="noreset,sigmarl")
ap.add_argument("--paths", default="0-9")
ap.add_argument("--cbf", default="1")
ap.add_argument("--radius", type=float, default=None, help="override CBFQP.small_circle_radius (sensitivity only)")
ap.add_argument("--steps", type=int, default=600)
ap.add_argument("--arc", type=float, default=0.5)
ap.add_argument("--seed", type=int, default=1)
ap.add_argument("--out", default="/work/notes/itsc25_groundtruth.json")
args = ap.parse_args()
a, b = (args.paths.split("-") + [None])[:2]
paths = list(range(int(a), int(b) + 1)) if b else [int(x) for x in args.paths.split(",")]

# ------------------------------------------------------------------ wrappers (SigmaRL code itself untouched)
STATE = {"place": None, "suppress_agent_reset": False, "agent_resets_suppressed": 0, "agent_resets": 0,
         "placed": None}
_orig_init_state = ScenarioRoadTraffic._reset_init_state
_orig_reset_world_at = ScenarioRoadTraffic.reset_world_at


def point_at_arc(center_line, s):
    c = center_line.double()
    seg = (c[1:] - c[:-1]).norm(dim=-1)
    cum = torch.cat([torch.zeros(1, dtype=torch.float64), seg.cumsum(0)])
    k = int(torch.searchsorted(cum, torch.tensor([s], dtype=torch.float64)).item()) - 1
    k = max(0, min(k, len(seg) - 1))
    t = (s - cum[k]) / seg[k]
    p = c[k] + t * (c[k + 1] - c[k])
    d = c[k + 1] - c[k]
    yaw = math.atan2(d[1].item(), d[0].item())
    return p.float(), yaw, k, float(cum[k]), float(seg[k])


def _reset_init_state(self, env_i, i_agent, *a, **kw):
    ref_path, path_id = _orig_init_state(self, env_i, i_agent, *a, **kw)
    if STATE["place"] is not None:
        s = STATE["place"]
        STATE["place"] = None  # only the very first reset
        agent = self.world.agents[int(i_agent)]
        p, yaw, k, cum_k, seg_k = point_at_arc(ref_path["center_line"], s)
        dev = self.world.device
        agent.set_pos(p.to(dev), batch_index=env_i)
        agent.set_rot(torch.tensor([yaw], dtype=torch.float32, device=dev), batch_index=env_i)
        zero = torch.zeros(1, dtype=torch.float32, device=dev)
        agent.set_steering(zero, batch_index=env_i)
        agent.set_sideslip_angle(zero, batch_index=env_i)
        agent.set_speed(zero, batch_index=env_i)
        agent.set_vel(torch.zeros(2, dtype=torch.float32, device=dev), batch_index=env_i)
        self.ref_paths_agent_related.point_id[env_i, i_agent] = k
        STATE["placed"] = dict(path_id=int(path_id), arc=s, pos=p.tolist(), yaw=yaw, seg_index=k,
                               vertex_yaw=float(ref_path["center_line_yaw"][k]),
                               n_center_points=int(ref_path["center_line"].shape[0]), seg_len=seg_k,
                               is_loop=bool(ref_path["is_loop"]))
    return ref_path, path_id


def reset_world_at(self, env_index=None, agent_index=None):
    if agent_index is not None:
        STATE["agent_resets"] += 1
        if STATE["suppress_agent_reset"]:
            STATE["agent_resets_suppressed"] += 1
            return
    return _orig_reset_world_at(self, env_index=env_index, agent_index=agent_index)


ScenarioRoadTraffic._reset_init_state = _reset_init_state
ScenarioRoadTraffic.reset_world_at = reset_world_at

# ------------------------------------------------------------------ timing wrappers (Q3); perf_counter, 1 torch thread
TIMES = {"call": [], "pseudo_dis": [], "prob_solve": [], "scs_solve": [], "scs_setup": [], "status": [],
         "call_cpu": [], "prob_solve_cpu": []}  # *_cpu: time.thread_time (CPU time of this thread, robust to load)
_orig_qp = CBFQP.solve_decentralized_cbf_qp
_orig_prob_solve = cp.Problem.solve


def timed_qp(self, tensordict):
    c0 = time.thread_time()
    t0 = time.perf_counter()
    out = _orig_qp(self, tensordict)
    TIMES["call"].append(time.perf_counter() - t0)
    TIMES["call_cpu"].append(time.thread_time() - c0)
    TIMES["pseudo_dis"].append(self.time_pseudo_dis)  # SigmaRL's own time.time() sum over its get_distance calls
    return out


def timed_prob_solve(self, *a, **kw):
    c0 = time.thread_time()
    t0 = time.perf_counter()
    out = _orig_prob_solve(self, *a, **kw)
    TIMES["prob_solve"].append(time.perf_counter() - t0)  # cvxpy canonicalisation + SCS + unpacking
    TIMES["prob_solve_cpu"].append(time.thread_time() - c0)
    st = self.solver_stats
    TIMES["scs_solve"].append(st.solve_time if st is not None and st.solve_time is not None else float("nan"))
    TIMES["scs_setup"].append(st.setup_time if st is not None and st.setup_time is not None else float("nan"))
    TIMES["status"].append(self.status)
    return out


CBFQP.solve_decentralized_cbf_qp = timed_qp
cp.Problem.solve = timed_prob_solve


def timing_summary():
    out = {}
    for k in ("call", "pseudo_dis", "prob_solve", "scs_solve", "scs_setup", "call_cpu", "prob_solve_cpu"):
        v = np.array(TIMES[k], dtype=float)
        out[k] = dict(n=int(len(v)), mean_ms=float(np.nanmean(v) * 1e3) if len(v) else None,
                      median_ms=float(np.nanmedian(v) * 1e3) if len(v) else None,
                      p90_ms=float(np.nanpercentile(v, 90) * 1e3) if len(v) else None)
    if TIMES["call"]:
        rest = np.array(TIMES["call"]) - np.array(TIMES["prob_solve"])
        out["call_minus_prob_solve"] = dict(mean_ms=float(rest.mean() * 1e3), median_ms=float(np.median(rest) * 1e3))
        rest = np.array(TIMES["call_cpu"]) - np.array(TIMES["prob_solve_cpu"])
        out["call_minus_prob_solve_cpu"] = dict(mean_ms=float(rest.mean() * 1e3), median_ms=float(np.median(rest) * 1e3))
    return out


# ------------------------------------------------------------------ one rollout
def rollout(path_id, variant, is_using_cbf):
    evaluation = ev.CBF_MARL_Evaluation(path="checkpoints/itsc25", n_agents=1, is_using_cbf=is_using_cbf,
                                        scenario_type="CPM_entire", random_seed=args.seed,
                                        n_circles_approximate_vehicle=3, is_load_out_td=False, obs_noise_level=0.0)
    p = evaluation.parameters
    p.ref_path_idx = path_id
    p.is_save_simulation_video = False
    if variant == "noreset":
        p.reset_agent_fixed_duration = 0
        p.max_steps = 1000
        STATE["suppress_agent_reset"] = True
    else:
        STATE["suppress_agent_reset"] = False
    STATE.update(place=None, agent_resets=0, agent_resets_suppressed=0, placed=None)
    for v in TIMES.values():
        v.clear()
    env, policy, priority_module, cbf_controllers, p = mappo_cavs(parameters=p)
    if cbf_controllers is not None and args.radius is not None:
        for row in cbf_controllers:
            for c in row:
                c.small_circle_radius = args.radius
    STATE.update(place=args.arc, agent_resets=0, agent_resets_suppressed=0)  # consumed by the rollout's own reset
    t0 = time.time()
    out_td, _ = env.rollout(max_steps=args.steps, policy=policy, priority_module=priority_module, callback=None,
                            auto_cast_to_device=True, break_when_any_done=False, is_save_simulation_video=False,
                            cbf_controllers=cbf_controllers)
    wall = time.time() - t0
    nxt = out_td["next", "agents", "info"]
    coll = nxt["is_collision_with_lanelets"][0, :, 0].reshape(-1).bool().numpy()
    pos = nxt["pos"][0, :, 0].numpy()
    pos0 = out_td["agents", "info", "pos"][0, 0, 0].numpy()
    all_pos = np.concatenate([pos0[None], pos], 0)
    step_len = np.linalg.norm(np.diff(all_pos, axis=0), axis=-1)  # length driven in step t (ends at pos[t])
    # a reset teleports the car: don't count the jump as distance driven
    step_len = np.where(step_len > 0.2, 0.0, step_len)
    dist = float(step_len.sum())
    dist_coll = float(step_len[coll].sum())
    speed = np.linalg.norm(nxt["vel"][0, :, 0].numpy(), axis=-1)
    assert STATE["place"] is None and STATE["placed"] is not None
    assert np.allclose(pos0, STATE["placed"]["pos"], atol=1e-6), (pos0, STATE["placed"])
    res = dict(path=path_id, variant=variant, cbf=is_using_cbf, radius=args.radius, steps=int(len(coll)),
               placed=STATE["placed"],
               collision_steps=[int(i) + 1 for i in np.nonzero(coll)[0]],  # step numbers 1..600 (post-step state)
               first_collision_step=(int(np.nonzero(coll)[0][0]) + 1) if coll.any() else None,
               n_collision_steps=int(coll.sum()), distance_m=dist, distance_in_collision_m=dist_coll,
               per_100m=100 * dist_coll / dist if dist > 0 else None, mean_speed=float(speed.mean()),
               agent_resets_requested=STATE["agent_resets"], agent_resets_suppressed=STATE["agent_resets_suppressed"],
               num_fail=env.num_fail, infeasibility_rate=env.num_fail / len(coll) if is_using_cbf else None,
               mean_time_cbf=float(np.mean(env.time_cbf)) if env.time_cbf else None, wall_s=wall)
    if is_using_cbf:
        res["cbf_action_vs_nominal_max_abs"] = [
            float((nxt["cbf_action_vel"] - nxt["nominal_action_vel"]).abs().max()),
            float((nxt["cbf_action_steer"] - nxt["nominal_action_steer"]).abs().max())]
    res["timing"] = timing_summary()
    res["raw_times_s"] = {k: [round(x, 7) for x in TIMES[k]] for k in ("call", "pseudo_dis", "prob_solve", "scs_solve", "call_cpu",
                                                                  "prob_solve_cpu")}
    res["qp_status"] = list(TIMES["status"])
    res["trace"] = dict(pos=pos.round(5).tolist(), rot=nxt["rot"][0, :, 0, 0].numpy().round(5).tolist(),
                        coll=coll.astype(int).tolist())
    if is_using_cbf:
        for k in ("nominal_action_vel", "nominal_action_steer", "cbf_action_vel", "cbf_action_steer"):
            res["trace"][k] = nxt[k][0, :, 0].reshape(-1).detach().numpy().round(5).tolist()
    res["trace"]["speed"] = speed.round(5).tolist()
    return res


results = []
if os.path.exists(args.out):
    results = json.load(open(args.out))
for variant in args.variants.split(","):
    for cbf in [c == "1" for c in args.cbf.split(",")]:
        for pid in paths:
            r = rollout(pid, variant, cbf)
            results = [x for x in results if not (x["path"] == pid and x["variant"] == variant and x["cbf"] == cbf
                                                  and x.get("radius") == args.radius)]
            results.append(r)
            print(json.dumps({k: v for k, v in r.items() if k not in ("trace", "collision_steps", "raw_times_s")}),
                  flush=True)
            json.dump(results, open(args.out, "w"))
