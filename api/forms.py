"""Multipart forms parsed off the event loop.

Starlette parses a form in the event loop (python-multipart, pure Python): about 30 ms
of loop time per megabyte, so 100 concurrent uploads of 5 MB held every other request
(GET /health included) for seconds. Here the loop only copies the body into a spooled
temporary file (in memory, or on disk by worker threads); python-multipart parses that
file in a worker thread, in the app's parsing lanes (:data:`api.uploads.PARSE_LANES`).
"""

from __future__ import annotations

import tempfile
from typing import Any

import anyio
from fastapi import Request
from fastapi.exceptions import RequestValidationError
from python_multipart.exceptions import FormParserError
from python_multipart.multipart import Field, File, parse_form
from starlette.datastructures import FormData, Headers, UploadFile

from stand.errors import StorageError

#: Body bytes kept in memory before the spool goes to a temporary file.
SPOOL_MEMORY_BYTES = 1 << 20
#: Most files and most plain fields in one form.
MAX_FILES = 200
MAX_FIELDS = 200


def _malformed(message: str) -> RequestValidationError:
    return RequestValidationError([{"type": "value_error", "loc": ("body",), "input": None,
                                    "msg": f"malformed multipart form: {message}"}])


def _parse(headers: dict[str, bytes], body: Any) -> FormData:
    items: list[tuple[str, str | UploadFile]] = []
    counts = {"files": 0, "fields": 0}

    def on_field(field: Field) -> None:
        counts["fields"] += 1
        if counts["fields"] > MAX_FIELDS:
            raise _malformed(f"more than {MAX_FIELDS} fields")
        value = field.value or b""
        items.append(((field.field_name or b"").decode("utf-8", "replace"),
                      value.decode("utf-8", "replace")))

    def on_file(file: File) -> None:
        counts["files"] += 1
        if counts["files"] > MAX_FILES:
            raise _malformed(f"more than {MAX_FILES} files")
        stream: Any = file.file_object
        stream.seek(0)
        name = (file.field_name or b"").decode("utf-8", "replace")
        filename = file.file_name.decode("utf-8", "replace") if file.file_name else None
        items.append((name, UploadFile(stream, size=file.size, filename=filename,
                                       headers=Headers({"content-type": file.content_type or ""}))))

    body.seek(0)
    try:
        parse_form(headers, body, on_field, on_file)
    except (FormParserError, ValueError) as exc:
        raise _malformed(str(exc) or type(exc).__name__) from exc
    return FormData(items)


async def read_form(request: Request, lanes: anyio.CapacityLimiter) -> FormData:
    """The request's multipart form, parsed in a worker thread; 422 when malformed.

    The caller closes the form (``await form.close()``).
    """
    headers = {"Content-Type": request.headers.get("content-type", "").encode("latin-1")}
    spool = tempfile.SpooledTemporaryFile(max_size=SPOOL_MEMORY_BYTES)  # noqa: SIM115
    try:
        async for chunk in request.stream():
            if spool._rolled:  # type: ignore[attr-defined]
                # On disk: a write may wait for the kernel to flush dirty pages, which
                # under a hundred concurrent uploads took seconds; not in the loop.
                await anyio.to_thread.run_sync(spool.write, chunk)
            else:
                spool.write(chunk)
        return await anyio.to_thread.run_sync(_parse, headers, spool, limiter=lanes)
    except OSError as exc:  # the server's disk, not the caller's form (503)
        raise StorageError(f"cannot store the request body in a temporary file: {exc}; "
                           "free disk space on the server") from exc
    finally:
        spool.close()
