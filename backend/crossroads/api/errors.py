"""How errors become answers, in one place: domain errors as 404/422, and request validation errors
as FastAPI's 422 even when the request held what JSON cannot say back.

Python's JSON parser reads the literals ``NaN``, ``Infinity`` and ``-Infinity``; a field that refuses
them answers a 422 that echoes the value as ``input``, which the JSON response cannot encode (a 500).
Here every non-finite number in a validation error is written as its literal's text instead.
"""

from __future__ import annotations

import math
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from crossroads.intersections.resolve import NetworkNotFoundError
from crossroads.network.junction import JunctionError
from crossroads.policy.ref import PolicyError
from crossroads.validation import SpecError

MAX_ECHO_CHARS = 200  # [chars] of a refused string value echoed back as ``input``


def finite(data: Any) -> Any:
    """``data`` with NaN and the infinities as the strings ``"NaN"``, ``"Infinity"``, ``"-Infinity"``
    and long strings cut short (an echoed 1 MB value helps nobody)."""
    if isinstance(data, float) and not math.isfinite(data):
        return "NaN" if math.isnan(data) else ("Infinity" if data > 0 else "-Infinity")
    if isinstance(data, str) and len(data) > MAX_ECHO_CHARS:
        return data[:MAX_ECHO_CHARS] + "…"
    if isinstance(data, dict):
        return {k: finite(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [finite(v) for v in data]
    return data


def install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(RequestValidationError)
    async def _invalid(_: Request, exc: RequestValidationError) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": finite(jsonable_encoder(exc.errors()))})

    @app.exception_handler(NetworkNotFoundError)
    async def _not_found(_: Request, exc: NetworkNotFoundError) -> JSONResponse:
        return JSONResponse(status_code=404, content={"detail": str(exc)})

    @app.exception_handler(SpecError)
    @app.exception_handler(JunctionError)
    @app.exception_handler(PolicyError)
    async def _unprocessable(_: Request, exc: Exception) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": str(exc)})
