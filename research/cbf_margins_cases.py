# Reference cases for cpmx's reimplementation of SigmaRL's ITSC 2026 "CBF-informed reward", computed by SigmaRL's OWN
# code at tag 1.6.0 (= 4c8032dd6c6d9d417064236c20031d12de27734d), unmodified and imported as a package:
#   CBFQP.update_qp (is_solve_qp=False) -> compute_nominal_cbf_constraint_margins -> compute_cbf_violation_rewards_from_margins
#   (sigmarl/cbf_qp.py l.2534-2804), with rl_action_to_u, linearized_center_kinematics_coeffs, ttcbf_*_affine_coeffs,
#   estimate_agent_2_lane_safety_margin, PseudoDistance.get_distance, KinematicBicycleModel.ode all real.
# Mocked (SimpleNamespace): env.base_env.scenario_name with .parameters (a REAL sigmarl Parameters from
# sigmarl/config.json, overridden as main_training.py l.69-106 does), .world.agents[i].state.{pos,rot,speed,steering},
# .map_pseudo_distance (a real PseudoDistance made with __new__, .reference_paths = {0: straight, 1: arc}) and
# .reward_info (a real RewardInfo.zeros). The tensordict is a real TensorDict. SigmaRL's methods are wrapped on the
# instance (not changed) to record intermediate values.
# See research/cbf-margins-cases.md. Setup and run (from /work/main):
#   mkdir -p /tmp/sigmarl160 && git --git-dir=/work/.mirror/bassamlab+SigmaRL/repo archive 4c8032d | tar -x -C /tmp/sigmarl160
#   target/python-venv/bin/python -m pip install --no-deps --target /tmp/sigmarl160-pydeps cvxpy==1.7.2 scs==3.2.7 \
#       clarabel==0.9.0 osqp scikit-learn==1.6.0 joblib threadpoolctl termcolor==3.3.0 torchdiffeq==0.2.5
#   target/python-venv/bin/python -m pip install --no-deps --target /tmp/np1264 numpy==1.26.4
#   target/python-venv/bin/python -m pip install --no-deps --target /tmp/np23 "numpy==2.3.*"
#   nice target/python-venv/bin/python research/cbf_margins_cases.py [out.json]
# The driver runs every case in subprocesses: with numpy 1.26.4 (SigmaRL 1.6.0's pin, legacy pre-NEP-50 promotion;
# the PRIMARY reference), with numpy 2.3.x (NEP 50), and once with the venv's numpy (2.4.6), where SigmaRL's
# compute_nominal_cbf_constraint_margins raises (float() of a (1,1) array, cbf_qp.py:2677); that error is recorded.
import sys, os, json, math, hashlib, platform, subprocess
from types import SimpleNamespace

SRC = os.environ.get("SIGMARL_SRC", "/tmp/sigmarl160")
DEPS = os.environ.get("SIGMARL_PYDEPS", "/tmp/sigmarl160-pydeps")
NP1 = os.environ.get("SIGMARL_NP1", "/tmp/np1264")
NP2 = os.environ.get("SIGMARL_NP2", "/tmp/np23")  # numpy 2.3.x: numpy >= 2.4 makes SigmaRL's float(1x1 array) raise
HERE = os.path.dirname(os.path.abspath(__file__))


