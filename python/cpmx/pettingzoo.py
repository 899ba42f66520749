"""cpmx's environment as a PettingZoo ``ParallelEnv``.

One environment of a spec's training scenario, its agents ``agent_0``, ``agent_1``, ... acting
simultaneously. An episode ends for every agent at once (SigmaRL's scenario ends a whole
environment on a collision, and truncates it at the time limit); an agent that reaches the
end of an open path is re-placed alone and goes on (``infos[agent]["replaced"]``).

Example::

    import cpmx.pettingzoo

    env = cpmx.pettingzoo.parallel_env("experiments/at25-cpmx.yaml", fidelity="twin",
                                       render_mode="rgb_array")
    observations, infos = env.reset(seed=1)
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from cpmx._extras import missing_extra

try:
    from gymnasium import spaces
    from pettingzoo import ParallelEnv
except ModuleNotFoundError as error:  # the adapter's host library is an extra
    raise missing_extra("cpmx.pettingzoo", "pettingzoo", error) from error

from cpmx._cpmx import VecEnv

__all__ = ["CpmxParallelEnv", "parallel_env"]


class CpmxParallelEnv(ParallelEnv):
    """One environment of a cpmx spec's training scenario; see the module documentation."""

    metadata: ClassVar[dict[str, object]] = {
        "render_modes": ["rgb_array"],
        "name": "cpmx_v0",
        "is_parallelizable": True,
    }

    def __init__(
        self,
        spec: str | os.PathLike[str],
        fidelity: str | None = None,
        seed: int | None = None,
        render_mode: str | None = None,
        data: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = None,
    ) -> None:
        """Load the spec's ``training:`` section in ``fidelity`` (default: the section's own).

        Args:
            spec: The spec file.
            fidelity: A fidelity of the spec (default: the one the section trains in).
            seed: The random streams' seed until ``reset(seed=...)`` gives another (default 0).
            render_mode: ``"rgb_array"`` or ``None``.
            data: Folders to look up maps in (default: ``CPMX_DATA``).

        """
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be 'rgb_array' or None, got {render_mode!r}")
        if data is not None and isinstance(data, str | os.PathLike):
            data = [data]
        self._env = VecEnv(
            os.fspath(spec),
            fidelity=fidelity,
            num_envs=1,
            seed=0 if seed is None else seed,
            data=None if data is None else [os.fspath(d) for d in data],
        )
        self.render_mode = render_mode
        self.possible_agents: list[str] = list(self._env.agents)
        self.agents: list[str] = []
        self._low = np.asarray(self._env.action_low, dtype=np.float32)
        self._high = np.asarray(self._env.action_high, dtype=np.float32)

    @functools.cache  # noqa: B019 - PettingZoo asks for the same object per agent
    def observation_space(self, agent: str) -> spaces.Box:
        """SigmaRL's observation of one agent (float32, unbounded)."""
        size = self._env.observation_size
        return spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32)

    @functools.cache  # noqa: B019 - PettingZoo asks for the same object per agent
    def action_space(self, agent: str) -> spaces.Box:
        """Target speed [m/s] and steering angle [rad], within the vehicle's limits."""
        return spaces.Box(self._low, self._high, dtype=np.float32)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Start an episode; ``seed`` restarts the random streams from it."""
        observations = self._env.reset(seed=seed)[0]
        self.agents = list(self.possible_agents)
        obs = {a: observations[i] for i, a in enumerate(self.possible_agents)}
        return obs, {a: {} for a in self.agents}

    def step(
        self, actions: dict[str, np.ndarray]
    ) -> tuple[
        dict[str, np.ndarray],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        """Every agent's action at once; returns PettingZoo's five per-agent dicts."""
        if not self.agents:
            raise RuntimeError("the episode has ended: call reset() first")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no action for {', '.join(missing)}")
        batch = np.stack([np.asarray(actions[a], dtype=np.float32) for a in self.possible_agents])
        observations, rewards, terminated, truncated, info = self._env.step(batch[None])
        ended = bool(terminated[0].any() or truncated[0])
        if ended:
            # The environment has already placed the next episode: hand out where this one ended.
            observations = info["final_obs"]
        obs = {a: observations[0, i] for i, a in enumerate(self.possible_agents)}
        reward = {a: float(rewards[0, i]) for i, a in enumerate(self.possible_agents)}
        term = {a: bool(terminated[0, i]) for i, a in enumerate(self.possible_agents)}
        trunc = {a: bool(truncated[0]) for a in self.possible_agents}
        infos = {
            a: {
                "collides_with_agents": bool(info["collides_with_agents"][0, i]),
                "collides_with_boundary": bool(info["collides_with_boundary"][0, i]),
                "replaced": bool(info["agent_replaced"][0, i]),
                "follower_stopped_periods": int(info["follower_stopped_periods"][0, i]),
            }
            for i, a in enumerate(self.possible_agents)
        }
        if ended:
            self.agents = []
        return obs, reward, term, trunc, infos

    def render(self) -> np.ndarray | None:
        """The environment as ``uint8[H, W, 3]`` (map, reference paths, footprints to scale)."""
        if self.render_mode is None:
            return None
        return self._env.render(0)

    def state(self) -> np.ndarray:
        """Every agent's observation, concatenated (the centralised critic's input)."""
        return self._env.state()[0]

    def close(self) -> None:
        """Nothing to release."""


def parallel_env(
    spec: str | os.PathLike[str],
    fidelity: str | None = None,
    seed: int | None = None,
    render_mode: str | None = None,
    data: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = None,
) -> CpmxParallelEnv:
    """A PettingZoo ``ParallelEnv`` of a cpmx spec's training scenario; see the module docs."""
    return CpmxParallelEnv(spec, fidelity=fidelity, seed=seed, render_mode=render_mode, data=data)
