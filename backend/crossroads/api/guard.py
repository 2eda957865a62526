"""Who may talk to the API: the Host it is reached by, the access token, and the page a
state-changing request comes from. One ASGI middleware, in front of every route.

* **Host** (every request): the ``Host`` header must name this server (localhost, the interface it
  listens on, or a configured ``allowed_hosts`` name); otherwise 421. A web page whose DNS name
  was rebound to 127.0.0.1 sends its own name, so it reaches nothing.
* **Token** (when one is set; ``crossroads serve`` sets one whenever it listens beyond loopback):
  every ``/api`` request carries it as ``Authorization: Bearer <token>`` or in the cookie the page
  gets by opening ``/?token=<token>`` (the URL ``serve`` prints; answered with a redirect that drops
  it from the address bar). The cookie is ``SameSite=Strict``: another site's requests never carry
  it. Otherwise 401.
* **Origin** (POST, PUT, PATCH, DELETE): a browser says which page sent the request. It must be
  this server's own origin (the Host it was reached by), or the same port under another loopback
  name or an allowed host; a request a browser marks ``Sec-Fetch-Site: cross-site`` or
  ``same-site`` without an Origin is refused too. Otherwise 403. Clients that are not browsers
  (curl, scripts) send neither header and pass. GET and HEAD never change anything (the routes
  keep it so), so a page elsewhere can at most read what the browser then hides from it.
"""

from __future__ import annotations

import hmac
import json
import socket
from collections.abc import Awaitable, Callable, Iterable
from http.cookies import SimpleCookie
from typing import Any
from urllib.parse import parse_qsl, quote, urlencode, urlsplit

from crossroads.settings import WILDCARD_HOSTS, Settings, host_name, is_loopback

Scope = dict[str, Any]
Message = dict[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

UNSAFE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})
DEFAULT_PORTS = {"http": 80, "https": 443, "ws": 80, "wss": 443}
TOKEN_QUERY = "token"
PROTECTED_PREFIXES = ("/api", "/docs", "/redoc", "/openapi.json")  # the page itself is static


def cookie_name(port: int) -> str:
    """Cookies are shared by every port of a host: the name carries ours."""
    return f"crossroads_token_{port}"


def machine_names() -> set[str]:
    """This machine's own names and addresses (best effort): what a browser elsewhere on the
    network may call a server listening on every interface."""
    names: set[str] = set()
    for name in {socket.gethostname(), socket.getfqdn()}:
        if not name:
            continue
        names.add(host_name(name))
        try:
            for info in socket.getaddrinfo(name, None):
                names.add(host_name(str(info[4][0])))
        except OSError:
            pass
    # the address of the interface that routes outwards: a UDP "connect" sends nothing, it only
    # picks the source address (192.0.2.1 is a documentation address, never reached)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect(("192.0.2.1", 9))
            names.add(host_name(probe.getsockname()[0]))
    except OSError:
        pass
    return names - {"0.0.0.0"}


def split_host(value: str) -> tuple[str, int | None]:
    """``"[::1]:8000"`` → ``("::1", 8000)``; ``"localhost"`` → ``("localhost", None)``; a malformed
    value gives ``("", None)``."""
    try:
        parts = urlsplit(f"//{value}")
        return host_name(parts.hostname or ""), parts.port
    except ValueError:
        return "", None


