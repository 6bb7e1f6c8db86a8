"""motorstand: identify motors and reducers, diagnose the sim-to-real gap, drive CiA 402 stands.

The front door for notebooks and scripts; the ``stand`` command line and the HTTP
service call the same functions::

    import stand

    run = stand.read_run("no_load.csv")
    result = stand.identify(run)
    print(result.Kt_over_J, result.to_json())

Operations: :func:`read_run`, :func:`simulate`, :func:`identify`,
:func:`torque_constant`, :func:`efficiency`, :func:`step_identify`, :func:`diagnose`;
profiles: :func:`load_motor`, :func:`load_stand`, :func:`load_experiment`. Every result
has ``to_json()``, exactly the object ``stand … --json`` prints. Every error raised on
purpose derives from :class:`StandError`.

The names are imported on first use (PEP 562), so ``import stand`` stays cheap for the
bus and the command line, which need none of the numerical stack.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from stand.errors import (
    BusError,
    InputError,
    LimitError,
    NotExcitedError,
    NotFoundError,
    ProfileError,
    RunAborted,
    RunFileError,
    SolverError,
    StandError,
)

if TYPE_CHECKING:
    from stand.controller import ExperimentProfile, load_experiment
    from stand.diagnosis import Diagnosis, EffectScore, Where, diagnose
    from stand.ident.efficiency import EfficiencyResult, efficiency
    from stand.ident.identify import IdentifyResult
    from stand.ident.identify import identify_run as identify
    from stand.ident.supply import DriveSupply
    from stand.ident.torque_constant import TorqueConstantResult, torque_constant
    from stand.profiles import MotorProfile, StandProfile, load_motor, load_stand
    from stand.runfile import Run, read_run
    from stand.simulation import simulate
    from stand.stepid import StepResult
    from stand.stepid import identify_steps as step_identify

#: Public name -> (module, name there), imported on first use.
_LAZY: dict[str, tuple[str, str]] = {
    "read_run": ("stand.runfile", "read_run"),
    "Run": ("stand.runfile", "Run"),
    "simulate": ("stand.simulation", "simulate"),
    "identify": ("stand.ident.identify", "identify_run"),
    "IdentifyResult": ("stand.ident.identify", "IdentifyResult"),
    "DriveSupply": ("stand.ident.supply", "DriveSupply"),
    "torque_constant": ("stand.ident.torque_constant", "torque_constant"),
    "TorqueConstantResult": ("stand.ident.torque_constant", "TorqueConstantResult"),
    "efficiency": ("stand.ident.efficiency", "efficiency"),
    "EfficiencyResult": ("stand.ident.efficiency", "EfficiencyResult"),
    "step_identify": ("stand.stepid", "identify_steps"),
    "StepResult": ("stand.stepid", "StepResult"),
    "diagnose": ("stand.diagnosis", "diagnose"),
    "Diagnosis": ("stand.diagnosis", "Diagnosis"),
    "EffectScore": ("stand.diagnosis", "EffectScore"),
    "Where": ("stand.diagnosis", "Where"),
    "load_motor": ("stand.profiles", "load_motor"),
    "load_stand": ("stand.profiles", "load_stand"),
    "MotorProfile": ("stand.profiles", "MotorProfile"),
    "StandProfile": ("stand.profiles", "StandProfile"),
    "load_experiment": ("stand.controller", "load_experiment"),
    "ExperimentProfile": ("stand.controller", "ExperimentProfile"),
}

__all__ = [
    "BusError", "Diagnosis", "DriveSupply", "EffectScore", "EfficiencyResult", "ExperimentProfile",
    "IdentifyResult", "InputError", "LimitError", "MotorProfile", "NotExcitedError",
    "NotFoundError", "ProfileError", "Run", "RunAborted", "RunFileError", "SolverError",
    "StandError", "StandProfile", "StepResult", "TorqueConstantResult", "Where", "diagnose",
    "efficiency", "identify", "load_experiment", "load_motor", "load_stand", "read_run",
    "simulate", "step_identify", "torque_constant",
]


def __getattr__(name: str) -> Any:
    try:
        module, attribute = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'stand' has no attribute {name!r}") from None
    value = getattr(import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
