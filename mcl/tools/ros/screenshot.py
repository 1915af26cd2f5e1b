"""`python -m mcl.tools.ros.screenshot RRD PNG`: a screenshot of Rerun's web viewer showing a recording.

    robocup-mcl node --rrd live.rrd ...                                   # or node bench --rrd live.rrd
    python -m mcl.tools.ros.screenshot live.rrd docs/images/ros_node_rerun.png --wait 90

It serves the recording with the Rerun viewer's web server (`rerun --serve-web`, the viewer that rerun-sdk
ships, so nothing is fetched from the network), opens it in headless Chromium (WebGL on its software
rasteriser, SwiftShader) and, after `--wait` seconds for the viewer to load and lay out the file, saves what the
page shows through Chromium's DevTools protocol (`Page.captureScreenshot`; a small WebSocket client of the
standard library). Both servers listen on the loopback of a network namespace that has no other interface (as
root it re-runs itself under `unshare --net`, as `robocup-mcl node bench` does; elsewhere it refuses), so no
port opens on the machine's network. Needs `chromium` (or `chromium-browser`) on the PATH and the `rerun`
command of rerun-sdk.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import socket
import struct
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import argparse

PROG = "python -m mcl.tools.ros.screenshot"
VIEWER_PORT, GRPC_PORT, DEVTOOLS_PORT = 9090, 9876, 9222


class DevTools:
    """A minimal client of Chromium's DevTools protocol over one WebSocket (text frames, masked as a client must)."""

    def __init__(self, port: int, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=2) as answer:
                    targets = json.load(answer)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise RuntimeError("Chromium's DevTools did not answer") from None
                time.sleep(0.5)
        url = next(t["webSocketDebuggerUrl"] for t in targets if t.get("type") == "page")
        path = url.split(f":{port}", 1)[1]
        self.socket = socket.create_connection(("127.0.0.1", port), timeout=60)
        key = base64.b64encode(os.urandom(16)).decode()
        self.socket.sendall(
            f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
        )
        answer = b""
        while b"\r\n\r\n" not in answer:
            answer += self.socket.recv(4096)
        head, self._buffer = answer.split(b"\r\n\r\n", 1)
        if b" 101 " not in head.split(b"\r\n")[0]:
            raise RuntimeError(f"DevTools refused the WebSocket: {head[:200]!r}")
        self._id = 0

    def _send(self, message: dict) -> None:
        data, mask = json.dumps(message).encode(), os.urandom(4)
        n = len(data)
        if n < 126:
            head = bytes([0x81, 0x80 | n])
        elif n < 65536:
            head = bytes([0x81, 0x80 | 126]) + struct.pack(">H", n)
        else:
            head = bytes([0x81, 0x80 | 127]) + struct.pack(">Q", n)
        self.socket.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))

    def _exactly(self, n: int) -> bytes:
        while len(self._buffer) < n:
            chunk = self.socket.recv(1 << 20)
            if not chunk:
                raise RuntimeError("DevTools closed the connection")
            self._buffer += chunk
        data, self._buffer = self._buffer[:n], self._buffer[n:]
        return data

    def _receive(self) -> dict:
        payload = b""
        while True:
            first, second = self._exactly(2)
            n = second & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._exactly(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._exactly(8))[0]
            payload += self._exactly(n)
            if first & 0x80:  # the last fragment
                return json.loads(payload)

    def call(self, method: str, **params: Any) -> dict:
        """Call `method` and return its result (events received meanwhile are skipped)."""
        self._id += 1
        self._send({"id": self._id, "method": method, "params": params})
        while True:
            message = self._receive()
            if message.get("id") == self._id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})


def _stop_group(process: subprocess.Popen) -> None:
    """SIGTERM to the process group `process` leads (it was started in a session of its own), 10 s, then SIGKILL."""
    import signal

    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            break
        try:
            process.wait(timeout=10)
            break
        except subprocess.TimeoutExpired:
            continue
    try:  # the group's other members, should the leader have gone first
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait()


def screenshot(rrd: str, out: str, wait: float, width: int, height: int) -> None:
    """Serve `rrd` with Rerun's web viewer, open it in headless Chromium, wait `wait` s, save the page to `out`.
    Run it where the only network interface is the loopback (see the module docstring)."""
    rerun = shutil.which("rerun", path=os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]]))
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if rerun is None or chromium is None:
        raise RuntimeError("needs the `rerun` command (rerun-sdk) and `chromium` on the PATH")
    server = subprocess.Popen(
        [
            rerun,
            "--serve-web",
            "--web-viewer-port",
            str(VIEWER_PORT),
            "--port",
            str(GRPC_PORT),
            "--renderer",
            "webgl",
            rrd,
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # `rerun` starts the viewer's server as a child: stopped with its group
    )
    browser = subprocess.Popen(
        [
            chromium,
            "--headless=new",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--ignore-gpu-blocklist",
            f"--window-size={width},{height}",
            f"--remote-debugging-port={DEVTOOLS_PORT}",
            "about:blank",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # Chromium's helper processes too
    )
    try:
        tools = DevTools(DEVTOOLS_PORT)
        tools.call("Page.enable")
        tools.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1, mobile=False)
        proxy = f"rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{GRPC_PORT}%2Fproxy"
        tools.call("Page.navigate", url=f"http://127.0.0.1:{VIEWER_PORT}/?url={proxy}&renderer=webgl")
        time.sleep(wait)
        shot = tools.call("Page.captureScreenshot", format="png")
        Path(out).write_bytes(base64.b64decode(shot["data"]))
    finally:
        for process in (browser, server):
            _stop_group(process)


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    import argparse

    parser = argparse.ArgumentParser(
        prog=prog,
        description="A screenshot of Rerun's web viewer showing a recording (.rrd), taken with headless Chromium in "
        "a network namespace with only the loopback.",
    )
    parser.add_argument("rrd", help="the Rerun recording (.rrd)")
    parser.add_argument("out", help="the image to write (.png)")
    parser.add_argument("--wait", type=float, default=90.0, help="seconds for the viewer to load (default 90)")
    parser.add_argument("--width", type=int, default=1400, help="the page's width in pixels (default 1400)")
    parser.add_argument("--height", type=int, default=900, help="the page's height in pixels (default 900)")
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`python -m mcl.tools.ros.screenshot RRD PNG` (see `--help`); returns the exit status."""
    from mcl.tools.cli_checks import CommandError, check_output_file
    from mcl.tools.ros.bench import rerun_isolated

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser(prog).parse_args(argv)
    if not os.path.isfile(args.rrd):
        raise CommandError(f"{args.rrd}: no such file")
    if not (args.wait >= 0 and args.width > 0 and args.height > 0):
        raise CommandError("--wait must be >= 0, --width and --height > 0")
    check_output_file(args.out, "out")
    status = rerun_isolated("mcl.tools.ros.screenshot", argv, "the viewer and the browser")
    if status is not None:
        return status
    try:
        screenshot(os.path.abspath(args.rrd), os.path.abspath(args.out), args.wait, args.width, args.height)
    except (RuntimeError, OSError) as error:
        raise CommandError(str(error)) from None
    print(f"{args.out}: the viewer after {args.wait:g} s")
    return 0


if __name__ == "__main__":
    from mcl.tools.cli_checks import run_main

    raise SystemExit(run_main(main, PROG))