# ====================================================================== worker (runs under one numpy version)
def worker():
    sys.path[:0] = [p for p in os.environ.get("EXTRA_PYPATH", "").split(":") if p] + [DEPS, SRC]
    import numpy as np
    import torch
    torch.set_num_threads(1)
    from tensordict import TensorDict
    from sigmarl.cbf_qp import CBFQP
    from sigmarl.pseudo_distance import PseudoDistance
    from sigmarl.helper_common import Parameters
    from sigmarl.helper_scenario import RewardInfo, compute_pseudo_tangent_vector
    import warnings
    warnings.simplefilter("ignore")  # numpy's "ndim>0 array to scalar" DeprecationWarning in float(A @ u)

    def fl(x):
        return float(x.item() if isinstance(x, torch.Tensor) else x)

    def fl_list(a):
        if isinstance(a, torch.Tensor):
            a = a.detach().cpu().numpy()
        return np.asarray(a).astype(np.float64).tolist()

    # ------------------------------------------------------------------ lanes (float32 polylines)
    xs = np.linspace(-2.0, 2.0, 81)
    straight_l = torch.tensor(np.stack([xs, np.full_like(xs, 0.15)], 1), dtype=torch.float32)
    straight_r = torch.tensor(np.stack([xs, np.full_like(xs, -0.15)], 1), dtype=torch.float32)
    th = -1.5 + 0.05 * np.arange(61)  # driven counter-clockwise: LEFT = inner circle r 0.85, RIGHT = outer r 1.15
    mk = lambda r: torch.tensor(np.stack([r * np.cos(th), r * np.sin(th)], 1), dtype=torch.float32)
    arc_l, arc_r = mk(0.85), mk(1.15)

    def ref_path(left, right):  # as parse_map_base.py:100-116 fills the *_shared entries
        return {"left_boundary_shared": left, "right_boundary_shared": right,
                "left_boundary_shared_pseudo_vector": compute_pseudo_tangent_vector(left),
                "right_boundary_shared_pseudo_vector": compute_pseudo_tangent_vector(right)}

    REF = {0: ref_path(straight_l, straight_r), 1: ref_path(arc_l, arc_r)}

    def make_params(n):
        p = Parameters.from_json(os.path.join(SRC, "sigmarl", "config.json"))  # dt 0.1, is_obs_noise false
        # as main_training.py l.69-106 (ITSC26 training), rew_method "cbf", --h_nom 0.1
        p.scenario_type = "cpm_mixed"
        p.n_agents = n
        p.is_using_centralized_cbf = True
        p.is_using_cbf_testing = False
        p.is_using_prioritized_marl = False
        p.is_apply_cbf_action = False
        p.is_solve_qp = False
        p.h_nom = 0.1
        p.is_testing_mode = False
        p.is_using_cbf_training = True
        p.rew_method = "cbf"
        return p

    def run_case(case):
        n = len(case["states"])
        params = make_params(n)
        assert params.dt == 0.1 and params.n_circles_approximate_vehicle == 3 and not params.is_obs_noise
        agents = []
        for s in case["states"]:
            st = torch.tensor([s], dtype=torch.float32)  # env batch of 1
            agents.append(SimpleNamespace(state=SimpleNamespace(pos=st[:, 0:2].clone(), rot=st[:, 2:3].clone(),
                                                                speed=st[:, 3:4].clone(), steering=st[:, 4:5].clone())))
        pd = PseudoDistance.__new__(PseudoDistance)  # __init__ needs a MapManager; get_distance reads .reference_paths
        pd.reference_paths = REF
        scen = SimpleNamespace(parameters=params, map_pseudo_distance=pd, world=SimpleNamespace(agents=agents),
                               reward_info=RewardInfo.zeros(1, n))
        env = SimpleNamespace(base_env=SimpleNamespace(scenario_name=scen))
        cbf = CBFQP(env=env, env_idx=0, agent_idx=None)
        td = TensorDict({"agents": TensorDict({
            "action": torch.tensor([case["actions"]], dtype=torch.float32),
            "info": TensorDict({"path_id": torch.tensor([[case["path_id"]] * n], dtype=torch.int64)}, batch_size=[1, n]),
        }, batch_size=[1, n])}, batch_size=[1])
        action_before = td["agents", "action"].clone()

        rec = {"u": [], "lane": [], "kins": [], "dist": []}
        o_rl = cbf.rl_action_to_u
        def rl_action_to_u(rl_actions, v, steering):
            a_in, v_in, s_in = rl_actions.clone(), v.clone(), steering.clone()
            ra, u = o_rl(rl_actions=rl_actions, v=v, steering=steering)
            rec["u"].append(dict(action_in=fl_list(a_in), v=fl(v_in), v_dtype=str(v_in.dtype), steering=fl(s_in),
                                 action_clamped=fl_list(ra.flatten()), u_float32=fl_list(u.flatten()), u_dtype=str(u.dtype)))
            return ra, u
        cbf.rl_action_to_u = rl_action_to_u
        o_gd = pd.get_distance
        def get_distance(ref_id, pos):
            dl, dr = o_gd(ref_id, pos)
            rec["dist"].append(dict(query=fl_list(pos), left=fl_list(dl), right=fl_list(dr), dtype=str(dl.dtype)))
            return dl, dr
        pd.get_distance = get_distance
        o_est = cbf.estimate_agent_2_lane_safety_margin
        def est(agent_pos, path_id):
            out = o_est(agent_pos, path_id)
            smL, gL, HL, smR, gR, HR = out
            rec["lane"].append(dict(pos=fl_list(agent_pos), path_id=path_id,
                                    smL=fl(smL), gL=fl_list(gL), HL=fl_list(HL), smR=fl(smR), gR=fl_list(gR), HR=fl_list(HR),
                                    types=dict(sm=type(smL).__name__, grad=str(gL.dtype), hess=str(HL.dtype))))
            return out
        cbf.estimate_agent_2_lane_safety_margin = est
        o_kin = cbf.linearized_center_kinematics_coeffs
        def kin(state_agent):
            k = o_kin(state_agent)
            rec["kins"].append(dict(state=fl_list(state_agent), dx=list(k["dx"]), dy=list(k["dy"]),
                                    a_ddx=[a.tolist() for a in k["a_ddx"]], c_ddx=list(k["c_ddx"]),
                                    a_ddy=[a.tolist() for a in k["a_ddy"]], c_ddy=list(k["c_ddy"])))
            return k
        cbf.linearized_center_kinematics_coeffs = kin
        o_m = cbf.compute_nominal_cbf_constraint_margins
        def margins(tensordict, **kw):
            m = o_m(tensordict, **kw)
            rec["margins"] = m
            return m
        cbf.compute_nominal_cbf_constraint_margins = margins
        o_r = cbf.compute_cbf_violation_rewards_from_margins
        def rewards(m):
            r = o_r(m)
            rec["rewards_f64"] = r
            return r
        cbf.compute_cbf_violation_rewards_from_margins = rewards

        cbf.update_qp(td)  # the real entry point the collector calls (helper_training.py:1625)

        ri = scen.reward_info
        # road_traffic.py:1141-1147, per agent, float32 tensors
        cbf_rew = [fl((ri.rew_near_left_lane[:, a] + ri.rew_near_right_lane[:, a] + ri.rew_near_other_agents[:, a]) / 3)
                   for a in range(n)]
        m = rec["margins"]
        nc = params.n_circles_approximate_vehicle
        kins = rec["kins"][:n]  # first pass (lane loop) is one call per agent, in order
        out_agents = []
        for a in range(n):
            circles = []
            for c in range(nc):
                L = rec["lane"][a * nc + c]
                D = rec["dist"][a * nc + c]
                k = kins[a]
                circles.append(dict(center=L["pos"], d_left_9=D["left"], d_right_9=D["right"],
                                    smL=L["smL"], gradL=L["gL"], hessL=L["HL"], smR=L["smR"], gradR=L["gR"], hessR=L["HR"],
                                    vel=[k["dx"][c], k["dy"][c]], a_ddx=k["a_ddx"][c], c_ddx=k["c_ddx"][c],
                                    a_ddy=k["a_ddy"][c], c_ddy=k["c_ddy"][c],
                                    gL_margin=float(m["lane_L_margin"][a, c]), gR_margin=float(m["lane_R_margin"][a, c])))
            out_agents.append(dict(
                state=case["states"][a], action=case["actions"][a], path_id=case["path_id"],
                action_clamped=rec["u"][a]["action_clamped"], u=rec["u"][a]["u_float32"], v_used=rec["u"][a]["v"],
                circles=circles,
                worst_gL=float(np.min(m["lane_L_margin"][a])), worst_gR=float(np.min(m["lane_R_margin"][a])),
                r_L=rec["rewards_f64"][0][a], r_R=rec["rewards_f64"][1][a], r_P=rec["rewards_f64"][2][a],
                r_L_f32=fl(ri.rew_near_left_lane[0, a]), r_R_f32=fl(ri.rew_near_right_lane[0, a]),
                r_P_f32=fl(ri.rew_near_other_agents[0, a]), cbf_reward_f32=cbf_rew[a]))
        pairs = {}
        for (i, j, ci, cj), g in m["pair_margin"].items():
            pairs.setdefault(f"{i}-{j}", [[None] * nc for _ in range(nc)])[ci][cj] = g
        return dict(
            name=case["name"], note=case["note"], lane=["straight", "arc"][case["path_id"]],
            agents=out_agents, pair_g=pairs,
            worst_pair_g={k: min(min(r) for r in v) for k, v in pairs.items()},
            action_tensor_unchanged=bool(torch.equal(action_before, td["agents", "action"])),
            types=dict(lane=rec["lane"][0]["types"], distance=rec["dist"][0]["dtype"], u=rec["u"][0]["u_dtype"],
                       state_speed=rec["u"][0]["v_dtype"]),
        )

    cases = json.loads(sys.stdin.read())
    probe = CBFQP.__new__(CBFQP)
    out = dict(numpy=np.__version__, torch=torch.__version__, python=platform.python_version(),
               cases=[run_case(c) for c in cases])
    # constants as SigmaRL's code reads them
    from sigmarl.constants import AGENTS
    from sigmarl.rectangle_approximation import RectangleCircleApproximation
    rca = RectangleCircleApproximation(AGENTS["length"], AGENTS["width"], 3)
    out["constants"] = dict(AGENTS={k: v for k, v in AGENTS.items()}, circle_radius=float(rca.radius),
                            circle_radius_type=type(rca.radius).__name__, circle_centers_body=rca.centers,
                            d_safe=float(2.0 * rca.radius + 0), lambda_ttcbf=0.5, dt_taylor=float(2 * 0.1),
                            fd_step=0.02)
    json.dump(out, sys.stdout)


