"""cpmx's environment as a TorchRL ``EnvBase``.

The batch is ``(num_envs,)``; the agents form one group, ``"agents"``, laid out as TorchRL's
multi-agent environments (VMAS) lay theirs out::

    ("agents", "observation")   float32[num_envs, n_agents, observation_size]
    ("agents", "action")        float32[num_envs, n_agents, 2]   speed m/s, steering rad
    ("next", "agents", "reward")  float32[num_envs, n_agents, 1]
    "done", "terminated", "truncated"  bool[num_envs, 1]   (an episode ends for all agents)

Ended environments are reset when TorchRL asks (``"_reset"``, as ``step_and_maybe_reset``
and collectors do): the environment has placed the next episode in the step that ended the
last one, so ``"next"`` holds where that episode ended and the reset hands out the new
episode's first observations.

Example::

    from torchrl.envs.utils import check_env_specs
    from cpmx.torchrl import CpmxEnv

    env = CpmxEnv("experiments/at25-cpmx.yaml", fidelity="twin", num_envs=32, seed=0)
    check_env_specs(env)
    rollout = env.rollout(100)
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from cpmx._extras import missing_extra

try:
    import torch
    from tensordict import TensorDict, TensorDictBase
    from torchrl.data import Bounded, Categorical, Composite, Unbounded
    from torchrl.envs import EnvBase
except ModuleNotFoundError as error:  # the adapter's host library is an extra
    raise missing_extra("cpmx.torchrl", "torchrl", error) from error

from cpmx._cpmx import VecEnv

__all__ = ["CpmxEnv"]


class CpmxEnv(EnvBase):
    """A cpmx spec's training scenario as a batched TorchRL environment (see the module)."""

    batch_locked = True

    def __init__(
        self,
        spec: str | os.PathLike[str],
        fidelity: str | None = None,
        num_envs: int = 32,
        seed: int = 0,
        device: str | torch.device = "cpu",
        data: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = None,
    ) -> None:
        """Load the spec's ``training:`` section in ``fidelity`` (default: the section's own).

        Args:
            spec: The spec file.
            fidelity: A fidelity of the spec (default: the one the section trains in).
            num_envs: Environments stepped together (the batch size).
            seed: The random streams' seed (``set_seed`` gives another).
            device: Where the tensors live.
            data: Folders to look up maps in (default: ``CPMX_DATA``).

        """
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        if data is not None and isinstance(data, str | os.PathLike):
            data = [data]
        self._env = VecEnv(
            os.fspath(spec),
            fidelity=fidelity,
            num_envs=num_envs,
            seed=seed,
            data=None if data is None else [os.fspath(d) for d in data],
        )
        self.n_agents = self._env.num_agents
        self.agent_names = list(self._env.agents)
        self.group_map = {"agents": self.agent_names}
        self._seed_next_reset: int | None = seed
        self._observations: np.ndarray | None = None
        # Where the environment already placed the next episode (its first observations),
        # for the reset TorchRL asks for after a step that ended an episode.
        self._placed = np.zeros(num_envs, dtype=bool)
        self._on_cpu = self.device == torch.device("cpu")
        self._make_specs()

    def _make_specs(self) -> None:
        e, a, o = self.batch_size[0], self.n_agents, self._env.observation_size
        low = torch.as_tensor(self._env.action_low, device=self.device).expand(e, a, 2)
        high = torch.as_tensor(self._env.action_high, device=self.device).expand(e, a, 2)
        self.full_observation_spec = Composite(
            agents=Composite(
                observation=Unbounded(shape=(e, a, o), dtype=torch.float32, device=self.device),
                shape=(e, a),
            ),
            shape=(e,),
        )
        self.full_action_spec = Composite(
            agents=Composite(
                action=Bounded(
                    low=low.clone(),
                    high=high.clone(),
                    shape=(e, a, 2),
                    dtype=torch.float32,
                    device=self.device,
                ),
                shape=(e, a),
            ),
            shape=(e,),
        )
        self.full_reward_spec = Composite(
            agents=Composite(
                reward=Unbounded(shape=(e, a, 1), dtype=torch.float32, device=self.device),
                shape=(e, a),
            ),
            shape=(e,),
        )
        flag = Categorical(n=2, shape=(e, 1), dtype=torch.bool, device=self.device)
        self.full_done_spec = Composite(
            done=flag.clone(), terminated=flag.clone(), truncated=flag.clone(), shape=(e,)
        )

    def _tensor(self, array: np.ndarray) -> torch.Tensor:
        tensor = torch.from_numpy(np.ascontiguousarray(array))
        return tensor if self._on_cpu else tensor.to(self.device)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: object) -> TensorDictBase:
        e = self.batch_size[0]
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(e).cpu().numpy().astype(bool)
        if mask is None or self._observations is None:
            self._observations = self._env.reset(seed=self._seed_next_reset)
            self._seed_next_reset = None
            self._placed[:] = False
        else:
            # Environments that ended have been placed already; reset only the others asked for.
            fresh = mask & ~self._placed
            if fresh.any():
                self._observations = self._env.reset(mask=list(fresh))
            self._placed[mask] = False
        return self._output(self._observations, np.zeros((e, 1), dtype=bool))

    def _output(self, observations: np.ndarray, flags: np.ndarray) -> TensorDictBase:
        e = self.batch_size[0]
        # `_new_unsafe`, as TorchRL's own gym-like environments build theirs: the tensors are
        # made here with the specs' shapes, so the per-entry checks would only cost time.
        return TensorDict._new_unsafe(
            {
                "agents": TensorDict._new_unsafe(
                    {"observation": self._tensor(observations)},
                    batch_size=(e, self.n_agents),
                    device=self.device,
                ),
                "done": self._tensor(flags),
                "terminated": self._tensor(flags),
                "truncated": self._tensor(flags),
            },
            batch_size=self.batch_size,
            device=self.device,
        )

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        e = self.batch_size[0]
        actions = tensordict.get(("agents", "action")).detach().cpu().numpy()
        observations, reward, terminated, truncated, info = self._env.step(actions)
        term = terminated.any(axis=1)
        done = term | truncated
        self._observations = observations
        self._placed = done.copy()
        shown = (
            np.where(done[:, None, None], info["final_obs"], observations)
            if done.any()
            else observations
        )
        return TensorDict._new_unsafe(
            {
                "agents": TensorDict._new_unsafe(
                    {
                        "observation": self._tensor(shown),
                        "reward": self._tensor(reward[..., None]),
                    },
                    batch_size=(e, self.n_agents),
                    device=self.device,
                ),
                "done": self._tensor(done[:, None]),
                "terminated": self._tensor(term[:, None]),
                "truncated": self._tensor(truncated[:, None]),
            },
            batch_size=self.batch_size,
            device=self.device,
        )

    def maybe_reset(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Hand out the next episodes' first observations where an episode ended.

        ``step_and_maybe_reset`` (and TorchRL's collectors) call this on the step's ``"next"``
        moved to the root. The environment placed the next episodes in the step that ended the
        last ones, so this writes their first observations and clears the flags, without the
        round trip through ``reset`` and its merge (which random actions trigger every step).
        The result is the one ``reset`` with ``"_reset"`` gives.
        """
        if not self._placed.any():
            return tensordict
        placed = self._tensor(self._placed)
        agents = tensordict.get("agents")
        fresh = self._tensor(self._observations)
        agents.set(
            "observation", torch.where(placed[:, None, None], fresh, agents.get("observation"))
        )
        flags = tensordict.get("done")
        for key in ("done", "terminated", "truncated"):
            tensordict.set(key, torch.zeros_like(flags))
        self._placed[:] = False
        return tensordict

    def _set_seed(self, seed: int | None) -> None:
        # The next full reset restarts every environment's streams from `seed`.
        self._seed_next_reset = seed
