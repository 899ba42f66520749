# Reference cases for cpmx's reimplementation of SigmaRL's ITSC 2025 CBF safety filter, computed by SigmaRL's OWN
# code at tag 1.4.0 (sigmarl/cbf_qp.py CBFQP.solve_decentralized_cbf_qp, sigmarl/pseudo_distance.py,
# sigmarl/helper_scenario.compute_pseudo_tangent_vector), unmodified and imported as a package.
# Only the environment objects the filter reads are mocked (SimpleNamespace env/parameters/map parser and a dict
# standing in for the TensorDict); SigmaRL's methods are wrapped (not changed) to record intermediate values, and
# cvxpy.Problem.solve is wrapped to run once with SigmaRL's own call (SCS) and once with Clarabel at tight tolerances.
# See research/cbf-reference-cases.md for setup. Run:
#   git -C <a clone of bassamlab/SigmaRL> archive 1.4.0 | tar -x -C /tmp/sigmarl140
#   target/python-venv/bin/pip install --no-deps --target /tmp/sigmarl-pydeps \
#       cvxpy==1.5.3 scs==3.2.7 clarabel==0.9.0 torchdiffeq==0.2.4
#   target/python-venv/bin/python research/cbf_reference_cases.py [out.json]
import sys, os, json, math, io, contextlib, hashlib, itertools, platform
from types import SimpleNamespace

DEPS = os.environ.get("SIGMARL_PYDEPS", "/tmp/sigmarl-pydeps")
SRC = os.environ.get("SIGMARL_SRC", "/tmp/sigmarl140")
sys.path[:0] = [p for p in os.environ.get("EXTRA_PYPATH", "").split(":") if p] + [DEPS, SRC]
torch_threads = 1
import numpy as np
import torch
torch.set_num_threads(torch_threads)
import cvxpy as cp
import scs, clarabel
import sigmarl.cbf_qp as cbf_qp_mod
from sigmarl.cbf_qp import CBFQP
from sigmarl.pseudo_distance import PseudoDistance
from sigmarl.helper_scenario import compute_pseudo_tangent_vector

OUT = sys.argv[1] if len(sys.argv) > 1 else "research/cbf_reference_cases.json"
f16, f32 = np.float16, np.float32
CLARABEL_OPTS = dict(tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10, tol_infeas_abs=1e-10, tol_infeas_rel=1e-10,
                     tol_ktratio=1e-8, max_iter=500)
ACTIVE_TOL = 1e-7


def fl(x):  # exact value of a float16/float32/float64 scalar or tensor element as a Python float
    if isinstance(x, torch.Tensor):
        x = x.item()
    return float(x)


def fl_list(a):
    if isinstance(a, torch.Tensor):
        a = a.detach().cpu().numpy()
    return np.asarray(a).astype(np.float64).tolist()


# ---------------------------------------------------------------- boundaries (float32 polylines, like SigmaRL's maps)
def straight(hw):
    xs = np.linspace(-2.0, 2.0, 81)  # every 0.05 m
    left = torch.tensor(np.stack([xs, np.full_like(xs, hw)], 1), dtype=torch.float32)
    right = torch.tensor(np.stack([xs, np.full_like(xs, -hw)], 1), dtype=torch.float32)
    return left, right


ARC_R, ARC_HW, ARC_TH0, ARC_DTH, ARC_N = 1.0, 0.15, -1.5, 0.05, 61  # centre-line angle -1.5 .. 1.5 rad


def arc():
    # Lane on a circle of radius 1 m about the origin, driven counter-clockwise (direction theta + pi/2), so the
    # LEFT boundary is the inner circle (r = 0.85) and the RIGHT boundary the outer one (r = 1.15).
    th = ARC_TH0 + ARC_DTH * np.arange(ARC_N)
    mk = lambda r: torch.tensor(np.stack([r * np.cos(th), r * np.sin(th)], 1), dtype=torch.float32)
    return mk(ARC_R - ARC_HW), mk(ARC_R + ARC_HW)


BOUNDARIES = {"straight_hw0.15": straight(0.15), "straight_hw0.06": straight(0.06), "arc_r1.0_hw0.15": arc()}