# ====================================================================== cases (inputs only)
PI = math.pi
CASES = [
    dict(name="C1_centred", path_id=0, note="1 agent, straight lane, centred, straight ahead: all margins positive",
         states=[[0.0, 0.0, 0.0, 0.5, 0.0]], actions=[[0.6, 0.0]]),
    dict(name="C2_left_partial", path_id=0,
         note="1 agent near the left boundary steering into it: negative left margin, unsaturated",
         states=[[0.0, 0.02, 0.2, 0.5, 0.05]], actions=[[0.6, 0.15]]),
    dict(name="C3_arc_saturate", path_id=1,
         note="1 agent on the arc, heading out towards the outer (right) boundary, steering right: r_R saturates at -1",
         states=[[1.06 * math.cos(0.112), 1.06 * math.sin(0.112), 0.112 + PI / 2 - 0.5, 1.0, -0.2]],
         actions=[[1.0, -0.5]]),
    dict(name="C4_clamps", path_id=0,
         note="1 agent, action (1.5, 0.9): target speed clamped to 1, steering to 31 deg; then acc clamped to 5 and "
              "steering rate to pi/2",
         states=[[0.5, 0.0, 0.2, 0.2, 0.1]], actions=[[1.5, 0.9]]),
    dict(name="C5_reverse", path_id=0,
         note="1 agent reversing (v=-0.4) towards the right boundary, action speed -0.8 (clamped to -0.5)",
         states=[[0.0, -0.05, 0.3, -0.4, 0.1]], actions=[[-0.8, -0.2]]),
    dict(name="C6_headon2", path_id=0,
         note="2 agents on the straight lane driving at each other, both accelerating: pair margin negative",
         states=[[-0.16, 0.0, 0.0, 0.8, 0.0], [0.16, 0.01, PI, 0.8, 0.0]], actions=[[1.0, 0.0], [1.0, 0.05]]),
    dict(name="C7_arc_follow2", path_id=1,
         note="2 agents on the arc, following at a distance: pair margins positive (r_P=0)",
         states=[[math.cos(-0.312), math.sin(-0.312), -0.312 + PI / 2, 0.6, 0.1],
                 [0.95 * math.cos(0.187), 0.95 * math.sin(0.187), 0.187 + PI / 2 + 0.1, 0.5, 0.2]],
         actions=[[0.7, 0.2], [0.5, 0.25]]),
    dict(name="C8_three", path_id=0,
         note="3 agents: 0 and 1 close and converging, 2 ahead reversing (v=-0.15) towards them; all pair margins "
              "negative but unsaturated, different r_P per agent",
         states=[[0.0, 0.06, -0.2, 0.5, -0.1], [0.06, -0.06, 0.3, 0.6, 0.1], [0.5, -0.02, 0.0, -0.15, 0.0]],
         actions=[[0.6, -0.2], [0.7, 0.3], [-0.25, 0.1]]),
    # quirk demonstration, not a regular test case: the circle centre lies exactly on the ray theta = 0 through an arc
    # vertex; the -dx probe (1.04, 0) falls into the float32 gap between two segments' projection ranges
    # (lambda >= 1 on one, lambda < 0 on the other), so its pseudo-distance is the masked 1000.
    dict(name="Q9_vertex_gap", path_id=1,
         note="QUIRK: middle circle's -dx probe gets the masked pseudo-distance 1000 (arc vertex ray theta=0); "
              "numpy 1.26: H_xx = 2.5e6 and gL = 1.6e4; numpy 2.x: float16 overflow, H_xx = gL = inf",
         states=[[1.06, 0.0, PI / 2 - 0.5, 1.0, -0.2]], actions=[[1.0, -0.5]]),
]


