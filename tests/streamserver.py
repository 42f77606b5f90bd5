"""Live video streams served on 127.0.0.1 for the tests: a camera that plays a test pattern for a
few seconds and then goes away (the server ends the connection).

- HTTP: FFmpeg itself (``-listen 1``) sends MJPEG as multipart/x-mixed-replace, as many IP
  cameras do.
- RTSP: FFmpeg cannot serve RTSP to a player, so a small RTSP server here answers OPTIONS,
  DESCRIBE (an SDP for RTP/H.264), SETUP (RTP interleaved in the TCP connection; UDP is refused
  with 461, as a camera behind NAT does) and PLAY, then relays the RTP packets that an FFmpeg
  started for the client sends to a local UDP port. When FFmpeg has sent ``seconds`` of video
  the connection is closed: a camera that disconnects.

Everything stops by itself: FFmpeg runs for ``seconds`` (``-t``) and the server's threads are
daemons with timeouts.
"""

from __future__ import annotations

import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import imageio_ffmpeg

FFMPEG = imageio_ffmpeg.get_ffmpeg_exe()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _pattern(
    seconds: float, size: str, rate: int, codec: list[str], video: str | None
) -> list[str]:
    """FFmpeg playing ``video`` (looped), or else a test pattern, at its own pace."""
    head = [FFMPEG, "-hide_banner", "-loglevel", "error", "-re"]
    if video is None:
        head += ["-f", "lavfi", "-i", f"testsrc=size={size}:rate={rate}"]
    else:
        head += ["-stream_loop", "-1", "-i", video, "-an"]
    return [*head, "-t", str(seconds), *codec]


MJPEG = ["-c:v", "mjpeg", "-q:v", "5"]
# H.264 as cameras send it, its parameter sets repeated in the stream (the SDP carries none).
H264 = ["-c:v", "libx264", "-preset", "ultrafast", "-tune", "zerolatency", "-pix_fmt", "yuv420p"]
H264 += ["-g", "10", "-x264-params", "repeat-headers=1"]


@contextmanager
def http_camera(
    seconds: float = 2.0, size: str = "160x120", rate: int = 10, video: str | None = None
) -> Iterator[str]:
    """An MJPEG-over-HTTP camera for one client; yields its URL."""
    port = free_port()
    url = f"http://127.0.0.1:{port}/video.mjpg"
    proc = subprocess.Popen(
        [*_pattern(seconds, size, rate, MJPEG, video), "-f", "mpjpeg", "-listen", "1", url]
    )
    try:
        _wait_listening(port)
        yield url
    finally:
        proc.kill()
        proc.wait()


def _wait_listening(port: int, timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            # A connection attempt would be taken as the one client: only look for the socket.
            with open("/proc/net/tcp") as f:
                if any(
                    line.split()[1].endswith(f":{port:04X}") and line.split()[3] == "0A"
                    for line in f.readlines()[1:]
                ):
                    return
        except OSError:
            pass
        time.sleep(0.05)
    raise TimeoutError(f"no server listening on port {port}")


_SDP = (
    "v=0\r\no=- 0 0 IN IP4 127.0.0.1\r\ns=densepeds test camera\r\nc=IN IP4 127.0.0.1\r\n"
    "t=0 0\r\nm=video 0 RTP/AVP 96\r\na=rtpmap:96 H264/90000\r\n"
    "a=fmtp:96 packetization-mode=1\r\na=control:track0\r\n"
)


class RtspCamera:
    """A one-stream RTSP server on 127.0.0.1 (see the module docstring); ``url`` to play."""

    def __init__(
        self, seconds: float = 2.0, size: str = "160x120", rate: int = 10, video: str | None = None
    ) -> None:
        self.seconds, self.size, self.rate, self.video = seconds, size, rate, video
        self._listener = socket.create_server(("127.0.0.1", 0))
        self._listener.settimeout(0.2)
        self.url = f"rtsp://127.0.0.1:{self._listener.getsockname()[1]}/live"
        self._stop = threading.Event()
        self._procs: list[subprocess.Popen[bytes]] = []
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self._listener.close()
        for proc in self._procs:
            proc.kill()
            proc.wait()

    def __enter__(self) -> RtspCamera:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            threading.Thread(target=self._client, args=(conn,), daemon=True).start()

    def _client(self, conn: socket.socket) -> None:
        conn.settimeout(0.2)
        buf = b""
        playing: threading.Thread | None = None
        try:
            while not self._stop.is_set():
                if playing is not None and not playing.is_alive():
                    return  # the stream ended: the camera hangs up
                try:
                    data = conn.recv(65536)
                except TimeoutError:
                    continue
                if not data:
                    return
                buf += data
                while True:
                    if buf[:1] == b"$":  # the client's RTCP, interleaved: skipped
                        if len(buf) < 4:
                            break
                        size = 4 + int.from_bytes(buf[2:4], "big")
                        if len(buf) < size:
                            break
                        buf = buf[size:]
                        continue
                    end = buf.find(b"\r\n\r\n")
                    if end < 0:
                        break
                    head, buf = buf[:end].decode("latin-1"), buf[end + 4 :]
                    started = self._answer(conn, head)
                    if started is not None:
                        playing = started
        finally:
            conn.close()

    def _answer(self, conn: socket.socket, head: str) -> threading.Thread | None:
        lines = head.split("\r\n")
        method = lines[0].split(" ")[0]
        fields = {
            k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])
        }
        reply = [f"CSeq: {fields.get('cseq', '0')}"]
        body = ""
        started = None
        status = "200 OK"
        if method == "OPTIONS":
            reply.append("Public: OPTIONS, DESCRIBE, SETUP, PLAY, TEARDOWN, GET_PARAMETER")
        elif method == "DESCRIBE":
            body = _SDP
            reply += [f"Content-Base: {self.url}/", "Content-Type: application/sdp"]
        elif method == "SETUP":
            if "TCP" not in fields.get("transport", ""):
                status = "461 Unsupported Transport"
            else:
                reply += ["Transport: RTP/AVP/TCP;unicast;interleaved=0-1", "Session: 1"]
        elif method == "PLAY":
            reply += ["Session: 1", "Range: npt=0.000-"]
            started = threading.Thread(target=self._relay, args=(conn,), daemon=True)
        elif method not in ("GET_PARAMETER", "TEARDOWN"):
            status = "405 Method Not Allowed"
        if body:
            reply.append(f"Content-Length: {len(body)}")
        text = f"RTSP/1.0 {status}\r\n" + "".join(f"{r}\r\n" for r in reply) + "\r\n"
        conn.sendall(text.encode())
        if body:
            conn.sendall(body.encode())
        if started is not None:
            started.start()
        return started

    def _relay(self, conn: socket.socket) -> None:
        """RTP from an FFmpeg started now, to the client, interleaved on channel 0."""
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
            udp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 23)  # a slow reader loses less
            udp.bind(("127.0.0.1", 0))
            udp.settimeout(0.5)
            port = udp.getsockname()[1]
            cmd = [*_pattern(self.seconds, self.size, self.rate, H264, self.video), "-f", "rtp"]
            target = f"rtp://127.0.0.1:{port}?pkt_size=1200"
            proc = subprocess.Popen([*cmd, target], stdout=subprocess.DEVNULL)
            self._procs.append(proc)
            while not self._stop.is_set():
                try:
                    packet = udp.recv(65536)
                except TimeoutError:
                    if proc.poll() is not None:
                        return
                    continue
                try:
                    conn.sendall(b"$\x00" + len(packet).to_bytes(2, "big") + packet)
                except OSError:
                    return
