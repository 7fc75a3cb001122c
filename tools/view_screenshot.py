"""Screenshot of ``continuum-mhe view --serve-web`` in headless Chromium (loopback only).

Simulates the two-section robot's ``spatial`` scenario, estimates it with the MHE, serves
the view of the estimate and its truth on 127.0.0.1, loads the web viewer in headless
Chromium and saves what it shows::

    python tools/view_screenshot.py --out docs/figures/viewer_two_section.png

Needs ``chromium`` on PATH and rerun-sdk; drives Chromium through its DevTools protocol
(tornado's websocket client, installed with dask's distributed). Every address is
127.0.0.1.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

CLI = [sys.executable, "-m", "continuum_mhe.cli"]


def _run(*args: str) -> None:
    subprocess.run([*CLI, *args], check=True)


def _wait_line(proc: subprocess.Popen[str], text: str, seconds: float) -> str:
    assert proc.stderr is not None
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        line = proc.stderr.readline()
        if text in line:
            return line
        if not line and proc.poll() is not None:
            raise RuntimeError(f"view exited ({proc.returncode}) before '{text}'")
    raise RuntimeError(f"no '{text}' from view within {seconds:g} s")


def _devtools_ws(port: int, seconds: float = 30.0) -> str:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=2) as r:
                pages = [p for p in json.load(r) if p.get("type") == "page"]
            if pages:
                return str(pages[0]["webSocketDebuggerUrl"])
        except OSError:
            pass
        time.sleep(0.3)
    raise RuntimeError("Chromium's DevTools endpoint did not come up")


def _screenshot(ws_url: str, url: str, wait_s: float, out: Path) -> None:
    from tornado.ioloop import IOLoop
    from tornado.websocket import websocket_connect

    async def go() -> None:
        conn = await websocket_connect(ws_url, max_message_size=256 * 2**20)
        ids = iter(range(1, 1_000_000))

        async def call(method: str, **params: Any) -> dict[str, Any]:
            i = next(ids)
            await conn.write_message(json.dumps({"id": i, "method": method, "params": params}))
            while True:
                msg = await conn.read_message()
                if msg is None:
                    raise RuntimeError("DevTools connection closed")
                data = json.loads(msg)
                if data.get("id") == i:
                    return dict(data.get("result", {}))

        await call("Page.enable")
        await call("Page.navigate", url=url)
        time.sleep(wait_s)  # the viewer compiles its WebAssembly and streams the data
        shot = await call("Page.captureScreenshot", format="png")
        out.write_bytes(base64.b64decode(shot["data"]))
        conn.close()

    IOLoop.current().run_sync(go)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures/viewer_two_section.png"))
    ap.add_argument("--trail", default="10", help="view --trail: seconds of tip trail")
    ap.add_argument("--wait", type=float, default=45.0, help="seconds before the screenshot")
    ap.add_argument("--web-port", type=int, default=9191)
    ap.add_argument("--grpc-port", type=int, default=9877)
    ap.add_argument("--devtools-port", type=int, default=9223)
    args = ap.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        print("view_screenshot: needs chromium on PATH", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        robot = ["--robot", "two-section"]
        _run("simulate", "spatial", "-o", str(d / "m.csv"), "--truth", str(d / "t.csv"), *robot)
        _run("estimate", str(d / "m.csv"), "-o", str(d / "e.csv"), *robot)
        view = subprocess.Popen(
            [*CLI, "view", str(d / "e.csv"), *robot, "--truth", str(d / "t.csv"), "--serve-web",
             "--web-port", str(args.web_port), "--grpc-port", str(args.grpc_port),
             "--trail", args.trail],
            stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        browser = None
        try:
            url = _wait_line(view, "serving the view at", 120).split(" at ")[1].split()[0]
            browser = subprocess.Popen(
                [chromium, "--headless=new", "--no-sandbox", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--window-size=1600,900",
                 f"--remote-debugging-port={args.devtools_port}",
                 "--remote-debugging-address=127.0.0.1", f"--user-data-dir={d / 'chrome'}",
                 "about:blank"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
            )  # fmt: skip
            args.out.parent.mkdir(parents=True, exist_ok=True)
            _screenshot(_devtools_ws(args.devtools_port), url, args.wait, args.out)
        finally:
            if browser is not None:
                os.killpg(browser.pid, signal.SIGTERM)
                browser.wait(timeout=10)
            view.send_signal(signal.SIGINT)
            view.wait(timeout=30)
    print(f"wrote {args.out} ({url})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