# ====================================================================== independent re-implementation (cross-check)
# Pure Python floats (= f64) plus explicit float32/float16 roundings, i.e. what a Rust port has to do. It takes the
# case inputs and SigmaRL's float16 pseudo-distances (d_9, recorded) and recomputes every lane and pair g.
# legacy=True models numpy 1.26 (SigmaRL's pin), legacy=False numpy 2.x (NEP 50).
def reimpl_case(case, rec_case, legacy):
    import numpy as np
    f16 = lambda x: float(np.float16(x))
    f32 = lambda x: float(np.float32(x))
    R = math.hypot(0.22 / 3 / 2, 0.107 / 2)  # RectangleCircleApproximation.radius (np.hypot, float64)
    OFF = [-0.11 + 0.22 / 6 + k * 0.22 / 3 for k in range(3)]  # body-x of the circle centres, y = 0
    DT, LAM, DTT = 0.1, 0.5, float(2 * 0.1)
    SMAX = f32(31 * math.pi / 180)
    k = 0.075 / 0.15

    def fd(d):  # estimate_agent_2_lane_safety_margin, d = 9 float16 values
        d0, xp, yp, xm, ym, pp, pm, mp, mm = d
        if legacy:  # (f16-f16) is a float16 scalar op; "/0.02", "2*d" and anything with a python number -> float64
            gx, gy = f16(xp - d0) / 0.02, f16(yp - d0) / 0.02
            hxx, hyy = (xp - 2 * d0 + xm) / 0.02 ** 2, (yp - 2 * d0 + ym) / 0.02 ** 2
            hxy = f16(f16(f16(pp - pm) - mp) + mm) / (4 * 0.02 * 0.02)
        else:  # NEP 50: python constants are cast to float16 first, every op rounds to float16
            with np.errstate(over="ignore"):
                c02, c0004, c0016 = f16(0.02), f16(0.02 ** 2), f16(4 * 0.02 * 0.02)
                gx, gy = f16(f16(xp - d0) / c02), f16(f16(yp - d0) / c02)
                hxx = f16(f16(f16(xp - 2 * d0) + xm) / c0004)
                hyy = f16(f16(f16(yp - 2 * d0) + ym) / c0004)
                hxy = f16(f16(f16(f16(pp - pm) - mp) + mm) / c0016)
        return d0 - R, (gx, gy), ((hxx, hxy), (hxy, hyy))

    agents = []
    for a, (st, act) in enumerate(zip(case["states"], case["actions"])):
        x, y, psi, v, dl = (f32(q) for q in st)
        # rl_action_to_u (float32 torch)
        tv = min(max(f32(act[0]), -0.5), 1.0)
        td = min(max(f32(act[1]), -SMAX), SMAX)
        ua = min(max(f32(f32(tv - v) / f32(DT)), -5.0), 5.0)
        uw = min(max(f32(f32(td - dl) / f32(DT)), f32(-math.pi / 2)), f32(math.pi / 2))
        # KinematicBicycleModel.ode in float32 (v is the signed speed)
        beta = f32(np.arctan(np.float32(k) * np.tan(np.float32(dl))))
        cpb = f32(np.float32(psi) + np.float32(beta))
        vx, vy = f32(np.float32(v) * np.cos(np.float32(cpb))), f32(np.float32(v) * np.sin(np.float32(cpb)))
        dpsi = f32(np.float32(v) / np.float32(0.15) * np.tan(np.float32(dl)) * np.cos(np.float32(beta)))

        def dd(u1, u2):  # compute_dstate_2nd_time, float64
            tdl = math.tan(dl); bt = math.atan(k * tdl); sec2 = 1 / math.cos(dl) ** 2
            tb = k * tdl; cb = 1 / math.sqrt(1 + tb ** 2); sb = tb * cb
            dbeta = (k * sec2 * u2) / (1 + (k * tdl) ** 2)
            ddx = u1 * math.cos(psi + bt) - v * math.sin(psi + bt) * (dpsi + dbeta)
            ddy = u1 * math.sin(psi + bt) + v * math.cos(psi + bt) * (dpsi + dbeta)
            ddp = (u1 / 0.15) * cb * tdl + (v / 0.15) * cb * sec2 * u2 - (v / 0.15) * sb * tdl * dbeta
            return ddx, ddy, ddp
        base, e1, e2 = dd(0.0, 0.0), dd(1.0, 0.0), dd(0.0, 1.0)
        cp_, sp_ = f32(np.cos(np.float32(psi))), f32(np.sin(np.float32(psi)))
        circ = []
        for c in range(3):
            ox = OFF[c]
            cx = f32(f32(cp_ * f32(ox)) + x); cy = f32(f32(sp_ * f32(ox)) + y)  # get_circle_centers (float32)

            def cen(ddx, ddy, ddp):  # compute_center_state_time_derivatives (delta_y = 0)
                s_, c_ = math.sin(psi), math.cos(psi)
                return (ddx - ox * (s_ * ddp + c_ * dpsi * dpsi) - 0.0 * (c_ * ddp - s_ * dpsi * dpsi),
                        ddy + ox * (c_ * ddp - s_ * dpsi * dpsi) - 0.0 * (s_ * ddp + c_ * dpsi * dpsi))
            c0, c1, c2 = cen(*base), cen(*e1), cen(*e2)
            dxc = vx - ox * math.sin(psi) * dpsi - 0.0 * math.cos(psi) * dpsi
            dyc = vy + ox * math.cos(psi) * dpsi - 0.0 * math.sin(psi) * dpsi
            circ.append(dict(p=(cx, cy), v=(dxc, dyc), c=c0, ax=(c1[0] - c0[0], c2[0] - c0[0]),
                             ay=(c1[1] - c0[1], c2[1] - c0[1])))
        gl = []
        for c in range(3):
            K = circ[c]
            rc = rec_case["agents"][a]["circles"][c]
            out = []
            for d9 in (rc["d_left_9"], rc["d_right_9"]):
                h, g, H = fd(d9)
                A = [0.5 * (DTT * DTT) * (g[0] * K["ax"][i] + g[1] * K["ay"][i]) for i in range(2)]
                dot_h = g[0] * K["v"][0] + g[1] * K["v"][1]
                vHv = sum(K["v"][i] * H[i][j] * K["v"][j] for i in range(2) for j in range(2))
                cdd = g[0] * K["c"][0] + g[1] * K["c"][1] + vHv
                b = LAM * h + dot_h * DTT + 0.5 * (DTT * DTT) * cdd
                out.append(A[0] * ua + A[1] * uw + b)
            gl.append(out)
        agents.append(dict(u=(ua, uw), circ=circ, g=gl))
    ds2 = (2.0 * R) ** 2
    pairs = {}
    n = len(agents)
    for i in range(n - 1):
        for j in range(i + 1, n):
            for ci in range(3):
                for cj in range(3):
                    Ki, Kj = agents[i]["circ"][ci], agents[j]["circ"][cj]
                    dx, dy = f32(Ki["p"][0] - Kj["p"][0]), f32(Ki["p"][1] - Kj["p"][1])
                    vrx, vry = Ki["v"][0] - Kj["v"][0], Ki["v"][1] - Kj["v"][1]
                    h = dx * dx + dy * dy - ds2
                    dh = 2.0 * (dx * vrx + dy * vry)
                    Ai = [0.5 * (DTT * DTT) * 2.0 * (dx * Ki["ax"][q] + dy * Ki["ay"][q]) for q in range(2)]
                    Aj = [0.5 * (DTT * DTT) * -2.0 * (dx * Kj["ax"][q] + dy * Kj["ay"][q]) for q in range(2)]
                    cdd = 2.0 * (vrx * vrx + vry * vry) + 2.0 * (dx * (Ki["c"][0] - Kj["c"][0]) + dy * (Ki["c"][1] - Kj["c"][1]))
                    b = LAM * h + dh * DTT + 0.5 * (DTT * DTT) * cdd
                    ui, uj = agents[i]["u"], agents[j]["u"]
                    pairs[(i, j, ci, cj)] = Ai[0] * ui[0] + Ai[1] * ui[1] + Aj[0] * uj[0] + Aj[1] * uj[1] + b
    r = []
    for a in range(n):
        vL = min(agents[a]["g"][c][0] for c in range(3)); vR = min(agents[a]["g"][c][1] for c in range(3))
        vP = min([0.0] + [g for (i, j, _, _), g in pairs.items() if a in (i, j)])
        r.append(tuple(min(max(q / 0.1, -1.0), 0.0) for q in (vL, vR, vP)))
    return agents, pairs, r


