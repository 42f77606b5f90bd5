"""A model mirror on 127.0.0.1 for tests: Python's http.server in a thread, with HTTP Range
support (206 partial content) and an optional cut-off that drops the connection mid-file."""

from __future__ import annotations

import functools
import http.server
import re
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


class _Handler(http.server.SimpleHTTPRequestHandler):
    ranges: list[str | None]  # the Range header of every GET, in order (set per server)
    cut_after: list[int | None]  # bytes sent before dropping the connection, once

    def log_message(self, *args: Any) -> None:  # quiet test output
        pass

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        path = Path(self.translate_path(self.path))
        header = self.headers.get("Range")
        self.ranges.append(header)
        if not path.is_file():
            self.send_error(404)
            return
        data = path.read_bytes()
        start = 0
        m = re.fullmatch(r"bytes=(\d+)-", header or "")
        if m:
            start = int(m.group(1))
            if start >= len(data):
                self.send_response(416)
                self.send_header("Content-Range", f"bytes */{len(data)}")
                self.end_headers()
                return
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
        else:
            self.send_response(200)
        body = data[start:]
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        cut = self.cut_after[0]
        if cut is not None:
            self.cut_after[0] = None  # only the first download is interrupted
            self.wfile.write(body[:cut])
            self.wfile.flush()
            self.close_connection = True
            return
        self.wfile.write(body)


@contextmanager
def serve(root: Path, cut_after: int | None = None) -> Iterator[tuple[str, list[str | None]]]:
    """Serve ``root`` on 127.0.0.1; yields (base URL, the Range headers received)."""
    ranges: list[str | None] = []
    handler = type("Handler", (_Handler,), {"ranges": ranges, "cut_after": [cut_after]})
    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(handler, directory=str(root))
    )
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", ranges
    finally:
        server.shutdown()
        server.server_close()
        thread.join()
