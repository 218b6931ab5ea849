"""One error model for every HTTP error the daemon sends, and the handlers that enforce it.

Error policy: every 4xx/5xx body is ``{"detail": "<one line naming the field>", "errors": [...]}``.
``detail`` is what a person reads (the web pages show it as is); ``errors`` lists each invalid
field as ``{"loc": [...], "msg": ..., "type": ...}`` for programs (empty when the problem is not
about one field). FastAPI's own validation errors are reshaped into this model, without the
``input`` echo: a 10 MB field must not come back in the response (or reach a log line).
The same model is declared in OpenAPI for every status a route can answer, so ``/docs`` tells the
truth and a schema-driven fuzzer can check it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

from common.errors import shorten


class ErrorItem(BaseModel):
    """One invalid field."""

    loc: list[str | int] = Field(description="Where: body/query/path, then the field names.")
    msg: str = Field(description="What is wrong with it.")
    type: str = Field(description="Machine-readable kind of problem.")


class ErrorBody(BaseModel):
    """The body of every error response."""

    detail: str = Field(description="One line naming the field (or thing) and the problem.")
    errors: list[ErrorItem] = Field(default_factory=list, description="Each invalid field.")


_WHAT = {
    400: "Malformed request",
    401: "Missing or wrong token",
    403: "Refused: foreign Origin or Host, or a camera image under privacy: positions_only "
    "(docs/guides/security.md)",
    404: "No such thing",
    409: "Conflicts with the daemon's state (e.g. model refused, collection running)",
    413: "Request body too large",
    415: "State-changing requests take a JSON body",
    422: "A field is invalid",
    503: "Not available yet",
}


def error_responses(*statuses: int, plain_route: bool = False) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entries declaring :class:`ErrorBody` for ``statuses``.

    ``plain_route``: the route answers 200 with another media type (JPEG, Prometheus text);
    FastAPI would document its errors with that type, so the JSON schema is given explicitly.
    """
    if plain_route:
        ref = {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorBody"}}}
        return {s: {"description": _WHAT[s], "content": ref} for s in statuses}
    return {status: {"model": ErrorBody, "description": _WHAT[status]} for status in statuses}


def error_response(
    status: int,
    detail: str,
    errors: Iterable[dict[str, Any]] = (),
    headers: Mapping[str, str] | None = None,
) -> JSONResponse:
    body = ErrorBody(detail=shorten(detail, 500), errors=[ErrorItem(**e) for e in errors])
    return JSONResponse(body.model_dump(), status_code=status, headers=headers)


def _loc_text(loc: Sequence[Any]) -> str:
    return ".".join(str(part) for part in loc)


def validation_items(raw: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Pydantic error dicts without the echoed input, messages capped."""
    return [
        {
            "loc": [p if isinstance(p, int) else shorten(p, 80) for p in item.get("loc", ())],
            "msg": shorten(str(item.get("msg", "invalid")).removeprefix("Value error, "), 300),
            "type": str(item.get("type", "value_error")),
        }
        for item in raw
    ]


def install_error_handlers(app: FastAPI) -> None:
    """Make HTTPException and request validation answer with :class:`ErrorBody`."""

    async def http_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, StarletteHTTPException)
        return error_response(exc.status_code, str(exc.detail), headers=exc.headers)

    async def invalid(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        items = validation_items(exc.errors())
        first = items[0] if items else {"loc": [], "msg": "invalid request"}
        more = f" (and {len(items) - 1} more)" if len(items) > 1 else ""
        detail = f"{_loc_text(first['loc'])}: {first['msg']}{more}"
        return error_response(422, detail, items)

    app.add_exception_handler(StarletteHTTPException, http_error)
    app.add_exception_handler(RequestValidationError, invalid)
