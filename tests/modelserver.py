"""A model mirror on 127.0.0.1 for tests: Python's http.server in a thread, with HTTP Range
support (206 partial content), an optional cut-off that drops the connection mid-file, and
``special`` answers for some paths: ``("redirect", location)`` (302), ``("announce", n)`` (a
200 announcing n bytes, sending at most the file), ``("stream", n)`` (n junk bytes, no length,
closed after; ``sent[path]`` records how many the client took before it hung up), ``("slow", s)``
(served as usual after s seconds)."""

from __future__ import annotations

import functools
import http.server
import re
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


class _Handler(http.server.SimpleHTTPRequestHandler):
    ranges: list[str | None]  # the Range header of every GET, in order (set per server)
    cut_after: list[int | None]  # bytes sent before dropping the connection, once
    special: dict[str, tuple[str, Any]]
    sent: dict[str, int]
    paths: list[str]  # every GET's path, in order

    def log_message(self, *args: Any) -> None:  # quiet test output
        pass

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        path = Path(self.translate_path(self.path))
        header = self.headers.get("Range")
        self.ranges.append(header)
        self.paths.append(self.path)
        if self.path in self.special:
            kind, arg = self.special[self.path]
            if kind != "slow":
                self._special(kind, arg)
                return
            time.sleep(arg)  # then served as usual
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

    def _special(self, kind: str, arg: Any) -> None:
        if kind == "redirect":
            self.send_response(302)
            self.send_header("Location", arg)
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        if kind == "announce":
            self.send_response(200)
            self.send_header("Content-Length", str(arg))
            self.end_headers()
            self.wfile.write(b"x" * 1000)
            self.close_connection = True
            return
        assert kind == "stream"
        self.protocol_version = "HTTP/1.0"
        self.send_response(200)
        self.end_headers()
        block = b"y" * 65536
        self.sent[self.path] = 0
        try:
            for _ in range(arg // len(block)):
                self.wfile.write(block)
                self.sent[self.path] += len(block)
        except OSError:
            pass
        self.close_connection = True


@contextmanager
def serve(
    root: Path,
    cut_after: int | None = None,
    special: dict[str, tuple[str, Any]] | None = None,
    paths: list[str] | None = None,
    sent: dict[str, int] | None = None,
) -> Iterator[tuple[str, list[str | None]]]:
    """Serve ``root`` on 127.0.0.1; yields (base URL, the Range headers received). ``paths``
    and ``sent``, where given, collect the paths asked for and the streamed byte counts."""
    ranges: list[str | None] = []
    handler = type(
        "Handler",
        (_Handler,),
        {
            "ranges": ranges,
            "cut_after": [cut_after],
            "special": special or {},
            "sent": {} if sent is None else sent,
            "paths": [] if paths is None else paths,
        },
    )
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