# ---------------------------------------------------------------- mocks of what CBFQP reads
def make_filter(boundary, n_circles):
    left, right = BOUNDARIES[boundary]
    ref_path = {  # as parse_map_base.py:100-111 fills reference_paths[...]
        "left_boundary_shared": left,
        "right_boundary_shared": right,
        "left_boundary_shared_pseudo_vector": compute_pseudo_tangent_vector(left),
        "right_boundary_shared_pseudo_vector": compute_pseudo_tangent_vector(right),
    }
    pd = PseudoDistance.__new__(PseudoDistance)  # skip __init__ (it needs a MapManager); get_distance only reads .map
    pd.map = SimpleNamespace(parser=SimpleNamespace(reference_paths={0: ref_path}))
    params = SimpleNamespace(device="cpu", dt=0.05, is_using_centralized_cbf=False,
                             n_circles_approximate_vehicle=n_circles)
    env = SimpleNamespace(base_env=SimpleNamespace(scenario_name=SimpleNamespace(map_pseudo_distance=pd,
                                                                                  parameters=params)))
    return CBFQP(env=env, env_idx=0, agent_idx=0), pd, ref_path


def make_tensordict(state, rl_action):
    obs = torch.tensor([[list(state) + [0.0, 0.0]]], dtype=torch.float32)  # [x,y,psi,v,delta,lanelet_id,path_id]
    return {
        ("agents", "info", "cbf_observation"): obs,
        ("agents", "action"): torch.tensor([[list(rl_action)]], dtype=torch.float32),
        ("agents", "info", "nominal_action"): torch.zeros(1, 1, 2, dtype=torch.float32),
    }


# ---------------------------------------------------------------- one SigmaRL call with recording wrappers
_orig_solve = cp.Problem.solve


def run_sigmarl(state, rl_action, n_circles, boundary, solver):
    cbf, pd, ref_path = make_filter(boundary, n_circles)
    rec = {"distance_calls": [], "margins": [], "cbf": [], "centers_deriv": [], "u_to_rl": []}

    orig_gd = pd.get_distance
    def get_distance(path_id, lanelet_id, query_points):
        out = orig_gd(path_id, lanelet_id, query_points)
        rec["distance_calls"].append((query_points.clone(), out))
        return out
    pd.get_distance = get_distance

    orig_est = cbf.estimate_agent_2_lane_safety_margin
    def est(agent_pos, lanelet_id, path_id):
        out = orig_est(agent_pos, lanelet_id, path_id)
        rec["margins"].append((agent_pos.clone(), out))
        return out
    cbf.estimate_agent_2_lane_safety_margin = est

    orig_cc = cbf.compute_cbf_conditions
    def cc(dstate_time, ddstate_time, sm, grad_sm, hessian_sm):
        out = orig_cc(dstate_time, ddstate_time, sm, grad_sm, hessian_sm)
        h, dot_h, ddot_h, c1, c2 = out
        lam_h = cbf.lambda_ttcbf * h
        types = {  # the actual Python/NumPy types of each operand in SigmaRL's expressions
            "sm": type(sm).__name__ + "/" + str(getattr(sm, "dtype", "")),
            "grad_sm": str(grad_sm.dtype), "hessian_sm": str(hessian_sm.dtype),
            "dstate_time(circle velocity)": str(dstate_time.dtype),
            "ddstate_time": type(ddstate_time).__name__ + "[" + type(ddstate_time[0]).__name__ + "]",
            "h": type(h).__name__, "lambda_ttcbf": type(cbf.lambda_ttcbf).__name__, "dt": type(cbf.dt).__name__,
            "lambda*h": type(lam_h).__name__, "dot_h": type(dot_h).__name__,
            "dot_h*dt": type(dot_h * cbf.dt).__name__, "lambda*h + dot_h*dt": type(lam_h + dot_h * cbf.dt).__name__,
            "dstate.T@H@dstate": type(dstate_time.T @ hessian_sm @ dstate_time).__name__,
            "ddot_h": type(ddot_h).__name__, "cbf_condition_2": type(c2).__name__,
        }
        rec["cbf"].append(dict(dstate=dstate_time.copy(), dd=ddstate_time, h=h, dot_h=dot_h, ddot_h=ddot_h, c2=c2,
                               lam_h=lam_h, types=types))
        return out
    cbf.compute_cbf_conditions = cc

    orig_csd = cbf.compute_center_state_time_derivatives
    def csd(psi, dstate_time_agent, ddx, ddy, ddpsi, idx):
        out = orig_csd(psi, dstate_time_agent, ddx, ddy, ddpsi, idx)
        rec["centers_deriv"].append((idx, dstate_time_agent.clone(), out))
        return out
    cbf.compute_center_state_time_derivatives = csd

    orig_gcc = cbf.get_circle_centers
    def gcc(state_t):
        out = orig_gcc(state_t)
        rec["circle_states"] = out.clone()
        return out
    cbf.get_circle_centers = gcc

    orig_u2rl = cbf.u_to_rl_action
    def u2rl(u, state_v, state_steering):
        out = orig_u2rl(u, state_v, state_steering)
        rec["u_to_rl"].append((np.array(u, dtype=np.float64), out.clone()))
        return out
    cbf.u_to_rl_action = u2rl

    def solve(self, *args, **kwargs):
        rec["sigmarl_solve_kwargs"] = {k: (v if isinstance(v, (bool, int, float)) else str(v)) for k, v in kwargs.items()}
        if solver == "CLARABEL":
            kwargs = dict(kwargs, solver=cp.CLARABEL, **CLARABEL_OPTS)
        rec["prob"] = self
        ret = _orig_solve(self, *args, **kwargs)
        (v,) = self.variables()
        rec["u_value"] = None if v.value is None else np.array(v.value, dtype=np.float64).copy()
        rec["duals"] = [None if con.dual_value is None else float(np.asarray(con.dual_value).reshape(()))
                        for con in self.constraints]
        return ret

    td = make_tensordict(state, rl_action)
    out = io.StringIO()
    cp.Problem.solve = solve
    try:
        with contextlib.redirect_stdout(out):
            cbf.solve_decentralized_cbf_qp(td)
    finally:
        cp.Problem.solve = _orig_solve
    rec["stdout"] = out.getvalue()
    rec["td"] = td
    rec["cbf_obj"] = cbf
    rec["ref_path"] = ref_path
    return rec


