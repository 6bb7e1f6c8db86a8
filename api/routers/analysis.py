"""Analyses of stored or uploaded runs: the same operations and field names as the CLI.

Each route takes JSON (run ids) or a multipart form (CSV files or ids in the same
fields), calls the domain function off the event loop, stores the result with its
inputs and answers the result's fields plus ``result_id``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel

from api.deps import Authorized, SettingsDep, StorageDep
from api.schemas import (
    DiagnoseRequest,
    EfficiencyRequest,
    IdentifyRequest,
    StepIdentifyRequest,
    TorqueConstantRequest,
)
from api.uploads import forget_uploads, parse_body
from stand import diagnose, efficiency, identify, step_identify, torque_constant
from stand.errors import SolverError, StandError
from stand.ident.supply import motor_supply
from stand.jsonable import JsonResult
from stand.runfile import RunKind
from stand.storage import Storage

router = APIRouter(tags=["analysis"])
log = logging.getLogger("stand.api")


def _identify(body: IdentifyRequest, runs: dict[str, Any]) -> JsonResult:
    return identify(runs["run"], method=body.method, no_load_current_A=body.no_load_current_A,
                    effects=body.effects, estimator=body.estimator,
                    supply=motor_supply(body.motor))


def _torque_constant(body: TorqueConstantRequest, runs: dict[str, Any]) -> JsonResult:
    return torque_constant(runs["no_load"], runs["loaded"], body.added_inertia,
                           method=body.method, compensate=body.compensate,
                           effects=body.effects, estimator=body.estimator,
                           supply=motor_supply(body.motor))


def _efficiency(body: EfficiencyRequest, runs: dict[str, Any]) -> JsonResult:
    return efficiency(runs["run"], body.ratio, body.k_in, body.k_out)


def _step_identify(body: StepIdentifyRequest, runs: dict[str, Any]) -> JsonResult:
    return step_identify(runs["runs"], known={str(k): v for k, v in body.known.items()},
                         method=body.method)


def _diagnose(body: DiagnoseRequest, runs: dict[str, Any]) -> JsonResult:
    options = body.model_dump(include={"kt", "horizon_s", "max_effects"}, exclude_none=True)
    return diagnose(runs["train"], runs["holdout"], **options, supply=motor_supply(body.motor))


@dataclass(frozen=True)
class Operation:
    """One analysis: its request model, the kind of run each run field holds, the call."""

    name: str
    model: type[BaseModel]
    run_fields: dict[str, RunKind]
    call: Callable[[Any, dict[str, Any]], JsonResult]


OPERATIONS: dict[str, Operation] = {op.name: op for op in (
    Operation("identify", IdentifyRequest, {"run": "single"}, _identify),
    Operation("torque-constant", TorqueConstantRequest,
              {"no_load": "single", "loaded": "single"}, _torque_constant),
    Operation("efficiency", EfficiencyRequest, {"run": "reducer"}, _efficiency),
    Operation("step-identify", StepIdentifyRequest, {"runs": "step"}, _step_identify),
    Operation("diagnose", DiagnoseRequest, {"train": "single", "holdout": "single"}, _diagnose),
)}


def _load_runs(storage: Storage, op: Operation, body: BaseModel) -> dict[str, Any]:
    runs: dict[str, Any] = {}
    for name, kind in op.run_fields.items():
        value = getattr(body, name)
        if isinstance(value, list):
            runs[name] = [storage.load_run(v, kind) for v in value]
        else:
            runs[name] = storage.load_run(value, kind)
    return runs


def _execute(storage: Storage, op: Operation, body: BaseModel) -> dict[str, Any]:
    runs = _load_runs(storage, op, body)
    try:
        result = op.call(body, runs).to_json()
    except StandError:
        raise
    except (ValueError, ArithmeticError, IndexError, np.linalg.LinAlgError) as exc:
        # A numerical method that chokes on valid but odd data: the caller's data, not the
        # service, is the problem (422); the traceback is logged for the method's authors.
        log.exception("%s failed on %s", op.name, body.model_dump(mode="json"))
        raise SolverError(f"{op.name}: the method failed on these runs: "
                          f"{type(exc).__name__}: {exc}") from exc
    inputs = body.model_dump(mode="json")
    result_id = storage.add_result(op.name, inputs, result)
    return {**result, "result_id": result_id, "inputs": inputs}


def _openapi(op: Operation) -> dict[str, Any]:
    """Both request bodies in the OpenAPI document (the route parses them itself)."""
    schema = op.model.model_json_schema()
    form = {**schema, "properties": dict(schema["properties"])}
    for name in op.run_fields:
        prop = schema["properties"][name]
        one = {"anyOf": [{"type": "string", "format": "binary"}, {"type": "string"}]}
        form["properties"][name] = ({**prop, "items": one} if prop.get("type") == "array"
                                    else {**prop, **one})
    return {"requestBody": {"required": True, "content": {
        "application/json": {"schema": schema},
        "multipart/form-data": {"schema": form},
    }}}


def _route(op: Operation) -> Callable[..., Any]:
    async def analyse(request: Request, storage: StorageDep, settings: SettingsDep) -> dict[str, Any]:
        uploaded: list[str] = []
        try:
            body = await parse_body(request, op.model, op.run_fields, storage,
                                    settings.upload_limit_bytes, uploaded)
            return await run_in_threadpool(_execute, storage, op, body)
        except Exception:
            await run_in_threadpool(forget_uploads, storage, uploaded)
            raise

    analyse.__name__ = op.name.replace("-", "_")
    analyse.__doc__ = op.model.__doc__
    return analyse


for _op in OPERATIONS.values():
    router.add_api_route(f"/{_op.name}", _route(_op), methods=["POST"], dependencies=[Authorized],
                         openapi_extra=_openapi(_op), summary=(_op.model.__doc__ or "").split("\n")[0])

__all__ = ["OPERATIONS", "Operation", "router"]
