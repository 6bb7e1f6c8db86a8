"""The operations a batch maps over its items, and what one item's work returns.

Each operation calls the public API (:mod:`stand`) on the runs of one item and keeps its
``to_json()`` object: a batch row holds exactly what ``stand OPERATION --json`` prints
for the same runs. :func:`run_item` never raises for a bad item: the error goes into the
outcome, so one item never stops a batch.
"""

from __future__ import annotations

import math
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import stand
from stand.batch.inputs import RUN_PREFIX, Item
from stand.diagnosis.engine import ANCHOR_HORIZON_S, MAX_EFFECTS
from stand.errors import InputError, StandError
from stand.ident.derivatives import METHODS as DERIVATIVE_METHODS
from stand.jsonable import JsonResult
from stand.runfile import Run, RunKind
from stand.stepid import METHODS as STEP_METHODS
from stand.stepid.model import HOLDS as STEP_HOLDS

if TYPE_CHECKING:
    from stand.ident.qmatrix import QSums

Options = Mapping[str, Any]


@dataclass(frozen=True)
class Operation:
    """One batch operation.

    Attributes
    ----------
    name : str
        As on the command line (``identify``, ``torque-constant``, ...).
    kind : str
        Run kind of every run of an item (CONTRACT §1).
    runs_per_item : int
        1, or 2 for the operations that take a pair (``FIRST,SECOND``).
    defaults : dict
        Every option and its default; ``None`` marks a required option with no default.
    positive : tuple of str
        Options that must be finite numbers > 0 when given.
    call : callable
        ``call(runs, options) -> JsonResult``.
    fleet_field : str or None
        The number of the result whose spread over a group is reported.
    """

    name: str
    kind: RunKind
    runs_per_item: int
    defaults: dict[str, Any]
    call: Callable[[list[Run], dict[str, Any]], JsonResult]
    positive: tuple[str, ...] = ()
    required: tuple[str, ...] = ()
    fleet_field: str | None = None
    choices: dict[str, tuple[str, ...]] = field(default_factory=dict)


def _identify(runs: list[Run], o: dict[str, Any]) -> JsonResult:
    return stand.identify(runs[0], o["method"], o["no_load_current_A"], o["half_width"])


def _torque_constant(runs: list[Run], o: dict[str, Any]) -> JsonResult:
    return stand.torque_constant([runs[0]], [runs[1]], o["added_inertia"], o["method"],
                                 o["compensate"], o["half_width"])


def _efficiency(runs: list[Run], o: dict[str, Any]) -> JsonResult:
    return stand.efficiency(runs[0], o["ratio"], o["k_in"], o["k_out"])


def _step_identify(runs: list[Run], o: dict[str, Any]) -> JsonResult:
    return stand.step_identify(runs, known=o["known"], method=o["method"], hold=o["hold"],
                               use_current=o["use_current"])


def _diagnose(runs: list[Run], o: dict[str, Any]) -> JsonResult:
    return stand.diagnose(runs[0], runs[1], kt=o["kt"], horizon_s=o["horizon_s"],
                          max_effects=o["max_effects"], spring=o["spring"])


OPERATIONS: dict[str, Operation] = {op.name: op for op in (
    Operation("identify", "single", 1,
              {"method": "default", "no_load_current_A": 0.0, "half_width": None}, _identify,
              choices={"method": DERIVATIVE_METHODS}, fleet_field="Kt_over_J"),
    Operation("torque-constant", "single", 2,
              {"added_inertia": None, "method": "default", "compensate": True, "half_width": None},
              _torque_constant, positive=("added_inertia",), required=("added_inertia",),
              choices={"method": DERIVATIVE_METHODS}, fleet_field="Kt"),
    Operation("efficiency", "reducer", 1, {"ratio": None, "k_in": None, "k_out": None},
              _efficiency, positive=("ratio", "k_in", "k_out"),
              required=("ratio", "k_in", "k_out"), fleet_field="efficiency"),
    Operation("step-identify", "step", 1,
              {"known": {}, "method": "trf", "hold": "preceding", "use_current": True},
              _step_identify, choices={"method": STEP_METHODS, "hold": STEP_HOLDS}),
    Operation("diagnose", "single", 2,
              {"kt": None, "horizon_s": ANCHOR_HORIZON_S, "max_effects": MAX_EFFECTS,
               "spring": False}, _diagnose, positive=("kt", "horizon_s", "max_effects")),
)}


def operation(name: str) -> Operation:
    """The operation called ``name``; :class:`InputError` naming the choices otherwise."""
    try:
        return OPERATIONS[name]
    except KeyError:
        raise InputError(f"operation must be one of {', '.join(OPERATIONS)}, not {name!r}") from None