def affine_row(expr):
    """cbf_condition_2 is a cvxpy expression affine in u = [a, omega]: return (coef (2,), const)."""
    (var,) = expr.variables()
    def at(u):
        var.value = np.array(u, dtype=np.float64)
        return float(np.asarray(expr.value).reshape(()))
    c0 = at([0.0, 0.0])
    coef = [at([1.0, 0.0]) - c0, at([0.0, 1.0]) - c0]
    # rescaled evaluation to limit cancellation in the coefficients
    coef_big = [(at([1e4, 0.0]) - c0) / 1e4, (at([0.0, 1e4]) - c0) / 1e4]
    var.value = None
    return np.array(coef_big), c0, np.array(coef)


# ---------------------------------------------------------------- exact QP (independent check of Clarabel)
R = np.diag([30.0, 1.0])


def exact_qp(u0, rows, box=40.0):
    # box rows, in this order: a <= 40, a >= -40, w <= 40, w >= -40
    G = [r[0] for r in rows] + [np.array([-1.0, 0]), np.array([1.0, 0]), np.array([0, -1.0]), np.array([0, 1.0])]
    c = [r[1] for r in rows] + [box] * 4  # rows: coef.u + const >= 0
    nrm = [max(np.linalg.norm(g), 1e-300) for g in G]
    Gn = [g / n for g, n in zip(G, nrm)]; cn = [ci / n for ci, n in zip(c, nrm)]
    Ri = np.linalg.inv(R); best = None
    for m in range(3):
        for S in itertools.combinations(range(len(Gn)), m):
            if m:
                Gs = np.array([Gn[i] for i in S]); cs = np.array([cn[i] for i in S])
                M = Gs @ Ri @ Gs.T
                if np.linalg.cond(M) > 1e12:
                    continue
                mu = np.linalg.solve(M, -(Gs @ u0 + cs)) * 2
                if (mu < -1e-12).any():
                    continue
                u = u0 + Ri @ Gs.T @ mu / 2
            else:
                u = u0.copy()
            if all(Gn[i] @ u + cn[i] >= -1e-9 for i in range(len(Gn))):
                val = (u - u0) @ R @ (u - u0)
                if best is None or val < best[0] - 1e-15:
                    best = (val, u, S)
    return best


