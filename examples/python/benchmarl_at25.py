"""From a Python trainer to the paper's Table 2: BenchMARL's MAPPO on at25's scenario in the twin.

1. trains BenchMARL's MAPPO (its default configuration) on the training scenario of
   ``experiments/at25-cpmx.yaml`` in the spec's ``twin`` fidelity, through ``cpmx.benchmarl``;
2. writes the trained actor as safetensors in the layout ``mlp: {weights}`` reads (BenchMARL's
   MLP with its TanhNormal head is SigmaRL's actor: 4 raw outputs, locations then pre-scales);
3. evaluates it zero-shot with ``cpmx.run`` in at25's fidelities (sim, sim-mpc, twin) and
   prints the summary table, as ``cpmx run`` prints at25's.

Usage (from the repository root; ``pip install ./python[benchmarl]``)::

    python examples/python/benchmarl_at25.py --data ../shared/reference --frames 300000
    python examples/python/benchmarl_at25.py --data ../shared/reference --quick   # a smoke run

Training briefly does not make a good policy: the point is the loop. at25's own actors took
1,000 iterations of 4,096 frames (docs/training.md).
"""

from __future__ import annotations

import argparse
import json
import struct
import tempfile
from pathlib import Path

import cpmx
import torch
from benchmarl.algorithms import MappoConfig
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.models.mlp import MlpConfig
from cpmx.benchmarl import CpmxTask

REPOSITORY = Path(__file__).resolve().parents[2]
AT25 = REPOSITORY / "experiments" / "at25-cpmx.yaml"


def train(data: str, frames: int, out: Path, quick: bool) -> Experiment:
    """BenchMARL's MAPPO on at25's training scenario in the twin."""
    config = ExperimentConfig.get_from_yaml()
    config.sampling_device = config.train_device = "cpu"
    config.loggers = ["csv"]
    config.render = False
    config.evaluation = False
    config.save_folder = str(out)
    config.checkpoint_interval = 0
    config.max_n_frames = frames
    config.on_policy_n_envs_per_worker = 32
    if quick:
        config.on_policy_collected_frames_per_batch = 1024
        config.on_policy_n_minibatch_iters = 1
        config.on_policy_minibatch_size = 256
    model = MlpConfig.get_from_yaml()
    model.num_cells = [256, 256, 256]
    model.activation_class = torch.nn.Tanh
    experiment = Experiment(
        task=CpmxTask.from_spec(AT25, fidelity="twin", data=data),
        algorithm_config=MappoConfig.get_from_yaml(),
        model_config=model,
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=config,
    )
    experiment.run()
    return experiment


def linear_layers(experiment: Experiment) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """The actor's linear layers (weight ``[out, in]``, bias), input first."""
    policy = experiment.group_policies["agents"]
    weights = {}
    for name, tensor in policy.state_dict().items():
        parts = name.split(".")
        if parts[-1] in ("weight", "bias") and tensor.dim() in (1, 2):
            weights[name] = tensor.detach().cpu().float()
    names = sorted(
        {n.rsplit(".", 1)[0] for n in weights},
        key=lambda n: [int(p) if p.isdigit() else p for p in n.split(".")],
    )
    layers = [
        (weights[f"{n}.weight"], weights[f"{n}.bias"]) for n in names if f"{n}.bias" in weights
    ]
    if not layers:
        raise RuntimeError(f"no linear layers in the policy: {list(policy.state_dict())}")
    return layers


def write_safetensors(layers: list[tuple[torch.Tensor, torch.Tensor]], path: Path) -> None:
    """``actor.{i}.weight`` / ``actor.{i}.bias`` in the safetensors format (float32, little-endian)."""
    header: dict[str, dict[str, object]] = {}
    body = bytearray()
    for i, (w, b) in enumerate(layers):
        for kind, tensor in (("weight", w), ("bias", b)):
            data = tensor.contiguous().numpy().astype("<f4").tobytes()
            header[f"actor.{i}.{kind}"] = {
                "dtype": "F32",
                "shape": list(tensor.shape),
                "data_offsets": [len(body), len(body) + len(data)],
            }
            body += data
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 8)
    path.write_bytes(struct.pack("<Q", len(text)) + text + bytes(body))


def evaluate(actor: Path, data: str, out: Path) -> str:
    """at25's zero-shot table of the actor (at25's spec with this actor as its policy)."""
    text = AT25.read_text()
    start, end = text.index("policies:\n"), text.index("\ninitial_configurations:")
    spec = (
        text[:start]
        + f"policies:\n  - {{name: benchmarl-mappo, mlp: {{weights: {actor}}}, observation: stdlib:sigmarl, action: mean}}\n"
        + text[end:]
    )
    spec = spec.split("\n# How cpmx trains policies")[0].replace(
        "group_by: [fidelity]", "group_by: [fidelity, policy]"
    )
    path = out / "benchmarl-at25.yaml"
    path.write_text(spec)
    return cpmx.run(path, out=out / "runs", data=data).summary


def main() -> None:
    """Train, export, evaluate."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True, help="the folder with maps/cpm.xml")
    parser.add_argument("--frames", type=int, default=300_000, help="frames BenchMARL collects")
    parser.add_argument(
        "--out", type=Path, default=None, help="where to write (default: a temporary folder)"
    )
    parser.add_argument("--quick", action="store_true", help="a smoke run: two small batches")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="cpmx-benchmarl-"))
    out.mkdir(parents=True, exist_ok=True)
    frames = 2048 if args.quick else args.frames
    experiment = train(args.data, frames, out, args.quick)
    actor = out / "actor.safetensors"
    write_safetensors(linear_layers(experiment), actor)
    print(f"wrote {actor}")
    print(evaluate(actor, args.data, out))


if __name__ == "__main__":
    main()
