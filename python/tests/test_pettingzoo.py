"""cpmx.pettingzoo: PettingZoo's own conformance tests, and whole episodes replayed."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test
from pettingzoo.utils.conversions import parallel_to_aec

import cpmx.pettingzoo


@pytest.mark.parametrize("fidelity", ["sim", "twin"])
def test_parallel_api(at25, reference, fidelity):
    env = cpmx.pettingzoo.parallel_env(at25, fidelity=fidelity, seed=1, data=reference)
    parallel_api_test(env, num_cycles=200)


def test_aec_api(at25, reference):
    env = cpmx.pettingzoo.parallel_env(at25, seed=2, data=reference)
    api_test(parallel_to_aec(env), num_cycles=200)


def test_rgb_array(at25, reference):
    env = cpmx.pettingzoo.parallel_env(at25, seed=1, render_mode="rgb_array", data=reference)
    env.reset(seed=1)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert cpmx.pettingzoo.parallel_env(at25, data=reference).render() is None


def play(env: cpmx.pettingzoo.CpmxParallelEnv, seed: int, episodes: int) -> list:
    """Every value of whole episodes, actions drawn from seeded action spaces."""
    trace = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed if episode == 0 else None)
        trace.append(obs)
        for k, agent in enumerate(env.possible_agents):
            env.action_space(agent).seed(seed + 100 * episode + k)
        while env.agents:
            actions = {a: env.action_space(a).sample() for a in env.agents}
            trace.append(env.step(actions)[:4])
    return trace


def test_whole_episodes_repeat_bit_for_bit(at25, reference):
    # PettingZoo's parallel_seed_test compares one step; this compares three whole episodes.
    def values(trace: list) -> list:
        flat = []
        for item in trace:
            for part in item if isinstance(item, tuple) else (item,):
                flat.extend(np.asarray(part[a]).tobytes() for a in sorted(part))
        return flat

    first = play(cpmx.pettingzoo.parallel_env(at25, data=reference), seed=11, episodes=3)
    second = play(cpmx.pettingzoo.parallel_env(at25, data=reference), seed=11, episodes=3)
    assert len(first) > 3 * 2
    assert values(first) == values(second)
    other = play(cpmx.pettingzoo.parallel_env(at25, data=reference), seed=12, episodes=1)
    assert values(first)[:4] != values(other)[:4]


def test_stepping_after_the_end_is_refused(at25, reference):
    env = cpmx.pettingzoo.parallel_env(at25, seed=1, data=reference)
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
