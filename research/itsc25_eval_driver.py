# Q1 driver: SigmaRL 1.4.0's own ITSC 2025 evaluation (evaluation_itsc25.py, "choice 2: safety") on CPM_entire,
# with the published itsc25 checkpoint. Runs SigmaRL's `run_simulations` / `CBF_MARL_Evaluation` unmodified;
# the only difference from `python evaluation_itsc25.py` + "2" is that the scenario list is reduced to CPM_entire and
# the seed list is given on the command line, and that torch runs at 1 thread. `save_data` is wrapped (not changed)
# to additionally keep the raw per-step timing lists and the fail counter in a side JSON.
#
# Setup (see itsc25-sigmarl.md):
#   mkdir -p /tmp/gt140 && git -C /work/.mirror/bassamlab+SigmaRL/repo archive 1.4.0 | tar -x -C /tmp/gt140
#   /work/main/target/python-venv/bin/pip install --no-deps --target /tmp/sigmarl-pydeps \
#       cvxpy==1.5.3 scs==3.2.7 clarabel==0.9.0 torchdiffeq==0.2.4 termcolor==2.5.0 opencv-python-headless==4.11.0.86
#   /work/main/target/python-venv/bin/pip install --no-deps --target /tmp/sigmarl-pins \
#       torchrl==0.6.0 tensordict==0.6.2 vmas==1.4.3      # SigmaRL 1.4.0's pins (the venv's 0.11/0.11/1.5.2 break it)
#   mkdir -p /tmp/gt_eval/checkpoints/itsc25 && cp /work/shared/reference/sigmarl-published/checkpoints/itsc25/* \
#       /tmp/gt_eval/checkpoints/itsc25/
# Run (cwd must hold checkpoints/itsc25, the relative path evaluation_itsc25.py and the data.json use):
#   cd /tmp/gt_eval && nice -n 10 /work/main/target/python-venv/bin/python research/itsc25_eval_driver.py 1 2 3 4 5
import os, sys, json, time

DEPS = os.environ.get("SIGMARL_PYDEPS", "/tmp/sigmarl-pydeps")
SRC = os.environ.get("SIGMARL_SRC", "/tmp/gt140")
PINS = os.environ.get("SIGMARL_PINS", "/tmp/sigmarl-pins")  # torchrl 0.6.0, tensordict 0.6.2, vmas 1.4.3 (1.4.0 pins)
sys.path[:0] = [PINS, DEPS, SRC]
import torch

torch.set_num_threads(1)
torch.set_num_interop_threads(1)
import matplotlib

matplotlib.use("Agg")
import pyglet

pyglet.options["headless"] = True  # no X display here: render the evaluation video through EGL (mesa llvmpipe)

import sigmarl.evaluation_itsc25 as ev

seeds = [int(s) for s in sys.argv[1:]] or [1]
cbfs = [c == "1" for c in os.environ.get("CBFS", "1,0").split(",")]
scenarios = os.environ.get("SCENARIOS", "CPM_entire").split(",")

_orig_save_data = ev.CBF_MARL_Evaluation.save_data


def save_data(self, out_td, env):
    _orig_save_data(self, out_td, env)
    raw = {
        "time_rl": list(env.time_rl),
        "time_cbf": list(env.time_cbf),
        "time_pseudo_dis": list(env.time_pseudo_dis),
        "num_fail": env.num_fail,
        "is_using_cbf": self.parameters.is_using_cbf,
        "seed": self.parameters.random_seed,
        "scenario": self.parameters.scenario_type,
        "torch_threads": torch.get_num_threads(),
    }
    with open(self.performance_metric_path.replace(".json", "_raw.json"), "w") as f:
        json.dump(raw, f)


ev.CBF_MARL_Evaluation.save_data = save_data

t0 = time.time()
res = ev.run_simulations("checkpoints/itsc25", cbfs, seeds, [3], scenarios, False)
print("run_simulations returned:", res)
print("wall time", time.time() - t0)