def compare_reimpl(primary, np2):
    res = {}
    for case, c1, c2 in zip(CASES, primary["cases"], np2):
        row = {}
        for legacy, ref_g, tag in ((True, c1, "numpy1.26"), (False, c2, "numpy2")):
            ag, pairs, r = reimpl_case(case, c1, legacy)
            dg, dr = 0.0, 0.0
            for a, A in enumerate(ag):
                for c in range(3):
                    if legacy:
                        ref = (c1["agents"][a]["circles"][c]["gL_margin"], c1["agents"][a]["circles"][c]["gR_margin"])
                    else:
                        ref = (c2["agents"][a]["gL"][c], c2["agents"][a]["gR"][c])
                    for q in range(2):
                        if math.isfinite(ref[q]) or math.isfinite(A["g"][c][q]):
                            dg = max(dg, abs(A["g"][c][q] - ref[q]) / max(1.0, abs(ref[q])))
                rr = c1["agents"][a] if legacy else c2["agents"][a]
                dr = max(dr, max(abs(x - y) for x, y in zip(r[a], (rr["r_L"], rr["r_R"], rr["r_P"]))))
            pg = c1["pair_g"] if legacy else c2["pair_g"]
            for (i, j, ci, cj), g in pairs.items():
                dg = max(dg, abs(g - pg[f"{i}-{j}"][ci][cj]))
            row[tag] = dict(max_abs_g_diff=dg, max_abs_r_diff=dr)
        res[case["name"]] = row
    return res