# ---------------------------------------------------------------- the numpy reimplementation, for comparison
def load_reimpl(fixed=False):
    src = open("research/sigmarl_cbf_examples.py").read()
    src = src[: src.index('\nrun("A')]
    if fixed:  # SigmaRL's dot_h is np.float64, so lambda*h (float16) + dot_h*dt is float64, not float16
        old = "const = f16(LAM*h) + hdot*DT"
        assert old in src
        src = src.replace(old, "const = f16(LAM*h) + np.float64(hdot*DT)")
    ns = {}
    exec(compile(src, "sigmarl_cbf_examples.py", "exec"), ns)
    return ns


# ---------------------------------------------------------------- one case
SIDE_NAMES = ("left", "right")


def case_record(name, state, rl_action, n_circles, boundary, note=""):
    state = [fl(f32(s)) for s in state]
    rl_action = [fl(f32(a)) for a in rl_action]
    left, right = BOUNDARIES[boundary]
    res = {"name": name, "note": note, "boundary": boundary, "n_circles": n_circles,
           "state": state, "rl_action_nominal": rl_action}
    runs, errors = {}, {}
    for s in ("SCS", "CLARABEL"):
        try:
            with np.errstate(over="ignore", invalid="ignore"):  # float16 overflow at polyline ends (case END)
                runs[s] = run_sigmarl(state, rl_action, n_circles, boundary, s)
        except BaseException as e:  # Clarabel panics (pyo3 PanicException) on inf/nan problem data
            errors[s] = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    r = runs.get("CLARABEL") or runs["SCS"]
    cbf = r["cbf_obj"]
    # conversion (rl_action_to_u): clamped nominal action and u_nom exactly as SigmaRL computed them
    res["rl_action_nominal_clamped"] = fl_list(cbf.rl_actions_nominal_agent_list[0].flatten())
    u_nom = cbf.u_nominal_agent_list[0].detach().cpu().numpy().flatten()
    res["u_nom"] = fl_list(u_nom)
    res["u_nom_dtype"] = str(cbf.u_nominal_agent_list[0].dtype)
    res["ode_dstate_float32"] = fl_list(r["centers_deriv"][0][1])  # KinematicBicycleModel.ode [dx,dy,dpsi,dv,dd]
    circle_states = r["circle_states"]
    circles = []
    rows = []  # in cvxpy constraint order: left rows for circles 0..n-1, then right rows
    left_rows, right_rows = [], []
    for i in range(n_circles):
        pos, (sm_l, g_l, H_l, sm_r, g_r, H_r) = r["margins"][i]
        qp, (dl, dr) = r["distance_calls"][i]
        _, _, (dxc, dyc, dpsic, ddxc, ddyc, ddpsic) = r["centers_deriv"][i]
        circ = {"index": i, "body_offset": list(cbf.rec_cir_approx.centers[i]),
                "center_float32": fl_list(circle_states[i][0:2]),
                "query_points_float32": fl_list(qp), "velocity": [fl(dxc), fl(dyc)], "sides": {}}
        for side, sm, g, H, dists, k in (("left", sm_l, g_l, H_l, dl, 2 * i), ("right", sm_r, g_r, H_r, dr, 2 * i + 1)):
            c = r["cbf"][k]
            coef, const, coef_unit = affine_row(c["c2"])
            ddot0 = affine_row(c["ddot_h"])
            entry = {
                "d_float16_9pts": fl_list(dists),  # order: 0, +dx, +dy, -dx, -dy, (+,+), (+,-), (-,+), (-,-)
                "h_float16": fl(c["h"]), "h_dtype": str(np.asarray(c["h"]).dtype),
                "g_float16": fl_list(g), "H_float16": fl_list(H),
                "dot_h": fl(c["dot_h"]),
                "lambda_h": fl(c["lam_h"]), "lambda_h_dtype": str(np.asarray(c["lam_h"]).dtype),
                "ddot_h_coef": ddot0[0].tolist(), "ddot_h_const": ddot0[1],
                "row_coef": coef.tolist(), "row_const": const,
                "types": c["types"],
            }
            circ["sides"][side] = entry
            (left_rows if side == "left" else right_rows).append((coef, const, f"c{i}{side[0].upper()}"))
        circles.append(circ)
    res["circles"] = circles
    rows = left_rows + right_rows
    res["row_order"] = [lab for _, _, lab in rows]
    for s in ("SCS", "CLARABEL"):
        if s in errors:
            res[s.lower()] = {"status": "exception", "exception": errors[s], "u_star": None,
                              "note": "SigmaRL itself would crash here (the exception propagates out of "
                                      "solve_decentralized_cbf_qp); only possible with the swapped solver"}
            continue
        rr = runs[s]
        prob = rr["prob"]
        td = rr["td"]
        u_star = None if rr["u_value"] is None else fl_list(rr["u_value"])
        ent = {"status": prob.status, "u_star": u_star,
               "qp_solved_optimal": prob.status == cp.OPTIMAL,
               "filtered_action_float32": fl_list(td[("agents", "action")][0, 0]),
               "nominal_action_written": fl_list(td[("agents", "info", "nominal_action")][0, 0]),
               "u_to_rl_action_output": fl_list(rr["u_to_rl"][0][1]) if rr["u_to_rl"] else None,
               "u_to_rl_action_dtype": str(rr["u_to_rl"][0][1].dtype) if rr["u_to_rl"] else None,
               "num_fail": rr["cbf_obj"].num_fail, "stdout": rr["stdout"].strip(),
               "solve_kwargs": rr["sigmarl_solve_kwargs"] if s == "SCS" else dict(solver="CLARABEL", **CLARABEL_OPTS)}
        if s == "CLARABEL":
            ent["solver_stats"] = {"iterations": prob.solver_stats.num_iters}
            if u_star is not None:
                us = np.array(u_star)
                slacks = [float(cf @ us + c0) for cf, c0, _ in rows]
                duals = rr["duals"][4:]
                ent["row_slack"] = dict(zip(res["row_order"], slacks))
                ent["row_dual"] = dict(zip(res["row_order"], duals))
                ent["box_dual"] = rr["duals"][:4]
                ent["active_rows"] = [lab for (cf, c0, lab), sl in zip(rows, slacks) if sl < ACTIVE_TOL]
                bx = ["a>=-40", "a<=40", "w>=-40", "w<=40"]
                bs = [us[0] + 40, 40 - us[0], us[1] + 40, 40 - us[1]]
                ent["active_box"] = [b for b, v in zip(bx, bs) if v < ACTIVE_TOL]
        res[s.lower()] = ent
    # identical intermediate values in both runs (determinism check)
    res["scs_and_clarabel_runs_same_rows"] = len(runs) == 2 and all(
        np.array_equal(affine_row(a["c2"])[0], affine_row(b["c2"])[0]) and affine_row(a["c2"])[1] == affine_row(b["c2"])[1]
        for a, b in zip(runs["SCS"]["cbf"], runs["CLARABEL"]["cbf"]))
    if not all(np.isfinite(cf).all() and np.isfinite(c0) for cf, c0, _ in rows):
        res["exact_active_set"] = "not computed: non-finite row data"
        return res
    ex = exact_qp(np.array(u_nom, dtype=np.float64), [(cf, c0) for cf, c0, _ in rows])
    res["exact_active_set"] = None if ex is None else {
        "u_star": ex[1].tolist(),
        "active": [(res["row_order"] + ["a<=40", "a>=-40", "w<=40", "w>=-40"])[j] for j in ex[2]]}
    return res


