# Where does cpmx's closed loop first depart from SigmaRL 1.4.0's? Step-by-step trace of SigmaRL's OWN env
# (built exactly as itsc25_groundtruth.py builds it: CBF_MARL_Evaluation -> mappo_cavs -> env.rollout, the same
# "noreset" placing of the start at arc length 0.5 m of path k with speed 0 and steering 0), logging per step:
#   * the state the env integrates FROM and TO (wrapping WorldCustom.step: x0 = [x, y, yaw, speed, steering],
#     the (speed, steering) action the env receives, the (a, omega) it integrates after its own clamps, x1),
#   * with the filter: the state the filter reads (cbf_observation -> state_agent), the nominal action and the
#     filtered action (wrapping CBFQP.solve_decentralized_cbf_qp; the original runs unchanged), the QP status.
# Option --integrator:
#   dopri5  (default) SigmaRL 1.4.0's own KinematicBicycleModel.step: torchdiffeq odeint dopri5, rtol=atol=1e-8,
#           5 output ticks over dt (dynamics.py:120-170).
#   euler1  KinematicBicycleModel.step REPLACED by one explicit Euler step of the same ode (right-hand side at the
#           old state), float32 - the integration cpmx's KinematicBicycle::step uses (interpreter/vehicle/src/bicycle.rs).
#   euler5  torchdiffeq odeint method="euler" with the same 5 ticks (what SigmaRL 1.5.0+ does), for reference.
# Nothing else in SigmaRL is changed.
#
# Run: cd /tmp/gt_eval && nice -n 10 /work/main/target/python-venv/bin/python research/itsc25_divergence.py \
#          --paths 0,5 --cbf 0 --integrator dopri5 --out /tmp/div/sig_dopri5_cbf0.json
import os, sys, json, time, argparse, math

sys.path[:0] = ["/tmp/sigmarl-pins", "/tmp/sigmarl-pydeps", "/tmp/gt140"]
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
from sigmarl.helper_training import WorldCustom
from sigmarl.dynamics import KinematicBicycleModel
from torchdiffeq import odeint
import cvxpy as cp

ap = argparse.ArgumentParser()
ap.add_argument("--paths", default="0")
ap.add_argument("--cbf", default="0")
ap.add_argument("--integrator", default="dopri5", choices=["dopri5", "euler1", "euler5"])
ap.add_argument("--steps", type=int, default=600)
ap.add_argument("--arc", type=float, default=0.5)
ap.add_argument("--steer-high", type=float, default=None,
                help="override the TanhNormal's steering half-range (SigmaRL 1.4.0: pi/4); 0.54105204 = cpmx's ActionHead")
ap.add_argument("--lag", type=int, default=0,
                help="1: agent 0's corner-to-boundary distances from the PREVIOUS step's corners (cpmx's "
                     "agent0_boundary_lag, observation.rs BoundaryCorners::LaggedForFirstAgent); SigmaRL 1.4.0 has none")
ap.add_argument("--solver", default="SCS", help="SCS (SigmaRL's) or CLARABEL (the exact QP, to tell solver error "
                                                   "from loop differences)")
ap.add_argument("--out", required=True)
args = ap.parse_args()
paths = [int(x) for x in args.paths.split(",")]

STATE = {"place": None}
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
    return p.float(), math.atan2(d[1].item(), d[0].item()), k


def _reset_init_state(self, env_i, i_agent, *a, **kw):
    ref_path, path_id = _orig_init_state(self, env_i, i_agent, *a, **kw)
    if STATE["place"] is not None:
        s = STATE["place"]
        STATE["place"] = None
        agent = self.world.agents[int(i_agent)]
        p, yaw, k = point_at_arc(ref_path["center_line"], s)
        dev = self.world.device
        agent.set_pos(p.to(dev), batch_index=env_i)
        agent.set_rot(torch.tensor([yaw], dtype=torch.float32, device=dev), batch_index=env_i)
        zero = torch.zeros(1, dtype=torch.float32, device=dev)
        agent.set_steering(zero, batch_index=env_i)
        agent.set_sideslip_angle(zero, batch_index=env_i)
        agent.set_speed(zero, batch_index=env_i)
        agent.set_vel(torch.zeros(2, dtype=torch.float32, device=dev), batch_index=env_i)
        self.ref_paths_agent_related.point_id[env_i, i_agent] = k
    return ref_path, path_id


