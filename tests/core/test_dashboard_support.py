"""What the dashboard's tests share: a headless Chromium driven through the system's
chromedriver by a tiny W3C WebDriver client (the standard library's urllib, no selenium),
the dashboard served in a thread of the test, and a small store built the way the loop
records runs. Holds no tests itself."""

from __future__ import annotations

import base64
import json
import shutil
import socket
import subprocess
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from coadapt_core.dashboard.files import RunFolders
from coadapt_core.dashboard.readonly import ReadOnlyStore
from coadapt_core.dashboard.server import start

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")
#: why the browser tests cannot run here (None: they can); CI installs both (.ci/run)
MISSING = (
    None
    if CHROMIUM and DRIVER
    else "headless Chromium and chromedriver are not installed (apt-get install chromium "
    "chromium-driver; .ci/run installs them)"
)
needs_browser = pytest.mark.skipif(MISSING is not None, reason=str(MISSING))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Browser:
    """One headless Chromium session through chromedriver (W3C WebDriver over HTTP)."""

    def __init__(self, width: int = 1400, height: int = 1000):
        self.port = free_port()
        self.driver = subprocess.Popen(
            [str(DRIVER), f"--port={self.port}"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        self.base = f"http://127.0.0.1:{self.port}"
        deadline = time.monotonic() + 20
        while True:
            try:
                self._call("GET", "/status")
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)
        args = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"]
        args += [f"--window-size={width},{height}", "--no-first-run", "--disable-extensions"]
        caps = {"browserName": "chrome", "goog:chromeOptions": {"binary": CHROMIUM, "args": args}}
        answer = self._call("POST", "/session", {"capabilities": {"alwaysMatch": caps}})
        self.session = f"/session/{answer['sessionId']}"

    def _call(self, method: str, path: str, body: Any = None) -> Any:
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(self.base + path, data=data, method=method)
        request.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(request, timeout=60) as response:
                return json.loads(response.read() or b"{}").get("value")
        except urllib.error.HTTPError as exc:
            raise AssertionError(f"webdriver {path}: {exc.read()[:300]!r}") from None

    def go(self, url: str) -> None:
        self._call("POST", self.session + "/url", {"url": url})

    def run(self, script: str, *args: Any) -> Any:
        return self._call(
            "POST", self.session + "/execute/sync", {"script": script, "args": list(args)}
        )

    def text(self, selector: str = "body", shown: bool = True) -> str:
        """The text `selector` shows (innerText), or all it holds, shown or folded away in
        a closed <details> (textContent: `shown=False`)."""
        prop = "innerText" if shown else "textContent"
        return self.run(
            f"const n = document.querySelector(arguments[0]); return n ? n.{prop} : null;",
            selector,
        )

    def wait_text(
        self, selector: str, timeout: float = 20.0, contains: str = "", shown: bool = True
    ) -> str:
        """The text of `selector` once it exists (and holds `contains`)."""
        deadline = time.monotonic() + timeout
        while True:
            found = self.text(selector, shown)
            if found is not None and contains in found:
                return found
            if time.monotonic() > deadline:
                raise AssertionError(f"{selector!r} never showed {contains!r}; page: {self.text()}")
            time.sleep(0.2)

    def screenshot(self, path: Path) -> Path:
        """The whole page as PNG (the window stretched to the page's height first)."""
        rect = self.session + "/window/rect"
        self._call("POST", rect, {"width": 1700, "height": 900})
        height = self.run("return document.documentElement.scrollHeight;")
        # the window's height includes the browser's own frame: a margin keeps the page whole
        self._call("POST", rect, {"width": 1700, "height": min(6000, height + 200)})
        png = base64.b64decode(self._call("GET", self.session + "/screenshot"))
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(png)
        return path

    def close(self) -> None:
        try:
            self._call("DELETE", self.session)
        finally:
            self.driver.terminate()
            self.driver.wait(timeout=20)


class Served:
    """The dashboard of a store, served from a thread of the test on a free port."""

    def __init__(self, store: str | Path, runs: Path | None = None):
        self.store = ReadOnlyStore(str(store))
        self.server = start(self.store, RunFolders(runs), "127.0.0.1", 0)
        self.url = self.server.url
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def get(self, path: str) -> tuple[int, bytes]:
        """(status, body) of a raw request: the path is sent exactly as given."""
        import http.client

        host, port = self.server.server_address[:2]
        connection = http.client.HTTPConnection(host, port, timeout=30)
        connection.request("GET", path)
        response = connection.getresponse()
        out = response.status, response.read()
        connection.close()
        return out

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()
        self.store.close()


# -- a small store, as the loop records runs ----------------------------------------------------
#: a GIF of one white pixel (the run folder's best_vs_nominal.gif)
GIF = base64.b64decode("R0lGODlhAQABAIAAAP///wAAACH5BAAAAAAALAAAAAABAAEAAAICRAEAOw==")
#: strings a hostile store row holds: markup and script that must show as text and never run
PAYLOAD = "<img src=x onerror=\"document.title='pwned'\"><script>window.pwned=1</script>"


def add_run(
    store: Any,
    run_id: str,
    runs: Path,
    *,
    objectives: tuple[str, ...] = ("torque",),
    seed: int = 0,
    status: str = "finished",
    summary: dict[str, Any] | None = None,
    extra: dict[str, Any] | None = None,
) -> str:
    """A run of 2 outer iterations x 2 rounds of 4 real designs (surrogate-scored) and one
    surrogate design, 2 training phases, its folder with a GIF; `summary` when finished."""
    import numpy as np

    folder = runs / run_id
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "best_vs_nominal.gif").write_bytes(GIF)
    config = {"method": "ours", "objective": ",".join(objectives), "terrain": "flat"}
    config.update(seed=seed, preset="smoke", sim="mujoco", robot="kuafu", optimizer="pso")
    config.update(outer_iterations=2, **(extra or {}))
    store.create_run(config, run_id=run_id, run_dir=str(folder))
    rng = np.random.default_rng(seed)
    for outer in range(2):
        store.record_training(
            run_id,
            outer=outer,
            idx=0,
            steps=10_000,
            seconds=2.0,
            final_reward=0.3 + 0.1 * outer,
            extra={
                "vx": 0.35 + 0.1 * outer,
                "tracking_error": 0.2 - 0.05 * outer,
                "episode_length_s": 8.0 + 4.0 * outer,
            },
        )
        for inner in range(2):
            designs = rng.uniform(0.5, 1.5, size=(4, 2))
            rows = [
                {
                    "outer": outer,
                    "inner": inner,
                    "idx": i,
                    "kind": "real",
                    "design": d,
                    "costs": {
                        o: 1.0 + float(((d - 0.6) ** 2).sum()) * (1 + k)
                        for k, o in enumerate(objectives)
                    },
                    "surrogate_error": {objectives[0]: 0.05 * (d[0] - 1)},
                    "interactions": 1000,
                    "seconds": 0.5,
                }
                for i, d in enumerate(designs)
            ]
            rows.append(
                {
                    "outer": outer,
                    "inner": inner,
                    "idx": 0,
                    "kind": "surrogate",
                    "design": rng.uniform(0.5, 1.5, size=2),
                    "costs": {objectives[0]: 1.2},
                    "interactions": 0,
                    "seconds": 0.05,
                }
            )
            store.record_evaluations(run_id, rows)
    if summary is not None:
        store.finish_run(run_id, {"run_id": run_id, **summary}, status=status)
    elif status != "running":
        store.set_status(run_id, status)
    return run_id
