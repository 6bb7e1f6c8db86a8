"""Refuse a request body larger than the upload limit before reading it (413).

A declared ``Content-Length`` past the limit is answered at once; a chunked body is
counted as it streams and cut off past the limit. The routes check each uploaded file
against the same limit as well (:mod:`api.uploads`).
"""

from __future__ import annotations

import contextlib
import json

from starlette.types import ASGIApp, Message, Receive, Scope, Send

#: Room for the multipart framing and form fields around the files, bytes.
FORM_OVERHEAD_BYTES = 1 << 20


class BodyLimit:
    """ASGI middleware: 413 for bodies over ``limit`` (+ form overhead) bytes.

    Once a streamed body passes the limit, the app's receive raises
    :class:`BodyTooLarge`; whatever the app does about it (a form parser may report a
    "malformed" body, a route may answer 422), its answer is replaced by the 413 as long
    as no byte of it has been sent.
    """

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app = app
        self.limit = limit + FORM_OVERHEAD_BYTES

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        for name, value in scope.get("headers", []):
            if name == b"content-length" and value.isdigit() and int(value) > self.limit:
                await self._refuse(send)
                return
        seen = 0
        over = False
        started = False

        async def counted() -> Message:
            nonlocal seen, over
            if over:
                raise BodyTooLarge
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.limit:
                    over = True
                    raise BodyTooLarge
            return message

        async def guarded(message: Message) -> None:
            nonlocal started
            if over and not started:
                return  # the app's answer to a cut-off body; the 413 replaces it
            started = True
            await send(message)

        with contextlib.suppress(BodyTooLarge):
            await self.app(scope, counted, guarded)
        if over and not started:
            await self._refuse(send)

    async def _refuse(self, send: Send) -> None:
        body = json.dumps({"detail": f"request body larger than {self.limit} bytes "
                                     "(setting STAND_UPLOAD_LIMIT_BYTES)", "error": "too_large"})
        await send({"type": "http.response.start", "status": 413,
                    "headers": [(b"content-type", b"application/json")]})
        await send({"type": "http.response.body", "body": body.encode()})


class BodyTooLarge(Exception):
    """Raised inside the app when a streamed body passes the limit."""