class RequestGuard:
    """The ASGI middleware of the module docstring."""

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app = app
        self.settings = settings
        self.any_host = "*" in settings.allowed_hosts
        hosts = set(settings.answered_hosts())
        if host_name(settings.host) in WILDCARD_HOSTS:
            hosts |= machine_names()
        self.hosts = frozenset(hosts)
        self.origin_hosts = frozenset(settings.allowed_hosts) - {"*"}
        secret = settings.token.get_secret_value() if settings.token is not None else None
        self.token = secret.encode() if secret else None
        self.cookie = cookie_name(settings.port)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = _headers(scope["headers"])
        host = headers.get("host", "")
        name, _ = split_host(host)
        if not name or not (self.any_host or name in self.hosts):
            await _refuse(send, scope, 421, f"this server does not answer to the host {host or '(none)'!r}; "
                          "reach it by localhost or the address it listens on, or start it with "
                          f"--allowed-host {name or 'NAME'}")
            return
        path = scope.get("path", "")
        if self.token is not None:
            done = await self._check_token(scope, headers, path, send)
            if done:
                return
        if scope.get("method", "GET") in UNSAFE_METHODS:
            problem = self._origin_problem(headers, host, scope.get("scheme", "http"))
            if problem is not None:
                await _refuse(send, scope, 403, problem)
                return
        await self.app(scope, receive, send)

    # --- the token -------------------------------------------------------------------------------

    def _matches(self, candidate: str | None) -> bool:
        if not candidate or self.token is None:
            return False
        return hmac.compare_digest(candidate.encode(), self.token)

    async def _check_token(self, scope: Scope, headers: dict[str, str], path: str, send: Send) -> bool:
        """Answer the request here when the token decides it (a 401, or the page's redirect that
        sets the cookie); False when the request goes on."""
        query = parse_qsl(scope.get("query_string", b"").decode("latin-1"), keep_blank_values=True)
        given = dict(query).get(TOKEN_QUERY)
        if given is not None and scope.get("method") in ("GET", "HEAD") and not path.startswith("/api"):
            if not self._matches(given):
                await _refuse(send, scope, 401, "wrong access token: open the URL `crossroads serve` printed")
                return True
            rest = urlencode([(k, v) for k, v in query if k != TOKEN_QUERY])
            await _redirect(send, quote(path) + (f"?{rest}" if rest else ""),
                            f"{self.cookie}={given}; Path=/; HttpOnly; SameSite=Strict")
            return True
        if not path.startswith(PROTECTED_PREFIXES):
            return False
        auth = headers.get("authorization", "")
        bearer = auth[7:].strip() if auth[:7].lower() == "bearer " else None
        if self._matches(bearer) or self._matches(_cookie(headers.get("cookie", ""), self.cookie)):
            return False
        await _refuse(send, scope, 401, "this studio needs its access token: open the URL `crossroads serve` "
                      "printed (…/?token=…), or send the header 'Authorization: Bearer <token>'",
                      extra=[(b"www-authenticate", b"Bearer")])
        return True

    # --- the origin ------------------------------------------------------------------------------

    def _origin_problem(self, headers: dict[str, str], host: str, scheme: str) -> str | None:
        """Why a state-changing request is refused, or None when it may go on."""
        origin = headers.get("origin")
        if origin is None:
            site = headers.get("sec-fetch-site", "").lower()
            if site in ("cross-site", "same-site"):
                return f"refused: a {site} request may not change anything here"
            return None
        name, port = split_host(host)
        try:
            parts = urlsplit(origin)
            origin_name, origin_port = host_name(parts.hostname or ""), parts.port
            origin_port = origin_port if origin_port is not None else DEFAULT_PORTS.get(parts.scheme)
        except ValueError:  # garbage names no origin we allow ("null": a sandboxed page, a file)
            origin_name, origin_port = "", None
        served_port = port if port is not None else DEFAULT_PORTS.get(scheme)  # no port: the scheme's
        if origin_name and origin_port == served_port and (
                origin_name == name or (is_loopback(origin_name) and is_loopback(name))
                or origin_name in self.origin_hosts):
            return None
        return (f"refused: a page of {origin} may not change anything here (only the studio's own "
                "page may; allow another name with --allowed-host)")


def _headers(raw: Iterable[tuple[bytes, bytes]]) -> dict[str, str]:
    """Header names lowercased; the first of a repeated header."""
    out: dict[str, str] = {}
    for key, value in raw:
        out.setdefault(key.decode("latin-1").lower(), value.decode("latin-1"))
    return out


def _cookie(header: str, name: str) -> str | None:
    try:
        jar = SimpleCookie(header)
    except Exception:  # noqa: BLE001 - a malformed Cookie header carries no token
        return None
    morsel = jar.get(name)
    return morsel.value if morsel is not None else None


async def _refuse(send: Send, scope: Scope, status: int, detail: str,
                  extra: list[tuple[bytes, bytes]] | None = None) -> None:
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008})
        return
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode()), *(extra or [])]})
    await send({"type": "http.response.body", "body": body})


async def _redirect(send: Send, location: str, cookie: str) -> None:
    await send({"type": "http.response.start", "status": 303,
                "headers": [(b"location", location.encode("latin-1")), (b"set-cookie", cookie.encode("latin-1")),
                            (b"cache-control", b"no-store"), (b"content-length", b"0")]})
    await send({"type": "http.response.body", "body": b""})