def compare_reimpl(ns, c):
    """Numpy reimplementation (sigmarl_cbf_examples.py) vs SigmaRL on the same inputs."""
    left, right = BOUNDARIES[c["boundary"]]
    rows = ns["constraints"](c["state"], c["n_circles"], left.numpy().astype(np.float64), right.numpy().astype(np.float64))
    # reimpl order: per circle L, R
    out = {"max_abs_h": 0.0, "max_abs_const": 0.0, "max_rel_coef": 0.0, "h_mismatches": [], "gH_mismatches": []}
    for i in range(c["n_circles"]):
        p = np.array(c["circles"][i]["center_float32"])
        mg = ns["margins"](p, left.numpy().astype(np.float64), right.numpy().astype(np.float64))
        for j, side in enumerate(SIDE_NAMES):
            ref = c["circles"][i]["sides"][side]
            r = rows[2 * i + j]
            _, g, H = mg[j]
            if g.astype(float).tolist() != ref["g_float16"] or H.astype(float).tolist() != ref["H_float16"]:
                out["gH_mismatches"].append(f"circle{i} {side}")
            dh = abs(r[1] - ref["h_float16"])
            if dh > 0:
                out["h_mismatches"].append(f"circle{i} {side}: reimpl {r[1]!r} sigmarl {ref['h_float16']!r}")
            out["max_abs_h"] = max(out["max_abs_h"], dh)
            out["max_abs_const"] = max(out["max_abs_const"], abs(r[4] - ref["row_const"]))
            rc = np.array(ref["row_coef"])
            out["max_rel_coef"] = max(out["max_rel_coef"], float(np.max(np.abs(r[3] - rc) / np.maximum(np.abs(rc), 1e-12))))
    return out