def check_options(op: Operation, options: Options) -> dict[str, Any]:
    """The operation's options with defaults filled in, checked before any item runs.

    Raises
    ------
    InputError
        An unknown option, a missing required one, a value outside its choices, or a
        number that must be > 0 and is not.
    """
    defaults = op.defaults
    unknown = sorted(set(options) - set(defaults))
    if unknown:
        raise InputError(f"{op.name}: unknown option(s) {', '.join(unknown)}; it takes "
                         f"{', '.join(defaults) or 'none'}")
    merged = {**defaults, **{k: v for k, v in options.items() if v is not None}}
    for name in op.required:
        if merged[name] is None:
            raise InputError(f"{op.name}: option {name} is required")
    for name, allowed in op.choices.items():
        if merged[name] not in allowed:
            raise InputError(f"{op.name}: {name} must be one of {', '.join(allowed)}, "
                             f"not {merged[name]!r}")
    for name in op.positive:
        value = merged[name]
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value)
                                      and value > 0):
            raise InputError(f"{op.name}: {name} must be a finite number > 0, got {value!r}")
    return merged


@dataclass(frozen=True)
class Outcome:
    """What one item's work returns.

    Attributes
    ----------
    index : int
        The item's position in the batch.
    result : dict or None
        The operation's ``to_json()`` object; ``None`` when it failed.
    error : str
        ``""``, or the error: its type and message.
    seconds : float
        Wall time of the item in its worker (reading the runs and the operation), s.
    cpu_seconds : float
        CPU time of the worker's process over the item, s: the item's cost, less
        sensitive than ``seconds`` to what else the machine runs.
    sums : ndarray or None
        The Q-matrix sums ``G`` of an ``identify`` item (:func:`run_sums`), for pooling.
    sum_samples : int
        The samples those sums hold (seed 000's rows; the result's own ``samples`` may
        differ: the model with effects can drop rows at the ends).
    """

    index: int
    result: dict[str, Any] | None
    error: str
    seconds: float
    cpu_seconds: float = 0.0
    sums: np.ndarray | None = None
    sum_samples: int = 0


def run_item(item: Item, op_name: str, options: dict[str, Any],
             database: str | None = None) -> Outcome:
    """Read the runs of ``item`` and apply the operation; errors become the outcome's.

    Parameters
    ----------
    item : Item
        The item.
    op_name : str
        Operation name (:data:`OPERATIONS`).
    options : dict
        Options as returned by :func:`check_options`.
    database : str, optional
        The service's SQLite file, for ``run:ID`` refs.
    """
    start, cpu = time.perf_counter(), time.process_time()
    op = OPERATIONS[op_name]
    sums, sum_samples = None, 0
    try:
        runs = [_load(ref, op.kind, database) for ref in item.refs]
        result: dict[str, Any] | None = op.call(runs, options).to_json()
        if op.name == "identify":
            q = run_sums(runs[0], result)  # type: ignore[arg-type]
            sums, sum_samples = q.G, int(q.samples)
        error = ""
    except StandError as exc:
        result, error = None, f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # noqa: BLE001 - a method that chokes on one item must not stop the batch
        where = traceback.extract_tb(exc.__traceback__)[-1]
        result = None
        error = f"{type(exc).__name__}: {exc} (at {Path(where.filename).name}:{where.lineno})"
    return Outcome(item.index, result, error, time.perf_counter() - start,
                   time.process_time() - cpu, sums, sum_samples)


def run_sums(run: Run, result: Mapping[str, Any]) -> QSums:
    """The Q-matrix sums (seed 000 eq. 10) of the run an ``identify`` result came from.

    The one place a batch reaches into :mod:`stand.ident`: the public result carries the
    estimate, not the sums, and pooling adds sums across runs. It rebuilds the states
    with the result's own method, no-load current and kernel width, so the sums are those
    ``stand.identify`` solved.
    """
    from stand.ident.derivatives import state_derivatives
    from stand.ident.qmatrix import QSums

    current = run["current_A"] - result["no_load_current_A"]
    half_width = result["half_width"] if result["method"] == "default" else None
    states = state_derivatives(run["position_rad"], current, run.dt_s, result["method"],
                               half_width)
    return QSums.zeros(2, 1).add(states.xdot, states.x, states.inputs, run.dt_s)


def _load(ref: str, kind: RunKind, database: str | None) -> Run:
    if ref.startswith(RUN_PREFIX):
        if database is None:
            raise InputError(f"{ref}: a stored run needs the service's database")
        return _storage(database).load_run(ref[len(RUN_PREFIX):], kind)
    return stand.read_run(ref, kind)


@lru_cache(maxsize=4)
def _storage(database: str) -> Any:
    """One connection per worker process and database (opened on the first stored run)."""
    from stand.storage import Storage

    return Storage(database)