def reset_world_at(self, env_index=None, agent_index=None):
    if agent_index is not None:
        return  # "noreset": drop the testing-mode single-agent reset on collision
    return _orig_reset_world_at(self, env_index=env_index, agent_index=agent_index)


ScenarioRoadTraffic._reset_init_state = _reset_init_state
ScenarioRoadTraffic.reset_world_at = reset_world_at

# ------------------------------------------------------------------ integrator variants
_orig_dyn_step = KinematicBicycleModel.step


def euler1_step(self, x0, u, dt, tick_per_step=5):
    dx = self.ode(0.0, x0, u)
    x = x0 + dt * dx
    x[..., 4] = (x[..., 4] + torch.pi) % (2 * torch.pi) - torch.pi
    beta = torch.atan(self.l_r / self.l_wb * torch.tan(x[:, 4]))
    course = x[:, 2] + beta
    vel = torch.stack((x[:, 3] * torch.cos(course), x[:, 3] * torch.sin(course)), dim=1)
    return x, beta, vel


def euler5_step(self, x0, u, dt, tick_per_step=5):
    t = torch.linspace(0, dt, steps=tick_per_step + 1, device=self.device)
    x = odeint(lambda t, x: self.ode(t, x, u), x0, t, rtol=1e-8, atol=1e-8, method="euler")
    x[..., 4] = (x[..., 4] + torch.pi) % (2 * torch.pi) - torch.pi
    x = x[-1]
    beta = torch.atan(self.l_r / self.l_wb * torch.tan(x[:, 4]))
    course = x[:, 2] + beta
    vel = torch.stack((x[:, 3] * torch.cos(course), x[:, 3] * torch.sin(course)), dim=1)
    return x, beta, vel


if args.integrator == "euler1":
    KinematicBicycleModel.step = euler1_step
elif args.integrator == "euler5":
    KinematicBicycleModel.step = euler5_step

# ------------------------------------------------------------------ cpmx's agent-0 boundary lag, emulated
from sigmarl.helper_scenario import get_perpendicular_distances

_orig_before_rew = ScenarioRoadTraffic._update_state_before_rewarding


def lagged_before_rewarding(self, agent, agent_index):
    prev = self.vertices[:, 0].clone() if agent_index == 0 else None
    _orig_before_rew(self, agent, agent_index)
    if agent_index == 0:
        r = self.ref_paths_agent_related
        for c_i in range(4):
            self.distances.left_boundaries[:, 0, c_i + 1], _ = get_perpendicular_distances(
                point=prev[:, c_i, :], polyline=r.left_boundary[:, 0], n_points_long_term=r.n_points_left_b[:, 0])
            self.distances.right_boundaries[:, 0, c_i + 1], _ = get_perpendicular_distances(
                point=prev[:, c_i, :], polyline=r.right_boundary[:, 0], n_points_long_term=r.n_points_right_b[:, 0])


if args.lag:
    ScenarioRoadTraffic._update_state_before_rewarding = lagged_before_rewarding

# ------------------------------------------------------------------ tracing wrappers
TRACE = {"env": [], "cbf": []}
_orig_world_step = WorldCustom.step
_orig_ode = KinematicBicycleModel.ode
LAST_U = {}


def traced_dyn_step(fn):
    def w(self, x0, u, dt, tick_per_step=5):
        LAST_U["x0"] = x0.detach().clone()
        LAST_U["u"] = u.detach().clone()
        return fn(self, x0, u, dt, tick_per_step)
    return w


KinematicBicycleModel.step = traced_dyn_step(KinematicBicycleModel.step)


