"""cpmx's environment as a BenchMARL task.

A :class:`CpmxTask` is a BenchMARL ``TaskClass`` whose environment is
:class:`cpmx.torchrl.CpmxEnv`: any algorithm BenchMARL has (MAPPO, IPPO, ...) trains on a
cpmx spec's training scenario, in any of the spec's fidelities. BenchMARL's batch of
environments is cpmx's batch (stepped in Rust, in parallel), not a ``SerialEnv`` of copies.

Example::

    from benchmarl.algorithms import MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models.mlp import MlpConfig
    from cpmx.benchmarl import CpmxTask

    task = CpmxTask.from_spec(
        "experiments/at25-cpmx.yaml", fidelity="twin", data="path/to/reference"
    )
    experiment = Experiment(
        task=task,
        algorithm_config=MappoConfig.get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=ExperimentConfig.get_from_yaml(),
    )
    experiment.run()

``examples/python/benchmarl_at25.py`` trains MAPPO so, writes the actor and evaluates it with
``cpmx run``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

from cpmx._extras import missing_extra

try:
    from benchmarl.environments.common import TaskClass
    from torchrl.data import Composite
    from torchrl.envs import EnvBase
except ModuleNotFoundError as error:  # the adapter's host library is an extra
    raise missing_extra("cpmx.benchmarl", "benchmarl", error) from error

from cpmx.torchrl import CpmxEnv

__all__ = ["CpmxTask"]


class CpmxTask(TaskClass):
    """A cpmx spec's training scenario as a BenchMARL task.

    ``config`` keys: ``spec`` (the spec file, required), ``fidelity`` (default: the training
    section's), ``data`` (folders to look up maps in), ``max_steps`` (of an evaluation
    rollout; default: the scenario's episode length).
    """

    def __init__(self, name: str, config: dict[str, Any]) -> None:
        """A task named ``name`` (BenchMARL's logs and folders use it) with ``config``."""
        if "spec" not in config:
            raise ValueError("CpmxTask needs config['spec'], the spec file")
        super().__init__(name=name, config=config)

    @classmethod
    def from_spec(
        cls,
        spec: str | os.PathLike[str],
        fidelity: str | None = None,
        data: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = None,
        name: str | None = None,
    ) -> CpmxTask:
        """The task of ``spec``'s training section in ``fidelity``."""
        if data is not None and isinstance(data, str | os.PathLike):
            data = [data]
        config = {
            "spec": os.fspath(spec),
            "fidelity": fidelity,
            "data": None if data is None else [os.fspath(d) for d in data],
        }
        stem = os.path.splitext(os.path.basename(os.fspath(spec)))[0]
        return cls(name or f"{stem}_{fidelity or 'default'}".replace("-", "_"), config)

    def get_env_fun(
        self,
        num_envs: int,
        continuous_actions: bool,
        seed: int | None,
        device: Any,
    ) -> Callable[[], EnvBase]:
        """A function that makes the batched environment (``num_envs`` cpmx environments)."""
        if not continuous_actions:
            raise ValueError("cpmx's actions are continuous (speed and steering)")
        config = dict(self.config)
        return lambda: CpmxEnv(
            config["spec"],
            fidelity=config.get("fidelity"),
            num_envs=num_envs,
            seed=0 if seed is None else seed,
            device=device,
            data=config.get("data"),
        )

    def supports_continuous_actions(self) -> bool:
        """Speed and steering are continuous."""
        return True

    def supports_discrete_actions(self) -> bool:
        """No discrete actions."""
        return False

    def has_render(self, env: EnvBase) -> bool:
        """Rendering goes through cpmx's report page, not BenchMARL's videos."""
        return False

    def max_steps(self, env: EnvBase) -> int:
        """The evaluation rollout's length: ``max_steps`` or the scenario's episode length."""
        return int(self.config.get("max_steps") or env._env.episode_steps)

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        """One group, ``"agents"``."""
        return {"agents": list(env.agent_names)}

    def state_spec(self, env: EnvBase) -> Composite | None:
        """No global state beyond the agents' observations."""
        return None

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        """Every action is allowed."""
        return None

    def observation_spec(self, env: EnvBase) -> Composite:
        """The agents' observations."""
        return env.full_observation_spec_unbatched.clone()

    def info_spec(self, env: EnvBase) -> Composite | None:
        """No info keys."""
        return None

    def action_spec(self, env: EnvBase) -> Composite:
        """Speed [m/s] and steering [rad] per agent."""
        return env.full_action_spec_unbatched

    @staticmethod
    def env_name() -> str:
        """BenchMARL's name of the environment."""
        return "cpmx"
