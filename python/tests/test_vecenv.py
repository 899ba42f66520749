"""cpmx.VecEnv: shapes, errors, determinism, and cpmx train's environment bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

import cpmx
from cpmx import _cpmx


def random_actions(env: cpmx.VecEnv, rng: np.random.Generator) -> np.ndarray:
    low, high = env.action_low, env.action_high
    return rng.uniform(low, high, size=(env.num_envs, env.num_agents, 2)).astype(np.float32)


@pytest.mark.parametrize("fidelity", ["sim", "twin"])
def test_shapes_and_spaces(at25, reference, fidelity):
    env = cpmx.VecEnv(at25, fidelity=fidelity, num_envs=4, seed=1, data=reference)
    assert env.agents == [f"agent_{i}" for i in range(env.num_agents)]
    obs = env.reset()
    assert obs.shape == (4, env.num_agents, env.observation_size)
    assert obs.dtype == np.float32
    assert (
        env.action_low.shape == (2,) and np.all(env.action_low < 0) and np.all(env.action_high > 0)
    )
    assert env.state().shape == (4, env.num_agents * env.observation_size)
    obs, reward, terminated, truncated, info = env.step(
        random_actions(env, np.random.default_rng(0))
    )
    assert reward.shape == (4, env.num_agents) and reward.dtype == np.float32
    assert terminated.shape == (4, env.num_agents) and terminated.dtype == np.bool_
    assert truncated.shape == (4,)
    assert info["episode_return"].shape == (4, env.num_agents)
    image = env.render(0)
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
    # Footprints and roads are drawn: the picture is not blank.
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 3
    assert env.autoreset_mode == "same-step"


def test_episodes_end_with_their_final_observation(at25, reference):
    env = cpmx.VecEnv(at25, num_envs=8, seed=3, data=reference)
    env.reset()
    rng = np.random.default_rng(1)
    for _ in range(env.episode_steps + 1):
        obs, _, terminated, truncated, info = env.step(random_actions(env, rng))
        ended = terminated.any(axis=1) | truncated
        if ended.any():
            assert np.array_equal(info["_final_obs"], ended)
            # The returned observation is the next episode's first, not where this one ended.
            assert not np.array_equal(info["final_obs"][ended], obs[ended])
            return
    pytest.fail("no episode ended within the time limit")


def test_same_seed_same_bits_and_another_seed_differs(at25, reference):
    def rollout(seed: int, steps: int, fidelity: str = "sim") -> list[np.ndarray]:
        env = cpmx.VecEnv(at25, fidelity=fidelity, num_envs=32, seed=seed, data=reference)
        rng = np.random.default_rng(42)
        out = [env.reset()]
        for _ in range(steps):
            obs, reward, terminated, truncated, _ = env.step(random_actions(env, rng))
            out += [obs, reward, terminated, truncated]
        return out

    a, b = rollout(7, 300), rollout(7, 300)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    c = rollout(8, 5)
    assert not np.array_equal(a[0], c[0])


def test_a_thread_count_changes_nothing(at25, reference):
    rng = np.random.default_rng(5)
    one = cpmx.VecEnv(at25, num_envs=16, seed=2, data=reference, threads=1)
    two = cpmx.VecEnv(at25, num_envs=16, seed=2, data=reference, threads=2)
    assert np.array_equal(one.reset(), two.reset())
    for _ in range(50):
        actions = random_actions(one, rng)
        assert all(
            np.array_equal(x, y)
            for x, y in zip(one.step(actions)[:4], two.step(actions)[:4], strict=True)
        )


@pytest.mark.parametrize("fidelity", ["sim", "sim-mpc"])
def test_the_episodes_are_cpmx_trains(at25, reference, fidelity):
    # The learner's environment (cpmx_train's TrainingEnv, as `cpmx train` makes it for a seed)
    # stepped with the same actions.
    steps = 140
    rng = np.random.default_rng(9)
    env = cpmx.VecEnv(at25, fidelity=fidelity, num_envs=32, seed=4, data=reference)
    actions = np.stack([random_actions(env, rng) for _ in range(steps)])
    observations = [env.reset()]
    rewards = []
    for t in range(steps):
        obs, reward, *_ = env.step(actions[t])
        observations.append(obs)
        rewards.append(reward)
    trained_obs, trained_rewards = _cpmx._training_rollout(
        str(at25), fidelity, 4, actions, [str(reference)]
    )
    assert np.array_equal(np.stack(observations), trained_obs)
    assert np.array_equal(np.stack(rewards), trained_rewards)


def test_reset_by_mask_replaces_only_those(at25, reference):
    env = cpmx.VecEnv(at25, num_envs=4, seed=0, data=reference)
    env.reset()
    obs, *_ = env.step(np.zeros((4, env.num_agents, 2), np.float32))
    again = env.reset(mask=[False, True, False, False])
    assert np.array_equal(again[[0, 2, 3]], obs[[0, 2, 3]])
    assert not np.array_equal(again[1], obs[1])
    with pytest.raises(ValueError, match="4 environments"):
        env.reset(mask=[True])


def test_bad_input_raises_with_the_diagnostic(tmp_path, at25, reference):
    env = cpmx.VecEnv(at25, num_envs=2, data=reference)
    env.reset()
    with pytest.raises(ValueError, match=r"expected \[2, 4, 2\]"):
        env.step(np.zeros((2, 3, 2), np.float32))
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.full((2, 4, 2), np.nan, np.float32))
    spec = tmp_path / "bad.yaml"
    spec.write_text(
        at25.read_text().replace("timing: {dt: 0.1, steps: 180}", 'timing: {dt: 0.1, steps: "180"}')
    )
    with pytest.raises(cpmx.CpmxError) as error:
        cpmx.VecEnv(spec, data=reference)
    text = str(error.value)
    assert "bad.yaml:" in text and "remove the quotes" in text
    with pytest.raises(cpmx.CpmxError, match="no such fidelity"):
        cpmx.VecEnv(at25, fidelity="nowhere", data=reference)


def test_a_missing_map_says_how_python_adds_a_data_folder(tmp_path, monkeypatch, at25):
    monkeypatch.delenv("CPMX_DATA", raising=False)
    spec = tmp_path / "at25.yaml"
    spec.write_text(at25.read_text())
    with pytest.raises(cpmx.CpmxError) as error:
        cpmx.VecEnv(spec)
    message = str(error.value)
    assert "map file `maps/cpm.xml` was not found" in message
    assert "name its folder with `data=` or `CPMX_DATA`" in message
    assert "--data" not in message


@pytest.mark.parametrize(
    ("adapter", "library"),
    [("cpmx.torchrl", "torch"), ("cpmx.pettingzoo", "pettingzoo"), ("cpmx.benchmarl", "benchmarl")],
)
def test_an_adapter_without_its_library_says_which_extra_installs_it(monkeypatch, adapter, library):
    import importlib
    import sys

    for name in [m for m in sys.modules if m == adapter or m.startswith("cpmx.torchrl")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, library, None)  # `import library` now fails
    with pytest.raises(ModuleNotFoundError) as error:
        importlib.import_module(adapter)
    message = str(error.value)
    assert f"{adapter} needs the module `{library}`, which is not installed" in message
    assert f"pip install './python[{adapter.split('.')[1]}]'" in message


def test_the_follower_stops_are_counted_through_the_labs_stack(at25, reference):
    # Random actions make jittery plans, some of which the lab's MPC refuses: the car stops.
    counted = {}
    for fidelity in ("sim", "twin"):
        env = cpmx.VecEnv(at25, fidelity=fidelity, num_envs=8, seed=1, data=reference)
        env.reset()
        rng = np.random.default_rng(0)
        total = 0
        for _ in range(40):
            *_, info = env.step(random_actions(env, rng))
            stopped = info["follower_stopped_periods"]
            assert stopped.shape == (8, env.num_agents) and stopped.dtype == np.uint32
            # At most the step's 50 Hz periods (dt 0.1 s: five).
            assert stopped.max() <= 5
            total += int(stopped.sum())
        counted[fidelity] = total
    assert counted["sim"] == 0
    assert counted["twin"] > 0
