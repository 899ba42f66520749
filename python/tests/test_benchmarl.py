"""cpmx.benchmarl: BenchMARL trains on a cpmx task, and the documented example runs its loop."""

from __future__ import annotations

import subprocess
import sys

from conftest import REPOSITORY


def test_the_example_trains_exports_and_evaluates(tmp_path, reference):
    example = REPOSITORY / "examples" / "python" / "benchmarl_at25.py"
    done = subprocess.run(
        [sys.executable, str(example), "--data", str(reference), "--quick", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "actor.safetensors").is_file()
    # The zero-shot table: one row per fidelity of at25 for the BenchMARL policy.
    for fidelity in ("sim", "sim-mpc", "twin"):
        assert f"| {fidelity} | benchmarl-mappo |" in done.stdout, done.stdout
