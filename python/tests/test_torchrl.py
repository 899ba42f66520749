"""cpmx.torchrl.CpmxEnv: TorchRL's own spec check, rollouts across episode ends, seeding."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs.utils import check_env_specs

from cpmx.torchrl import CpmxEnv


@pytest.mark.parametrize("fidelity", ["sim", "twin"])
def test_check_env_specs(at25, reference, fidelity):
    env = CpmxEnv(at25, fidelity=fidelity, num_envs=4, seed=0, data=reference)
    check_env_specs(env)
    assert env.batch_size == torch.Size([4])
    assert env.action_key == ("agents", "action")
    assert env.full_action_spec["agents", "action"].shape == (4, env.n_agents, 2)


def test_rollout_crosses_episode_ends(at25, reference):
    env = CpmxEnv(at25, num_envs=8, seed=1, data=reference)
    steps = 300  # beyond the 128-step time limit: every environment resets at least twice
    rollout = env.rollout(steps, break_when_any_done=False)
    assert rollout.batch_size == torch.Size([8, steps])
    done = rollout.get(("next", "done"))
    assert done.sum() >= 16
    # Where an episode ended, the next step starts from the next episode's first observation.
    ended = done[:, :-1, 0]
    after = rollout.get(("agents", "observation"))[:, 1:][ended]
    final = rollout.get(("next", "agents", "observation"))[:, :-1][ended]
    assert not torch.equal(after, final)


def test_seeding_repeats_rollouts(at25, reference):
    def rollout(seed: int) -> torch.Tensor:
        env = CpmxEnv(at25, num_envs=4, seed=0, data=reference)
        env.set_seed(seed)
        torch.manual_seed(0)
        return env.rollout(50, break_when_any_done=False).get(("next", "agents", "observation"))

    assert torch.equal(rollout(3), rollout(3))
    assert not torch.equal(rollout(3), rollout(4))


def test_the_shortcut_reset_gives_what_torchrls_reset_gives(at25, reference):
    # Two environments, the same seed and actions: one resets ended episodes through
    # `maybe_reset` (the placed observations), the other through TorchRL's `reset` with
    # `"_reset"` (EnvBase's `maybe_reset`, which calls `_reset` with the mask).
    from torchrl.envs import EnvBase

    fast, generic = (CpmxEnv(at25, num_envs=8, seed=2, data=reference) for _ in range(2))
    td_fast, td_generic = fast.reset(), generic.reset()
    torch.manual_seed(0)
    resets = 0
    for _ in range(200):
        action = fast.full_action_spec.rand()
        td_fast.update(action)
        td_generic.update(action.clone())
        td_fast = fast._step_mdp(fast.step(td_fast))
        td_generic = generic._step_mdp(generic.step(td_generic))
        resets += int(td_fast.get("done").any())
        td_fast = fast.maybe_reset(td_fast)
        td_generic = EnvBase.maybe_reset(generic, td_generic)
        for key in [("agents", "observation"), "done", "terminated", "truncated"]:
            assert torch.equal(td_fast.get(key), td_generic.get(key)), key
    assert resets >= 8
