"""Check an ONNX model against a safetensors MLP with onnxruntime.

Usage: onnxruntime_check.py MODEL.onnx ACTOR.safetensors ACTIVATION

Prints the largest difference between the model's output (run by onnxruntime, float32) and
the MLP computed in numpy (float64) from the safetensors file, on 512 observations, in units of
float32 rounding: the difference of each output divided by float32's epsilon times the output's
condition (the sum of |weight x input| + |bias| of the last layer). A float32 evaluation of the
same network lands within a few units (numpy's own float32 product does, at about 6); a wrong
weight, layer or activation lands thousands of units away.
"""

from __future__ import annotations

import json
import struct
import sys
from pathlib import Path

import numpy as np
import onnxruntime


def load_safetensors(path: Path) -> dict[str, np.ndarray]:
    """The float32 tensors of a safetensors file."""
    data = path.read_bytes()
    (length,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8 : 8 + length])
    body = data[8 + length :]
    return {
        name: np.frombuffer(body[e["data_offsets"][0] : e["data_offsets"][1]], "<f4").reshape(
            e["shape"]
        )
        for name, e in header.items()
        if name != "__metadata__"
    }


def main() -> None:
    """Compare and print the largest difference in units of float32 rounding."""
    model, actor, activation = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
    tensors = load_safetensors(actor)
    prefix = min(n[: -len(".0.weight")] for n in tensors if n.endswith(".0.weight"))
    layers = []
    while f"{prefix}.{len(layers)}.weight" in tensors:
        i = len(layers)
        layers.append((tensors[f"{prefix}.{i}.weight"], tensors[f"{prefix}.{i}.bias"]))
    act = {
        "tanh": np.tanh,
        "relu": lambda x: np.maximum(x, 0),
        "elu": lambda x: np.where(x > 0, x, np.expm1(x)),
    }[activation]
    rng = np.random.default_rng(0)
    x = rng.uniform(-2, 2, size=(512, layers[0][0].shape[1])).astype(np.float32)
    expected = x.astype(np.float64)
    condition = np.ones(1)
    for k, (w, b) in enumerate(layers):
        condition = np.abs(expected) @ np.abs(w.T.astype(np.float64)) + np.abs(b)
        expected = expected @ w.T.astype(np.float64) + b
        if k < len(layers) - 1:
            expected = act(expected)
    session = onnxruntime.InferenceSession(str(model), providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name
    (got,) = session.run(None, {name: x})
    units = np.abs(got - expected) / (np.finfo(np.float32).eps * condition)
    print(float(units.max()))


if __name__ == "__main__":
    main()