# ---------------------------------------------------------------- cases
def note_cases():
    return [
        ("A", [0.0, 0.08, 0.2, 0.8, 0.1], [1.0, 0.3], 3, "straight_hw0.15", "heading into left boundary"),
        ("B", [0.0, 0.0, 0.0, 0.8, 0.0], [1.0, 0.0], 3, "straight_hw0.15", "centred, straight"),
        ("C", [0.0, 0.10, 0.5, 1.0, 0.3], [1.0, 0.6], 3, "straight_hw0.15", "too close, fast"),
        ("D", [0.0, 0.0, 0.4, 1.0, 0.0], [1.0, 0.0], 3, "straight_hw0.06", "narrow lane (half-width 0.06), heading 0.4"),
        ("E", [0.0, 0.04, 1.5707963, 1.0, 0.0], [1.0, 0.0], 3, "straight_hw0.15", "perpendicular to left boundary at 1 m/s"),
        ("F", [0.0, 0.05, 1.5707963, 1.0, 0.0], [1.0, 0.0], 3, "straight_hw0.15", "as E but 1 cm closer"),
    ]


def random_cases(seed=20250508, n=20):
    rng = np.random.default_rng(seed)
    out = []
    ncs = [3] * n
    for k in (2, 9, 15):
        ncs[k] = 1
    for k in (5, 12, 18):
        ncs[k] = 5
    for k in range(n):
        boundary = "straight_hw0.15" if k % 2 == 0 else "arc_r1.0_hw0.15"
        # lateral offset from the centre line (positive = towards the LEFT boundary), biased towards the boundaries:
        # |offset| in [0.04, 0.18], i.e. from well inside the lane to 3 cm outside its 0.15 m half-width
        off = rng.choice([-1.0, 1.0]) * rng.uniform(0.04, 0.18)
        dyaw = rng.uniform(-0.8, 0.8)
        v = rng.uniform(0.0, 1.0); delta = rng.uniform(-0.5, 0.5)
        a_v = rng.uniform(-0.5, 1.0); a_d = rng.uniform(-0.7, 0.7)
        if boundary.startswith("straight"):
            x = rng.uniform(-1.0, 1.0); y = off; yaw = dyaw
        else:
            th = rng.uniform(-0.8, 0.8)  # polyline covers -1.5..1.5 rad
            r = ARC_R - off  # left = inner circle
            x, y = r * math.cos(th), r * math.sin(th)
            yaw = math.atan2(math.sin(th + math.pi / 2 + dyaw), math.cos(th + math.pi / 2 + dyaw))
        out.append((f"R{k:02d}", [x, y, yaw, v, delta], [a_v, a_d], ncs[k], boundary,
                    f"random (seed {seed}), lateral offset {off:+.4f} m towards left, yaw offset {dyaw:+.4f} rad"))
    return out


