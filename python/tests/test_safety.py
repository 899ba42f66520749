"""``cpmx.cbf_filter``: SigmaRL's CBF safety filter from Python."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cpmx


def lane(half_width_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A straight lane along x from -2 to 2 m, points every 0.05 m."""
    xs = np.linspace(-2.0, 2.0, 81)
    left = np.stack([xs, np.full_like(xs, half_width_m)], 1)
    right = np.stack([xs, np.full_like(xs, -half_width_m)], 1)
    return left, right


def test_a_car_heading_out_of_its_lane_is_turned_back_as_sigmarl_turns_it() -> None:
    # SigmaRL 1.4.0's own filter (cbf_qp.py, its QP solved exactly) gives (0.8014386, -pi/4)
    # with the rear-left and front-right rows active (research/cbf-reference-cases.md, case A).
    left, right = lane(0.15)
    out = cpmx.cbf_filter([0.0, 0.08, 0.2, 0.8, 0.1], [1.0, 0.3], left, right)
    assert out.fallback is None
    assert out.action[0] == pytest.approx(0.8014386296272278, abs=1e-6)
    assert out.action[1] == pytest.approx(-0.7853981852531433, abs=1e-6)
    assert out.active == [0, 5]
    assert [(r[0], r[1]) for r in out.rows[:2]] == [(0, "left"), (0, "right")]


def test_no_action_keeps_it_then_the_clamped_nominal_one_goes_through() -> None:
    # Case F: perpendicular to the left boundary at 1 m/s, 1 cm too close: infeasible.
    left, right = lane(0.15)
    out = cpmx.cbf_filter([0.0, 0.05, 1.5707963, 1.0, 0.0], [1.0, 0.0], left, right)
    assert out.fallback == "infeasible"
    assert out.action == (1.0, 0.0)
    nan = cpmx.cbf_filter([float("nan"), 0.0, 0.0, 0.5, 0.0], [2.0, 0.0], left, right)
    assert nan.fallback == "not-finite"
    assert nan.action == (1.0, 0.0)


def test_bad_arguments_raise_value_errors() -> None:
    left, right = lane(0.15)
    with pytest.raises(ValueError, match="left boundary needs two points"):
        cpmx.cbf_filter([0.0] * 5, [0.0, 0.0], [[0.0, 0.15]], right)
    with pytest.raises(ValueError, match="circles must be positive"):
        cpmx.cbf_filter([0.0] * 5, [0.0, 0.0], left, right, circles=0)


def test_a_training_environment_drives_through_the_fidelitys_filter(reference: Path) -> None:
    """``VecEnv`` in a fidelity with a ``safety:`` layer filters the actions it is given."""
    spec = Path(__file__).resolve().parents[2] / "experiments" / "cbf-training.yaml"

    def rollout(fidelity: str) -> np.ndarray:
        env = cpmx.VecEnv(spec, fidelity=fidelity, num_envs=4, seed=7, data=reference)
        env.reset()
        # Full speed, full steering: every car heads off its lane at once.
        actions = np.tile(np.array([1.0, 0.5], dtype=np.float32), (4, env.num_agents, 1))
        observations = []
        for _ in range(5):
            observations.append(env.step(actions)[0].copy())
        return np.stack(observations)

    plain, filtered = rollout("sim"), rollout("sim-cbf")
    assert plain.shape == filtered.shape
    assert not np.array_equal(plain, filtered)
    # The same fidelity twice: the same bits.
    assert np.array_equal(filtered, rollout("sim-cbf"))
