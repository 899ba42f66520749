"""cpmx.run with Python policies, cpmx.validate, cpmx.read_runs."""

from __future__ import annotations

import csv
import json
import struct
from pathlib import Path

import numpy as np
import pytest

import cpmx

SPEC = """\
cpmx: 1
name: numpy-actor
map: {{file: maps/cpm.xml}}
vehicle: stdlib:mu-car
timing: {{dt: 0.1, steps: {steps}}}
agents: 3
policies:
  - {{name: network, mlp: {{weights: policy/actor.safetensors}}, observation: stdlib:sigmarl, action: mean}}
  - {{name: numpy, python: {{}}, observation: stdlib:sigmarl}}
initial_configurations:
  - name: init1
    agents:
      - {{ref_path: 6, arc_length: 0.3}}
      - {{ref_path: 2, arc_length: 0.3}}
      - {{ref_path: 3, arc_length: 0.3}}
repetitions: 1
seed: 2026
fidelities:
  sim: {{control: direct, dynamics: kinematic}}
metrics: stdlib:at25
"""


def load_safetensors(path: Path) -> dict[str, np.ndarray]:
    """A safetensors file's float32 tensors, read with the format's own layout."""
    data = path.read_bytes()
    (length,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8 : 8 + length])
    body = data[8 + length :]
    tensors = {}
    for name, entry in header.items():
        if name == "__metadata__":
            continue
        start, end = entry["data_offsets"]
        tensors[name] = np.frombuffer(body[start:end], dtype="<f4").reshape(entry["shape"])
    return tensors


class NumpyActor:
    """SigmaRL's actor in numpy: tanh MLP, then the mean of its TanhNormal in the action box."""

    def __init__(self, weights: dict[str, np.ndarray]) -> None:
        self.layers = [
            (
                weights[f"actor.{i}.weight"].astype(np.float64),
                weights[f"actor.{i}.bias"].astype(np.float64),
            )
            for i in range(4)
        ]
        self.high = np.array([1.0, np.deg2rad(31.0)])

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        x = observations.astype(np.float64)
        for i, (w, b) in enumerate(self.layers):
            x = x @ w.T + b
            if i < len(self.layers) - 1:
                x = np.tanh(x)
        return self.high * np.clip(np.tanh(x[:, :2]), -1 + 1e-6, 1 - 1e-6)


def positions(folder: Path, policy: str) -> np.ndarray:
    path = folder / "runs" / "sim" / policy / "init1" / "rep1" / "trajectory.csv"
    with path.open() as f:
        rows = list(csv.DictReader(f))
    return np.array([[float(r["x"]), float(r["y"])] for r in rows])


def test_a_numpy_actor_drives_as_the_network(tmp_path, reference):
    spec = tmp_path / "numpy.yaml"
    spec.write_text(SPEC.format(steps=25))
    actor = NumpyActor(load_safetensors(reference / "policy" / "actor.safetensors"))
    result = cpmx.run(spec, out=tmp_path / "out", policies={"numpy": actor}, data=reference)
    assert result.failed == {} and result.finished == 2
    network, numpy = positions(result.out, "network"), positions(result.out, "numpy")
    assert network.shape == numpy.shape and len(network) >= 25 * 3
    assert np.abs(network - numpy).max() < 1e-4
    assert (result.out / "report.html").is_file()
    rows = cpmx.read_runs(result.out, frame=False)
    assert {r["policy"] for r in rows} == {"network", "numpy"}
    assert all(isinstance(r["cd_m"], float) for r in rows)


def test_states_reach_a_two_argument_policy_and_resume_keeps_runs(tmp_path, reference):
    spec = tmp_path / "states.yaml"
    spec.write_text(SPEC.format(steps=10))
    seen = []

    def stand_still(observations: np.ndarray, states: np.ndarray) -> np.ndarray:
        seen.append(states.copy())
        return np.zeros((len(states), 2))

    out = tmp_path / "out"
    cpmx.run(
        spec, out=out, policies={"numpy": stand_still}, only={"policy": "numpy"}, data=reference
    )
    assert seen and seen[0].shape == (3, 5)
    again = cpmx.run(spec, out=out, policies={"numpy": stand_still}, data=reference, resume=True)
    assert again.resumed == 1 and again.finished == 1


def test_a_failing_callable_fails_its_runs_only(tmp_path, reference):
    spec = tmp_path / "fails.yaml"
    spec.write_text(SPEC.format(steps=5))

    def broken(observations: np.ndarray) -> np.ndarray:
        raise RuntimeError("no idea")

    result = cpmx.run(spec, out=tmp_path / "out", policies={"numpy": broken}, data=reference)
    assert list(result.failed) == ["sim/numpy/init1/rep1"]
    assert "RuntimeError: no idea" in result.failed["sim/numpy/init1/rep1"]
    assert result.finished == 1


def test_unbound_and_unknown_policies_are_refused(tmp_path, reference):
    spec = tmp_path / "unbound.yaml"
    spec.write_text(SPEC.format(steps=5))
    with pytest.raises(cpmx.CpmxError, match="nothing was bound"):
        cpmx.run(spec, out=tmp_path / "a", data=reference)
    with pytest.raises(cpmx.CpmxError, match="`numpy`"):
        cpmx.run(spec, out=tmp_path / "b", policies={"nummpy": lambda o: o}, data=reference)


def test_validate_gives_every_diagnostic(tmp_path, reference):
    spec = tmp_path / "broken.yaml"
    spec.write_text(
        SPEC.format(steps=5)
        .replace("{ref_path: 2, arc_length: 0.3}", "{ref_path: 99, arc_length: 0.3}")
        .replace("seed: 2026", "seed: 2026\nplanner: {control_horizon: 9, prediction_horizon: 4}")
    )
    diagnostics = cpmx.validate(spec, data=reference)
    errors = [d for d in diagnostics if d.level == "error"]
    codes = {d.code for d in errors}
    assert codes == {"cpmx::map::ref-path", "cpmx::check::horizon"}, diagnostics
    path = next(d for d in errors if d.code == "cpmx::map::ref-path")
    assert path.line == 14 and path.column == 20 and path.file.endswith("broken.yaml")
    assert "reference path 99" in path.message and "broken.yaml:14:20" in path.text
    assert "0..=39" in (path.help or "")
    with pytest.raises(cpmx.CpmxError, match="cannot read"):
        cpmx.validate(tmp_path / "missing.yaml")
