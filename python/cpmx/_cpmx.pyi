"""Type stubs of ``cpmx._cpmx``, the Rust extension (see ``python/src/``)."""

from collections.abc import Callable, Mapping, Sequence
from os import PathLike
from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str

class CpmxError(Exception):
    """A problem cpmx found: an invalid spec (every diagnostic with file:line:col and help),
    a map or weights it cannot use, or a run folder it cannot write.
    """

class Diagnostic:
    """One problem of a spec, as ``cpmx validate`` prints it."""

    level: str
    """``"error"`` or ``"warning"``."""
    code: str
    """A stable identifier of the kind of problem, e.g. ``cpmx::schema::type``."""
    message: str
    file: str
    line: int
    """1-based."""
    column: int
    """1-based, in characters."""
    label: str
    help: str | None
    text: str
    """The diagnostic as ``cpmx validate`` renders it."""

class VecEnv:
    """E environments of a spec's training scenario, stepped together.

    The spec's ``training:`` section (scenario, reward, observation) in ``fidelity`` (any
    fidelity of the spec; default the section's own, with its per-episode randomisation), as
    ``cpmx train`` steps it: with the same ``seed`` the episodes are ``cpmx train``'s, bit for
    bit. Autoreset is Gymnasium's ``SAME_STEP`` mode: a step that ends an episode returns the
    next episode's first observations, and the ended episode's last ones in
    ``info["final_obs"]`` (rows where ``info["_final_obs"]`` is true).

    Through a planning fidelity (``control: trajectory``) the action is held for the control
    horizon (``training.lookahead: hold``): a ``VecEnv`` has no actor to look ahead with.
    """

    def __init__(
        self,
        spec: str | PathLike[str],
        fidelity: str | None = None,
        num_envs: int = 32,
        seed: int = 0,
        data: str | PathLike[str] | Sequence[str | PathLike[str]] | None = None,
        threads: int | None = None,
    ) -> None:
        """Load ``spec`` (raises ``CpmxError`` with every diagnostic if it has errors).

        ``data``: folders to look up maps in, before ``CPMX_DATA``. ``threads``: threads that
        step environments in parallel (default: rayon's pool, one per core); the results do
        not depend on it.
        """

    def reset(
        self, seed: int | None = None, mask: Sequence[bool] | None = None
    ) -> npt.NDArray[np.float32]:
        """Re-place every environment (or those whose ``mask`` entry is true); ``seed`` first
        restarts every random stream from it. Returns the observations ``float32[E, A, O]``.
        """

    def step(
        self, actions: npt.ArrayLike
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
        dict[str, Any],
    ]:
        """One step: ``actions[E, A, 2]`` (target speed m/s, steering rad) →
        ``(observations[E, A, O], reward[E, A], terminated[E, A], truncated[E], info)``.

        ``terminated``: the episode ended by a collision or line rule (for every agent of the
        environment); ``truncated``: by the time limit. ``info``: ``final_obs`` and
        ``_final_obs`` (when an episode ended), ``episode_return[E, A]``,
        ``collides_with_agents[E, A]``, ``collides_with_boundary[E, A]``, ``agent_replaced[E, A]``
        (an agent at the end of an open path, re-placed alone), ``follower_stopped_periods[E, A]``
        (the step's 50 Hz periods in which the lab's follower stopped the vehicle once commanded:
        a refused trajectory, a command too old, positioning lost; 0 without the lab's stack).
        """

    def state(self) -> npt.NDArray[np.float32]:
        """The centralised critic's input: the agents' observations concatenated, ``[E, A·O]``."""

    def render(self, env: int = 0, width: int = 640) -> npt.NDArray[np.uint8]:
        """Environment ``env`` as ``uint8[H, W, 3]``: road boundaries, the agents' reference
        paths and footprints to scale.
        """

    @property
    def agents(self) -> list[str]:
        """``["agent_0", "agent_1", ...]``."""
    @property
    def num_envs(self) -> int: ...
    @property
    def num_agents(self) -> int: ...
    @property
    def observation_size(self) -> int: ...
    @property
    def state_size(self) -> int: ...
    @property
    def action_low(self) -> npt.NDArray[np.float32]:
        """``[-max speed m/s, -max steering rad]``."""
    @property
    def action_high(self) -> npt.NDArray[np.float32]:
        """``[max speed m/s, max steering rad]``."""
    @property
    def episode_steps(self) -> int:
        """Steps per episode (the time limit)."""
    @property
    def dt(self) -> float:
        """The policy step [s]."""
    @property
    def fidelity(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def autoreset_mode(self) -> str:
        """``"same-step"``: Gymnasium's ``AutoresetMode.SAME_STEP``."""

def validate(
    spec: str | PathLike[str],
    data: str | PathLike[str] | Sequence[str | PathLike[str]] | None = None,
) -> list[Diagnostic]:
    """Every diagnostic ``cpmx validate`` gives ``spec``."""

def _cbf_filter(
    state: Sequence[float],
    action: Sequence[float],
    left: Sequence[Sequence[float]],
    right: Sequence[Sequence[float]],
    circles: int = 3,
    dt_s: float = 0.05,
) -> tuple[
    list[float],
    str | None,
    list[int],
    list[tuple[int, str, float, float, float, float]],
]:
    """SigmaRL's CBF safety filter for one vehicle and step; see ``cpmx.cbf_filter``."""

def run(
    spec: str | PathLike[str],
    out: str | PathLike[str] | None = None,
    policies: Mapping[str, Callable[[np.ndarray, np.ndarray], Any]] | None = None,
    jobs: int | None = None,
    only: Mapping[str, Sequence[str]] | Sequence[str] | str | None = None,
    data: str | PathLike[str] | Sequence[str | PathLike[str]] | None = None,
    resume: bool = False,
    force: bool = False,
) -> dict[str, Any]:
    """``cpmx run`` with ``python: {}`` policies bound to callables ``f(observations[A, O],
    states[A, 5]) -> actions[A, 2]``; see ``cpmx.run``.
    """
