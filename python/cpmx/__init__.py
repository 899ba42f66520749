"""cpmx for Python: the CPM Lab benchmark's environments and runs.

cpmx is a Rust tool that makes sim-to-real experiments with multi-agent RL motion planners in
the CPM Lab reproducible. This package gives Python the same things the command line has:

- :class:`VecEnv`: the training environment of ``cpmx train`` (SigmaRL's scenario, reward
  and observation, in any fidelity of a spec: SigmaRL's simulation, the lab's planner and
  MPC, a digital twin randomised per episode), batched, stepped in Rust;
- :mod:`cpmx.torchrl`, :mod:`cpmx.benchmarl`, :mod:`cpmx.pettingzoo`: that environment as
  TorchRL, BenchMARL and PettingZoo know environments;
- :func:`run`: ``cpmx run`` with policies written in Python (``python: {}`` in a spec);
- :func:`validate`: ``cpmx validate``'s diagnostics as objects; :func:`read_runs`: a run
  folder's per-run metrics;
- :func:`cbf_filter`: SigmaRL's CBF safety filter (``safety: stdlib:sigmarl-cbf``) for one
  vehicle and step.
"""

from __future__ import annotations

import csv
import inspect
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cpmx._cpmx import CpmxError, Diagnostic, VecEnv, __version__, _cbf_filter
from cpmx._cpmx import run as _run
from cpmx._cpmx import validate as _validate

__all__ = [
    "CbfFiltered",
    "CpmxError",
    "Diagnostic",
    "RunResult",
    "VecEnv",
    "__version__",
    "cbf_filter",
    "read_runs",
    "run",
    "validate",
]

PathLike = str | os.PathLike[str]
"""A file or folder path."""

Policy = Callable[..., Any]
"""``f(observations[A, O]) -> actions[A, 2]`` or ``f(observations, states[A, 5])``."""


@dataclass(frozen=True)
class RunResult:
    """What :func:`run` did.

    Attributes:
        out: The run folder (``summary.md``, ``per_run.csv``, ``report.html``, ...).
        matrix_runs: Runs of the spec's whole matrix.
        finished: Runs executed by this call.
        resumed: Runs skipped because the folder held them with unchanged inputs.
        failed: Runs that failed, by run key, with the reason (the others are kept).
        summary: The summary table (Markdown), as ``cpmx run`` prints it.
        notes: Notes about the folder (e.g. that ``force=True`` replaced its spec).

    """

    out: Path
    matrix_runs: int
    finished: int
    resumed: int
    failed: dict[str, str]
    summary: str
    notes: list[str]

    def per_run(self) -> Any:
        """The folder's per-run metrics; see :func:`read_runs`."""
        return read_runs(self.out)


def _two_arguments(policy: Policy, name: str) -> Callable[[np.ndarray, np.ndarray], Any]:
    """``policy`` as a callable of (observations, states), whichever of the two it takes."""
    if not callable(policy):
        raise TypeError(f"policies[{name!r}] must be callable")
    try:
        parameters = inspect.signature(policy).parameters.values()
    except (TypeError, ValueError):
        return policy
    positional = [
        p
        for p in parameters
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty
    ]
    variadic = any(p.kind == p.VAR_POSITIONAL for p in parameters)
    if len(positional) == 1 and not variadic:
        return lambda observations, _states: policy(observations)
    return policy


def run(
    spec: PathLike,
    out: PathLike | None = None,
    policies: Mapping[str, Policy] | None = None,
    jobs: int | None = None,
    only: Mapping[str, str | Sequence[str]] | Sequence[str] | str | None = None,
    data: PathLike | Sequence[PathLike] | None = None,
    *,
    resume: bool = False,
    force: bool = False,
) -> RunResult:
    """Run a spec's matrix into a run folder, as ``cpmx run`` does.

    Args:
        spec: The spec file.
        out: The run folder (default ``out/<name>``).
        policies: Callables for the spec's ``python: {}`` policies, by policy name. Each is
            called once per step with the agents' observations ``float32[A, O]`` (of the
            policy's ``observation:``, default ``stdlib:sigmarl``) and, if it takes a second
            argument, their states ``float64[A, 5]`` (x m, y m, yaw rad, speed m/s, steering
            rad), and returns actions ``[A, 2]`` (target speed m/s, steering rad).
        jobs: Worker threads (default: all cores); results do not depend on it.
        only: Run only some runs: ``{"fidelity": ["sim", "twin"]}`` or ``"fidelity=sim,twin"``.
        data: Folders to look up maps and weights in (before ``CPMX_DATA``).
        resume: Skip runs the folder holds with unchanged inputs.
        force: Run into a folder made from another spec (it becomes the folder's spec).

    Returns:
        What was run, and the summary.

    Raises:
        CpmxError: The spec has errors (the text holds every diagnostic), a policy is not
            bound, or the folder cannot be written. A failing callable fails its runs only.
        KeyboardInterrupt: Ctrl-C: the runs under way finish and are kept, no other starts;
            ``resume=True`` continues.

    """
    bound = {name: _two_arguments(f, name) for name, f in (policies or {}).items()}
    if isinstance(only, Mapping):
        only = {
            axis: [names] if isinstance(names, str) else list(names) for axis, names in only.items()
        }
    outcome = _run(
        os.fspath(spec),
        None if out is None else os.fspath(out),
        bound,
        jobs,
        only,
        _data(data),
        resume,
        force,
    )
    return RunResult(
        out=Path(outcome["out"]),
        matrix_runs=outcome["matrix_runs"],
        finished=outcome["finished"],
        resumed=outcome["resumed"],
        failed=dict(outcome["failed"]),
        summary=outcome["summary"],
        notes=list(outcome["notes"]),
    )