def extra_cases():
    # the note's A with 1 and 5 circles, and an edge case at the end of the boundary polylines (x = 2)
    return [
        ("A_n1", [0.0, 0.08, 0.2, 0.8, 0.1], [1.0, 0.3], 1, "straight_hw0.15", "A with 1 circle"),
        ("A_n5", [0.0, 0.08, 0.2, 0.8, 0.1], [1.0, 0.3], 5, "straight_hw0.15", "A with 5 circles"),
        ("END", [1.985, 0.1, 0.0, 0.5, 0.0], [1.0, 0.0], 3, "straight_hw0.15",
         "polyline end: the front circle (x=2.038) and the +dx probe of the middle one lie past the last vertex, so "
         "their pseudo-distance is the masked 1000; float16 H overflows to inf"),
    ]


def float16_probe():
    """How NumPy >= 2 (NEP 50) evaluates the float16 expressions of estimate_agent_2_lane_safety_margin."""
    hs = np.arange(0, 2 ** 15, dtype=np.uint16).view(np.float16)  # all non-negative finite float16
    hs = hs[np.isfinite(hs) & (hs < 2.0)]
    h32 = hs.astype(np.float32); h64 = hs.astype(np.float64)
    lam = 0.1 * hs  # SigmaRL: self.lambda_ttcbf * h
    p = {
        "0.1*f16 dtype": str(lam.dtype),
        "0.1*h == f16(f32(f16(0.1))*f32(h)) for all h in [0,2)": bool(np.array_equal(lam, (np.float32(np.float16(0.1)) * h32).astype(f16))),
        "0.1*h == f16(0.1*h exact) for all h in [0,2)": bool(np.array_equal(lam, (0.1 * h64).astype(f16))),
        "count where they differ": int(np.sum(lam != (0.1 * h64).astype(f16))),
        "d-0.05 == f16(d - f16(0.05))": bool(np.array_equal(hs - 0.05, (h32 - np.float32(f16(0.05))).astype(f16))),
        "d-0.05 differs from f16(d-0.05 exact) count": int(np.sum((hs - 0.05) != (h64 - 0.05).astype(f16))),
        "(x)/0.02 == f16(x / f16(0.02)) ": bool(np.array_equal(hs / 0.02, (h32 / np.float32(f16(0.02))).astype(f16))),
        "(x)/0.02 differs from f16(x/0.02 exact) count": int(np.sum((hs / 0.02) != (h64 / 0.02).astype(f16))),
        "f16(0.1), f16(0.05), f16(0.02), f16(0.02**2), f16(4*0.02*0.02)": [fl(f16(0.1)), fl(f16(0.05)), fl(f16(0.02)),
                                                                           fl(f16(0.02 ** 2)), fl(f16(4 * 0.02 * 0.02))],
        "scalar: np.float16(0.02001953125)*0.1 == f16(f16(0.1)*h)": bool(f16(0.02001953125) * 0.1 == f16(np.float32(f16(0.1)) * np.float32(f16(0.02001953125)))),
        "scalar: np.float16(0.02001953125)*0.1 value, f16(0.1*h exact)": [fl(f16(0.02001953125) * 0.1), fl(f16(0.1 * 0.02001953125))],
        "scalar: type(np.float16(0.1) - 0.05), type(np.float16(0.1) / 0.02), type(2 * np.float16(0.1))": [
            type(f16(0.1) - 0.05).__name__, type(f16(0.1) / 0.02).__name__, type(2 * f16(0.1)).__name__],
        "type(np.float16(1) + 1.5)": type(np.float16(1) + 1.5).__name__,
        "type(np.float16(1) + np.float64(1.5))": type(np.float16(1) + np.float64(1.5)).__name__,
        "dtype(float16 array @ float64 array)": str((np.ones(2, f16) @ np.ones(2)).dtype),
    }
    return p