def sanitize(o):  # strict JSON: non-finite floats become "inf", "-inf", "nan"
    if isinstance(o, dict):
        return {k: sanitize(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [sanitize(v) for v in o]
    if isinstance(o, float) and not math.isfinite(o):
        return "nan" if math.isnan(o) else ("inf" if o > 0 else "-inf")
    return o


def run_worker(extra, allow_fail=False):
    env = dict(os.environ, EXTRA_PYPATH=extra, OMP_NUM_THREADS="1")
    p = subprocess.run([sys.executable, os.path.abspath(__file__), "--worker"], input=json.dumps(CASES),
                       capture_output=True, text=True, env=env, check=False)
    if p.returncode != 0 and allow_fail:
        return {"error": [l for l in p.stderr.strip().splitlines() if l.strip()][-3:]}
    if p.returncode != 0:
        sys.stderr.write(p.stderr)
        raise SystemExit(p.returncode)
    txt = p.stdout[p.stdout.index('{"numpy"'):]  # CBFQP prints nothing here, but be robust
    return json.loads(txt)


def main():
    out_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "cbf_margins_cases.json")
    primary = run_worker(NP1)  # numpy 1.26.4 = SigmaRL 1.6.0's pin
    secondary = run_worker(NP2)  # numpy 2.3.x
    venv_np = run_worker("", allow_fail=True)  # venv numpy (2.4.6): expected to raise inside SigmaRL
    assert primary["numpy"].startswith("1."), primary["numpy"]
    assert secondary["numpy"].startswith("2."), secondary["numpy"]
    src_hash = {f: hashlib.sha256(open(os.path.join(SRC, "sigmarl", f), "rb").read()).hexdigest()[:16]
                for f in ("cbf_qp.py", "pseudo_distance.py", "helper_scenario.py", "dynamics.py",
                          "rectangle_approximation.py", "constants.py", "helper_common.py", "config.json")}
    # compact numpy-2 view: only what the reward depends on
    np2 = []
    for c in secondary["cases"]:
        np2.append(dict(name=c["name"], types=c["types"], agents=[dict(
            gL=[ci["gL_margin"] for ci in a["circles"]], gR=[ci["gR_margin"] for ci in a["circles"]],
            gradL=[ci["gradL"] for ci in a["circles"]], gradR=[ci["gradR"] for ci in a["circles"]],
            hessL=[ci["hessL"] for ci in a["circles"]], hessR=[ci["hessR"] for ci in a["circles"]],
            r_L=a["r_L"], r_R=a["r_R"], r_P=a["r_P"], cbf_reward_f32=a["cbf_reward_f32"]) for a in c["agents"]],
            pair_g=c["pair_g"]))
    out = dict(
        description="SigmaRL 1.6.0 CBF-informed reward (update_qp with is_solve_qp=False) computed by SigmaRL's own "
                    "code; see research/cbf-margins-cases.md",
        sigmarl=dict(tag="1.6.0", commit="4c8032dd6c6d9d417064236c20031d12de27734d", src_sha256_16=src_hash),
        versions=dict(primary=dict(numpy=primary["numpy"], torch=primary["torch"], python=primary["python"]),
                      numpy2=dict(numpy=secondary["numpy"], torch=secondary["torch"])),
        conventions=dict(
            state="[x, y, psi, v, delta] float32; v is the SIGNED speed (agent.state.speed)",
            action="[target speed, target steering]; u = [acc, steering rate] (float32, rl_action_to_u)",
            lanes="path 0 straight: left y=+0.15, right y=-0.15, x=linspace(-2,2,81); path 1 arc: left = r 0.85 "
                  "(inner), right = r 1.15 (outer), theta = -1.5 + 0.05k, k<61, driven counter-clockwise; float32",
            d_9="pseudo-distance float16 at offsets 0, +dx, +dy, -dx, -dy, (+,+), (+,-), (-,+), (-,-); dx=dy=0.02",
            g="lane margin g = A.u + b, b = 0.5*h + dh*0.2 + 0.5*0.04*const_dd, h = sm = d - r; pair_g[i-j][ci][cj]",
            reward="r = clip(min(g)/h_nom, -1, 0) with h_nom=0.1; r_P over min(0, all pair g involving the agent); "
                   "cbf_reward_f32 = (r_L+r_R+r_P)/3 in float32 as road_traffic.py:1141-1147"),
        constants=primary["constants"],
        cases=primary["cases"],
        numpy2_cases=np2,
        venv_numpy_run=venv_np if "error" in venv_np else "ran without error",
    )
    # differences numpy 1.26.4 vs 2.x
    diffs = []
    for c1, c2 in zip(primary["cases"], np2):
        for a1, a2 in zip(c1["agents"], c2["agents"]):
            for key1, key2 in (("gL_margin", "gL"), ("gR_margin", "gR")):
                for k, ci in enumerate(a1["circles"]):
                    diffs.append(abs(ci[key1] - a2[key2][k]))
        for pk, v in c1["pair_g"].items():
            for r1, r2 in zip(v, c2["pair_g"][pk]):
                diffs += [abs(x - y) for x, y in zip(r1, r2)]
    out["reimpl_check"] = compare_reimpl(primary, np2)
    out["max_abs_g_diff_numpy1_vs_numpy2"] = max(d for d in diffs if math.isfinite(d))
    out["n_nonfinite_g_diff_numpy1_vs_numpy2"] = sum(not math.isfinite(d) for d in diffs)
    s = json.dumps(sanitize(out), separators=(",", ":"), allow_nan=False)
    print("json size", len(s))
    if len(s) < 60000:
        with open(out_path, "w") as fh:
            fh.write(s)
        print("wrote", out_path)
    else:
        print("NOT written (>= 60 kB)")
    for c in primary["cases"]:
        print(c["name"], c["lane"], "unchanged action:", c["action_tensor_unchanged"], c["types"])
        for k, a in enumerate(c["agents"]):
            print(f"  a{k} s={a['state']} act={a['action']} clamped={a['action_clamped']} u={a['u']}")
            print(f"     gL={[ci['gL_margin'] for ci in a['circles']]} gR={[ci['gR_margin'] for ci in a['circles']]}")
            print(f"     r_L={a['r_L']!r} r_R={a['r_R']!r} r_P={a['r_P']!r} cbf={a['cbf_reward_f32']!r}")
        for pk, v in c["worst_pair_g"].items():
            print(f"  pair {pk} worst g={v!r}")
    for k_, v_ in out["reimpl_check"].items():
        print("reimpl", k_, v_)
    print("max |g(numpy1) - g(numpy2)| =", out["max_abs_g_diff_numpy1_vs_numpy2"], "non-finite:",
          out["n_nonfinite_g_diff_numpy1_vs_numpy2"])
    for c1, c2 in zip(primary["cases"], np2):
        print(c1["name"], "numpy2 r (L,R,P,cbf):", [(a["r_L"], a["r_R"], a["r_P"], a["cbf_reward_f32"]) for a in c2["agents"]])
    return out


if __name__ == "__main__":
    if "--worker" in sys.argv:
        worker()
    else:
        main()
