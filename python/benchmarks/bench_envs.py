"""Environment speed on one core: cpmx's VecEnv, CpmxEnv and BenchMARL's collection beside VMAS.

Measured in one run on the same machine (one thread each: torch, rayon):

- env-steps/s of VMAS's ``road_traffic`` (the scenario SigmaRL grew from; 32 envs x 4 agents,
  random actions), of ``cpmx.VecEnv`` in ``sim`` and in the ``twin`` (at25's training scenario,
  32 envs x 4 agents), and of ``cpmx.torchrl.CpmxEnv`` in ``sim``;
- frames/s that BenchMARL's MAPPO collects on ``road_traffic`` and on cpmx's scenario, same
  configuration (the collector only: its policy forward and the environment steps).

Usage (from the repository root, with the package and its extras installed)::

    RAYON_NUM_THREADS=1 OMP_NUM_THREADS=1 python python/benchmarks/bench_envs.py \
        --data ../shared/reference [--seconds 5]
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Callable

import numpy as np
import torch

import cpmx

ENVS, AGENTS = 32, 4


def rate(step: Callable[[], None], seconds: float) -> float:
    """Calls of ``step`` per second, after a warm-up, over about ``seconds``."""
    for _ in range(20):
        step()
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        step()
        calls += 1
    return calls / (time.perf_counter() - start)


def vmas_road_traffic(seconds: float) -> float:
    """VMAS road_traffic env-steps/s (32 envs, 4 agents, random actions)."""
    import vmas

    env = vmas.make_env(
        "road_traffic", num_envs=ENVS, device="cpu", continuous_actions=True, n_agents=AGENTS
    )
    env.reset()

    def step() -> None:
        env.step([env.get_random_action(agent) for agent in env.agents])

    return ENVS * rate(step, seconds)


def cpmx_vecenv(spec: str, fidelity: str, data: str, seconds: float) -> float:
    """cpmx.VecEnv env-steps/s (32 envs, random actions)."""
    env = cpmx.VecEnv(spec, fidelity=fidelity, num_envs=ENVS, seed=0, data=data, threads=1)
    env.reset()
    rng = np.random.default_rng(0)
    low, high = env.action_low, env.action_high

    def step() -> None:
        env.step(rng.uniform(low, high, (ENVS, env.num_agents, 2)).astype(np.float32))

    return ENVS * rate(step, seconds)


def cpmx_torchrl(spec: str, data: str, seconds: float) -> float:
    """cpmx.torchrl.CpmxEnv env-steps/s (32 envs, random actions through TorchRL's step)."""
    from cpmx.torchrl import CpmxEnv

    env = CpmxEnv(spec, num_envs=ENVS, seed=0, data=data)
    td = env.reset()

    def step() -> None:
        nonlocal td
        td = env.rand_action(td)
        _, td = env.step_and_maybe_reset(td)

    return ENVS * rate(step, seconds)


def benchmarl_collection(task: object, seconds: float) -> float:
    """Frames/s BenchMARL's MAPPO collector gathers on ``task`` (its default configuration)."""
    from benchmarl.algorithms import MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models.mlp import MlpConfig

    config = ExperimentConfig.get_from_yaml()
    config.sampling_device = config.train_device = "cpu"
    config.on_policy_n_envs_per_worker = ENVS
    config.on_policy_collected_frames_per_batch = 6000
    config.loggers = []
    config.create_json = False
    config.save_folder = "/tmp"
    config.checkpoint_interval = 0
    experiment = Experiment(
        task=task,
        algorithm_config=MappoConfig.get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=config,
    )
    batches = iter(experiment.collector)
    next(batches)  # warm-up
    frames, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        frames += next(batches).numel()
    return frames / (time.perf_counter() - start)


def main() -> None:
    """Measure and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", default="experiments/at25-cpmx.yaml")
    parser.add_argument("--data", required=True, help="the folder with maps/cpm.xml")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--skip-benchmarl", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(1)

    rows = [
        ("VMAS road_traffic (32 x 4, random)", vmas_road_traffic(args.seconds), "env-steps/s"),
        (
            "cpmx.VecEnv sim (32 x 4, random)",
            cpmx_vecenv(args.spec, "sim", args.data, args.seconds),
            "env-steps/s",
        ),
        (
            "cpmx.torchrl.CpmxEnv sim",
            cpmx_torchrl(args.spec, args.data, args.seconds),
            "env-steps/s",
        ),
        (
            "cpmx.VecEnv twin (32 x 4, random)",
            cpmx_vecenv(args.spec, "twin", args.data, args.seconds),
            "env-steps/s",
        ),
    ]
    if not args.skip_benchmarl:
        from benchmarl.environments.vmas.common import VmasClass

        from cpmx.benchmarl import CpmxTask

        road = VmasClass("road_traffic", {"max_steps": 128, "n_agents": AGENTS})
        at25 = CpmxTask.from_spec(args.spec, data=args.data)
        rows += [
            (
                "BenchMARL MAPPO collection, road_traffic",
                benchmarl_collection(road, args.seconds),
                "frames/s",
            ),
            (
                "BenchMARL MAPPO collection, cpmx at25 sim",
                benchmarl_collection(at25, args.seconds),
                "frames/s",
            ),
        ]
    print(
        f"# {time.strftime('%Y-%m-%d')}, {platform.processor() or platform.machine()}, one thread"
    )
    print("| what | rate | unit | x VMAS |")
    print("|---|--:|---|--:|")
    base = {"env-steps/s": rows[0][1], "frames/s": rows[4][1] if len(rows) > 4 else float("nan")}
    for name, value, unit in rows:
        print(f"| {name} | {value:,.0f} | {unit} | {value / base[unit]:.1f} |")


if __name__ == "__main__":
    main()