def sanitize(o):
    """Strict JSON: non-finite floats become the strings "inf", "-inf", "nan"."""
    if isinstance(o, dict):
        return {k: sanitize(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [sanitize(v) for v in o]
    if isinstance(o, float) and not math.isfinite(o):
        return "nan" if math.isnan(o) else ("inf" if o > 0 else "-inf")
    return o


def main():
    src_hash = {f: hashlib.sha256(open(os.path.join(SRC, "sigmarl", f), "rb").read()).hexdigest()
                for f in ("cbf_qp.py", "pseudo_distance.py", "helper_scenario.py", "dynamics.py",
                          "rectangle_approximation.py", "constants.py")}
    ns, ns_fixed = load_reimpl(), load_reimpl(fixed=True)
    cases = []
    for args in note_cases() + extra_cases() + random_cases():
        c = case_record(*args)
        with np.errstate(over="ignore", invalid="ignore"):
            c["vs_numpy_reimpl"] = compare_reimpl(ns, c)
            c["vs_numpy_reimpl_with_float64_const"] = compare_reimpl(ns_fixed, c)
        if c["scs"]["u_star"] is not None and c["clarabel"]["u_star"] is not None:
            c["scs_minus_clarabel_u"] = (np.array(c["scs"]["u_star"]) - np.array(c["clarabel"]["u_star"])).tolist()
        cases.append(c)
        cl, sc = c["clarabel"], c["scs"]
        print(f"{c['name']:6s} n={c['n_circles']} {c['boundary']:16s} u_nom={np.round(c['u_nom'], 4)} "
              f"SCS {sc['status']:>18s} {np.round(sc['u_star'], 6) if sc['u_star'] else None} "
              f"CLA {cl['status']:>18s} {np.round(cl['u_star'], 6) if cl['u_star'] else None} "
              f"act={cl.get('active_rows')} exact={np.round(c['exact_active_set']['u_star'], 6) if isinstance(c['exact_active_set'], dict) else c['exact_active_set']} "
              f"reimpl dh={c['vs_numpy_reimpl']['max_abs_h']:.1e} gH={len(c['vs_numpy_reimpl']['gH_mismatches'])} "
              f"dconst={c['vs_numpy_reimpl']['max_abs_const']:.1e} fixed dconst={c['vs_numpy_reimpl_with_float64_const']['max_abs_const']:.1e}")
    out = {
        "description": "SigmaRL 1.4.0 CBF safety filter (cbf_qp.py CBFQP.solve_decentralized_cbf_qp) reference cases, "
                       "computed by SigmaRL's own code; see research/cbf-reference-cases.md",
        "conventions": {
            "state": "[x, y, psi, v, delta] float32 (geometric centre, v = |vel| >= 0)",
            "rl_action": "(speed m/s, steering rad)",
            "u": "[a m/s^2, omega rad/s]",
            "row": "row_coef . u + row_const >= 0 (cbf_condition_2 = lambda*h + dot_h*dt + 0.5*ddot_h*dt^2)",
            "row_order": "cvxpy constraint order: 4 box rows, then left rows for circles 0..n-1, then right rows",
            "d_float16_9pts order": "0, +dx, +dy, -dx, -dy, (+dx,+dy), (+dx,-dy), (-dx,+dy), (-dx,-dy); dx=dy=0.02",
            "filtered_action_float32": "what solve_decentralized_cbf_qp wrote to ('agents','action') (float32 tensor); "
                                       "on a non-OPTIMAL status this is the clamped nominal action",
            "active_rows": f"rows with slack < {ACTIVE_TOL} at the Clarabel solution",
            "exact_active_set": "independent float64 active-set solution of the same rows (sanity check)",
        },
        "versions": {"python": platform.python_version(), "numpy": np.__version__, "torch": torch.__version__,
                     "cvxpy": cp.__version__, "scs": scs.__version__, "clarabel": clarabel.__version__,
                     "sigmarl_tag": "1.4.0", "sigmarl_src_sha256": src_hash},
        "clarabel_options": CLARABEL_OPTS,
        "boundaries": {k: {"left": fl_list(l), "right": fl_list(r),
                           "left_pseudo_tangent": fl_list(compute_pseudo_tangent_vector(l)),
                           "right_pseudo_tangent": fl_list(compute_pseudo_tangent_vector(r))}
                       for k, (l, r) in BOUNDARIES.items()},
        "float16_probe": float16_probe(),
        "cases": cases,
    }
    for c in cases:  # the brief asks for the polylines per case too
        c["boundary_polylines"] = {"left": out["boundaries"][c["boundary"]]["left"],
                                   "right": out["boundaries"][c["boundary"]]["right"]}
    with open(OUT, "w") as fh:
        json.dump(sanitize(out), fh, indent=1, allow_nan=False)
    print("wrote", OUT)


if __name__ == "__main__":
    main()
