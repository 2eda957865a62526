"""A limit on request bodies, enforced before any route reads one (ASGI middleware).

A body whose ``Content-Length`` is above the limit is answered 413 at once, unread; one without
(chunked) is read up to the limit and answered 413 the moment it passes it. A body within the limit
is read whole here and handed on to the route, so no route ever holds more than the limit in memory.
The network upload has its own, larger limit and reads its body itself
(:mod:`crossroads.api.routes.uploads`): a route marked with :func:`reads_own_body` passes through
untouched.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

from crossroads.api.guard import ASGIApp, Message, Receive, Scope, Send

BODY_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})
OWN_LIMIT_ATTR = "__reads_own_body__"
F = TypeVar("F", bound=Callable[..., Any])


def reads_own_body(endpoint: F) -> F:
    """Mark a route's endpoint as reading (and limiting) its request body itself, e.g. an upload
    with a larger limit than the API's; :class:`BodyLimit` then lets its requests through."""
    setattr(endpoint, OWN_LIMIT_ATTR, True)
    return endpoint


def own_body_routes(routes: Iterable[Any]) -> tuple[re.Pattern[str], ...]:
    """The path patterns of the routes marked with :func:`reads_own_body`."""
    return tuple(r.path_regex for r in routes
                 if getattr(getattr(r, "endpoint", None), OWN_LIMIT_ATTR, False) and hasattr(r, "path_regex"))


class BodyLimit:
    """Refuse request bodies above ``max_bytes`` (413) on every path but those matching ``exempt``."""

    def __init__(self, app: ASGIApp, max_bytes: int, exempt: tuple[re.Pattern[str], ...] = ()) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.exempt = exempt

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (scope["type"] != "http" or scope.get("method") not in BODY_METHODS
                or any(p.match(scope.get("path", "")) for p in self.exempt)):
            await self.app(scope, receive, send)
            return
        declared = _content_length(scope)
        if declared is not None and declared > self.max_bytes:
            await _too_large(send, f"the request body is {declared} bytes, above the limit of "
                                   f"{self.max_bytes} bytes")
            return
        chunks: list[bytes] = []
        size = 0
        more = True
        while more:
            message = await receive()
            if message["type"] == "http.disconnect":
                return  # the client went away: nobody to answer
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_bytes:
                await _too_large(send, f"the request body is above the limit of {self.max_bytes} bytes")
                return
            chunks.append(chunk)
            more = bool(message.get("more_body", False))
        body = b"".join(chunks)
        await self.app(scope, _replay(body, receive), send)


def _content_length(scope: Scope) -> int | None:
    for key, value in scope.get("headers", []):
        if key.lower() == b"content-length":
            text = value.decode("latin-1").strip()
            return int(text) if text.isdigit() else None
    return None


def _replay(body: bytes, receive: Receive) -> Receive:
    """A ``receive`` that gives the body read already, then whatever the server says next."""
    sent = False

    async def replay() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return replay


async def _too_large(send: Send, detail: str) -> None:
    payload: dict[str, Any] = {"detail": detail}
    body = json.dumps(payload).encode()
    # "close": the rest of the body is not read, so the connection cannot carry another request
    await send({"type": "http.response.start", "status": 413,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close")]})
    await send({"type": "http.response.body", "body": body})