def validate(spec: PathLike, data: PathLike | Sequence[PathLike] | None = None) -> list[Diagnostic]:
    """Every problem ``cpmx validate`` finds in a spec, errors and warnings, as objects.

    An empty list means the spec is valid and has nothing to warn about. Each
    :class:`Diagnostic` has ``level``, ``code``, ``message``, ``file``, ``line``, ``column``,
    ``label``, ``help`` and ``text`` (as the command line renders it).
    """
    return _validate(os.fspath(spec), _data(data))


def read_runs(folder: PathLike, *, frame: bool | None = None) -> Any:
    """A run folder's per-run metrics (``per_run.csv``): one row per finished run.

    Args:
        folder: The run folder.
        frame: ``True``: a pandas DataFrame; ``False``: a list of dicts; ``None`` (default): a
            DataFrame where pandas is installed, else the list.

    Metrics are floats (``nan`` where a metric is undefined), the repetition and the seed
    ints, the other columns text.

    """
    path = Path(folder) / "per_run.csv"
    if not path.is_file():
        raise CpmxError(f"{folder}: no per_run.csv (not a run folder, or no run has finished)")
    with path.open(newline="") as f:
        rows = [_typed(row) for row in csv.DictReader(f)]
    if frame is False:
        return rows
    try:
        import pandas as pd
    except ImportError:
        if frame:
            raise
        return rows
    return pd.DataFrame(rows)


def _typed(row: dict[str, str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, text in row.items():
        if key in ("repetition", "seed"):
            out[key] = int(text)
            continue
        try:
            out[key] = float(text) if text != "" else float("nan")
        except ValueError:
            out[key] = text
    return out


def _data(data: PathLike | Sequence[PathLike] | None) -> list[str] | None:
    if data is None:
        return None
    if isinstance(data, str | os.PathLike):
        return [os.fspath(data)]
    return [os.fspath(d) for d in data]


@dataclass(frozen=True)
class CbfFiltered:
    """What :func:`cbf_filter` did.

    Attributes:
        action: The action to apply, ``(speed m/s, steering rad)``.
        fallback: Why the (clamped) nominal action went through, or ``None``:
            ``"infeasible"`` (no action satisfies every row), ``"not-finite"`` (the state or a
            row is not a number), ``"unsolved"`` (the solver stopped without a solution).
        active: Indices into ``rows`` of the rows the solution lies on.
        rows: Each CBF row ``(circle, side, margin_m, coefficient_acceleration,
            coefficient_steering_rate, constant)``: ``coefficients . (a, omega) + constant >= 0``.

    """

    action: tuple[float, float]
    fallback: str | None
    active: list[int]
    rows: list[tuple[int, str, float, float, float, float]]


def cbf_filter(
    state: Sequence[float],
    action: Sequence[float],
    left: Sequence[Sequence[float]] | np.ndarray,
    right: Sequence[Sequence[float]] | np.ndarray,
    circles: int = 3,
    dt_s: float = 0.05,
) -> CbfFiltered:
    """SigmaRL's CBF safety filter of the ITSC 2025 paper (its tag 1.4.0) for one vehicle and step.

    The same filter as ``safety: stdlib:sigmarl-cbf`` in a spec, on ``float32`` inputs as
    SigmaRL's ``CBFQP.solve_decentralized_cbf_qp`` takes them.

    Args:
        state: ``(x, y, yaw, speed, steering)`` of the vehicle's centre; the speed as the
            velocity's norm.
        action: The nominal action ``(speed m/s, steering rad)``.
        left: The lane's left boundary, ``(x, y)`` points in driving direction.
        right: Its right boundary.
        circles: Circles along the vehicle's axis (SigmaRL: 3).
        dt_s: The step the CBF looks ahead and the action converts over [s].

    Returns:
        The filtered action, the fallback, if any, and the rows.

    Raises:
        ValueError: A boundary with fewer than two points, ``circles`` < 1 or ``dt_s`` <= 0.

    """

    def points(boundary: Sequence[Sequence[float]] | np.ndarray) -> list[list[float]]:
        return np.asarray(boundary, dtype=np.float32).reshape(-1, 2).tolist()

    filtered, fallback, active, rows = _cbf_filter(
        [float(v) for v in state],
        [float(v) for v in action],
        points(left),
        points(right),
        circles,
        dt_s,
    )
    return CbfFiltered((filtered[0], filtered[1]), fallback, list(active), list(rows))
