"""Without a key, answer only callers that are on this machine and say so.

Binding to loopback keeps other machines out, but not a web page in a local browser: it
can post a cross-origin form to ``http://127.0.0.1:8000/stop`` (the browser sends it,
with an ``Origin`` of the page), or resolve its own domain to 127.0.0.1 after loading
(DNS rebinding) and call the service with a ``Host`` of that domain. In no-key mode
this middleware refuses (403) any request whose ``Host`` is not a loopback name, and any
state-changing request whose ``Origin`` is not a loopback origin. Programs (curl,
httpx, the CLI) send a loopback ``Host`` and no ``Origin``, and pass.
"""

from __future__ import annotations

import ipaddress
import json
from urllib.parse import urlsplit

from starlette.types import ASGIApp, Receive, Scope, Send

#: Methods that change nothing: a cross-origin page cannot read their answers (CORS).
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def is_loopback_name(host: str) -> bool:
    """Whether ``host`` (a name or address, no port) is the loopback interface."""
    host = host.strip("[]").lower().rstrip(".")
    if host == "localhost" or host.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _host_of(header: str) -> str:
    """The host part of a ``Host`` header (``name``, ``name:port``, ``[v6]:port``)."""
    return urlsplit(f"//{header}").hostname or ""


class LoopbackOnly:
    """ASGI middleware for no-key mode: loopback ``Host`` always, loopback ``Origin`` on
    state-changing requests; 403 otherwise."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http":
            refusal = self.refusal(scope)
            if refusal:
                body = json.dumps({"detail": refusal, "error": "forbidden"}).encode()
                await send({"type": "http.response.start", "status": 403,
                            "headers": [(b"content-type", b"application/json")]})
                await send({"type": "http.response.body", "body": body})
                return
        await self.app(scope, receive, send)

    @staticmethod
    def refusal(scope: Scope) -> str:
        """Why the request is refused, or '' when it may pass."""
        headers = dict(scope.get("headers", []))
        host = headers.get(b"host", b"").decode("latin-1")
        if not is_loopback_name(_host_of(host)):
            return (f"Host {host!r} is not a loopback name: without STAND_API_KEY the service "
                    "answers only requests to 127.0.0.1, [::1] or localhost")
        origin = headers.get(b"origin")
        if origin is not None and scope.get("method", "GET") not in SAFE_METHODS:
            text = origin.decode("latin-1")
            if not is_loopback_name(urlsplit(text).hostname or ""):
                return (f"Origin {text!r} is not this machine: without STAND_API_KEY "
                        "cross-origin requests that change something are refused")
        return ""