def world_step(self):
    ag = self.agents[0]
    act = ag.action.u[0].detach().clone().tolist()  # (speed, steering) as received, before the env's clamps
    _orig_world_step(self)
    x0 = LAST_U["x0"][0].tolist()
    u = LAST_U["u"][0].tolist()
    x1 = torch.cat([ag.state.pos, ag.state.rot, ag.state.speed, ag.state.steering], -1)[0].tolist()
    TRACE["env"].append(dict(x0=x0, action=act, u=u, x1=x1, vel1=ag.state.vel[0].tolist()))


WorldCustom.step = world_step

_orig_qp = CBFQP.solve_decentralized_cbf_qp
_orig_prob_solve = cp.Problem.solve
QP = {}


def prob_solve(self, *a, **kw):
    if args.solver != "SCS":
        kw["solver"] = getattr(cp, args.solver)
    out = _orig_prob_solve(self, *a, **kw)
    QP["status"] = self.status
    return out


cp.Problem.solve = prob_solve


def traced_qp(self, tensordict):
    out = _orig_qp(self, tensordict)
    st = self.state_agent_list[self.agent_idx]
    TRACE["cbf"].append(dict(
        state=[float(v) for v in st[:5]],
        nominal=[float(v) for v in tensordict[("agents", "info", "nominal_action")][self.env_idx, self.agent_idx]],
        u_nom=[float(v) for v in self.u_nominal_agent_list[self.agent_idx].flatten()],
        action=[float(v) for v in tensordict[("agents", "action")][self.env_idx, self.agent_idx]],
        status=QP.get("status")))
    return out


CBFQP.solve_decentralized_cbf_qp = traced_qp


def rollout(path_id, is_using_cbf):
    evaluation = ev.CBF_MARL_Evaluation(path="checkpoints/itsc25", n_agents=1, is_using_cbf=is_using_cbf,
                                        scenario_type="CPM_entire", random_seed=1,
                                        n_circles_approximate_vehicle=3, is_load_out_td=False, obs_noise_level=0.0)
    p = evaluation.parameters
    p.ref_path_idx = path_id
    p.is_save_simulation_video = False
    p.reset_agent_fixed_duration = 0
    p.max_steps = 1000
    env, policy, priority_module, cbf_controllers, p = mappo_cavs(parameters=p)
    if args.steer_high is not None:
        n = 0
        for m in policy.modules():
            dk = getattr(m, "distribution_kwargs", None)
            if dk and "high" in dk:
                hi, lo = dk["high"].clone(), dk["low"].clone()
                hi[..., 1], lo[..., 1] = args.steer_high, -args.steer_high
                dk["high"], dk["low"] = hi, lo
                n += 1
        assert n >= 1, "no TanhNormal found"
    for v in TRACE.values():
        v.clear()
    STATE["place"] = args.arc
    out_td, _ = env.rollout(max_steps=args.steps, policy=policy, priority_module=priority_module, callback=None,
                            auto_cast_to_device=True, break_when_any_done=False, is_save_simulation_video=False,
                            cbf_controllers=cbf_controllers)
    # the policy's own observation and action per step (before the filter)
    obs_key = ("agents", "observation") if ("agents", "observation") in out_td.keys(True) else None
    res = dict(path=path_id, cbf=is_using_cbf, integrator=args.integrator, steer_high=args.steer_high, lag=args.lag, solver=args.solver, env=list(TRACE["env"]),
               cbf_trace=list(TRACE["cbf"]))
    if obs_key is not None:
        res["obs"] = out_td[obs_key][0, :, 0].numpy().tolist()
    if is_using_cbf:
        res["num_fail"] = env.num_fail
    return res


results = []
for cbf in [c == "1" for c in args.cbf.split(",")]:
    for pid in paths:
        t0 = time.time()
        r = rollout(pid, cbf)
        print(f"path {pid} cbf {cbf} {args.integrator}: {len(r['env'])} env steps, {time.time() - t0:.0f} s",
              flush=True)
        results.append(r)
os.makedirs(os.path.dirname(args.out), exist_ok=True)
json.dump(results, open(args.out, "w"))
