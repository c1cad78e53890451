"""The dashboard's HTTP server (the standard library's threading server): four pages, their
JSON, the page assets shipped in `static/`, and the files of run folders (`files`).

Every page is the same small HTML shell; its script fetches the page's JSON and writes every
value from the store as text (`textContent`), never as markup, and the Content-Security-Policy
runs only the package's own scripts. A request names a run or grid by id (checked as a run
id, then looked up in the store) and a file by a path inside that run's folder; anything
else is refused with a one-line page. An error never shows a traceback: the page, or the
JSON, says in one line what went wrong."""

from __future__ import annotations

import json
import math
import sys
import urllib.parse
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

import sqlalchemy as sa

from coadapt_core.dashboard.files import Refused, RunFolders
from coadapt_core.dashboard.grid_data import grid_page
from coadapt_core.dashboard.run_data import compare_page, run_page
from coadapt_core.dashboard.runs_data import runs_page
from coadapt_core.errors import UserError
from coadapt_core.results.store import ResultsStore
from coadapt_core.validation import is_run_id

#: the page assets and their content types (nothing else is served from the package)
ASSETS = {
    "dashboard.js": "text/javascript; charset=utf-8",
    "chart.js": "text/javascript; charset=utf-8",
    "pages.js": "text/javascript; charset=utf-8",
    "dashboard.css": "text/css; charset=utf-8",
}
#: how many runs the compare page takes at most
MAX_COMPARED = 8
#: what the browser may run and load: the package's own files only
POLICY = (
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; "
    "connect-src 'self'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
PAGES = ("runs", "run", "grid", "compare")

SHELL = """<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>coadapt dashboard</title>
<link rel="stylesheet" href="/static/dashboard.css">
<script src="/static/chart.js" defer></script>
<script src="/static/dashboard.js" defer></script>
<script src="/static/pages.js" defer></script>
</head><body data-page="{page}">
<header><a href="/" class="brand">coadapt dashboard</a>
<span class="note">read-only view of {store}</span>
<span id="live" class="live"></span></header>
<main id="main"><p class="loading">Loading…</p></main>
<noscript><p>The dashboard draws its pages with JavaScript; this browser has it off.</p></noscript>
</body></html>
"""


def _clean(value: Any) -> Any:
    """JSON-safe: NaN and infinities become null (JSON has no such numbers)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


def shell(page: str, store_url: str) -> bytes:
    """The page shell; the store's URL (a password in it hidden) is the only value in it."""
    import html

    shown = sa.engine.make_url(store_url).render_as_string(hide_password=True)
    return SHELL.format(page=page, store=html.escape(shown)).encode()


class Handler(BaseHTTPRequestHandler):
    """One request: a page, its JSON, an asset or a run folder's file."""

    server: DashboardServer
    protocol_version = "HTTP/1.1"
    server_version = "coadapt-dashboard"
    sys_version = ""

    def log_message(self, format: str, *args: Any) -> None:  # quiet: one line per error only
        pass

    def do_HEAD(self) -> None:
        self.do_GET()

    def do_GET(self) -> None:
        try:
            self._route()
        except Exception as exc:  # never a traceback: one line here, one line in the page
            print(f"dashboard: {self.path!r}: {type(exc).__name__}: {exc}", file=sys.stderr)
            self._error(HTTPStatus.INTERNAL_SERVER_ERROR, "the dashboard could not answer this")

    def do_POST(self) -> None:
        self._error(HTTPStatus.METHOD_NOT_ALLOWED, "the dashboard only reads")

    do_PUT = do_DELETE = do_PATCH = do_POST

    def _route(self) -> None:
        if not self.server.host_allowed(self.headers.get("Host", "")):
            return self._error(HTTPStatus.FORBIDDEN, "unknown Host header; refused")
        parsed = urllib.parse.urlsplit(self.path)
        raw = parsed.path
        query = urllib.parse.parse_qs(parsed.query)
        parts = raw.split("/")
        if raw == "/":
            return self._send(HTTPStatus.OK, shell("runs", self.server.store.url), "text/html")
        head = parts[1]
        if head in ("run", "grid") and len(parts) == 3:
            return self._send(HTTPStatus.OK, shell(head, self.server.store.url), "text/html")
        if raw == "/compare":
            return self._send(HTTPStatus.OK, shell("compare", self.server.store.url), "text/html")
        if head == "api":
            return self._api(parts[2:], query)
        if head == "static" and len(parts) == 3 and parts[2] in ASSETS:
            body = resources.files(__package__).joinpath("static", parts[2]).read_bytes()
            return self._send(HTTPStatus.OK, body, ASSETS[parts[2]])
        if head == "files" and len(parts) >= 4:
            return self._file(parts[2], raw.split("/", 3)[3])
        return self._error(HTTPStatus.NOT_FOUND, "no such page")

    def _api(self, parts: list[str], query: dict[str, list[str]]) -> None:
        store, folders = self.server.store, self.server.folders

        def one(name: str, default: str = "") -> str:
            return (query.get(name) or [default])[0]

        try:
            if parts == ["runs"]:
                page = one("page", "0")
                data = runs_page(
                    store,
                    q=one("q"),
                    status=one("status"),
                    grid=one("grid"),
                    sort=one("sort", "created"),
                    descending=one("desc", "1") != "0",
                    page=int(page) if page.isdigit() else 0,
                )
            elif len(parts) == 2 and parts[0] == "run":
                data = run_page(store, folders, self._run_id(parts[1]))
            elif len(parts) == 2 and parts[0] == "grid":
                data = grid_page(store, self._run_id(parts[1], "grid"))
            elif parts == ["compare"]:
                ids = [self._run_id(i) for i in query.get("run", [])][:MAX_COMPARED]
                if not ids:
                    raise UserError("name the runs to compare: /compare?run=ID&run=ID")
                data = compare_page(store, ids)
            else:
                return self._json(HTTPStatus.NOT_FOUND, {"error": "no such data"})
        except UserError as exc:
            return self._json(HTTPStatus.NOT_FOUND, {"error": str(exc)})
        except sa.exc.OperationalError as exc:  # locked or busy while a run writes: try again
            detail = " ".join(str(exc.orig).split())[:120]
            return self._json(HTTPStatus.SERVICE_UNAVAILABLE, {"error": f"store busy: {detail}"})
        self._json(HTTPStatus.OK, data)

    @staticmethod
    def _run_id(text: str, field: str = "run") -> str:
        value = urllib.parse.unquote(text)
        if not is_run_id(value):
            raise UserError(f"'{value}' is not a {field} id", field=field)
        return value

    def _file(self, run_text: str, relative: str) -> None:
        try:
            run = self.server.store.get_run(self._run_id(run_text))
            path, kind = self.server.folders.file(run, urllib.parse.unquote(relative))
            body = path.read_bytes()
        except (UserError, Refused) as exc:
            return self._error(HTTPStatus.NOT_FOUND, str(exc))
        except OSError:
            return self._error(HTTPStatus.NOT_FOUND, "the file could not be read")
        self._send(HTTPStatus.OK, body, kind)

    def _json(self, status: HTTPStatus, data: Any) -> None:
        body = json.dumps(_clean(data), allow_nan=False, default=str).encode()
        self._send(status, body, "application/json")

    def _error(self, status: HTTPStatus, message: str) -> None:
        import html

        text = html.escape(" ".join(message.split()))
        body = (
            "<!doctype html><html lang='en'><head><meta charset='utf-8'><title>coadapt "
            f"dashboard: {status.value}</title></head><body><h1>{status.value} "
            f"{status.phrase}</h1><p id='error'>{text}</p><p><a href='/'>All runs</a></p>"
            "</body></html>"
        ).encode()
        self._send(status, body, "text/html")

    def _send(self, status: HTTPStatus, body: bytes, kind: str) -> None:
        if "charset" not in kind and kind.startswith(("text/", "application/json")):
            kind += "; charset=utf-8"
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("Content-Security-Policy", POLICY)
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)


class DashboardServer(ThreadingHTTPServer):
    """The server of one store and its run folders."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, store: ResultsStore, folders: RunFolders, host: str, port: int):
        self.store = store
        self.folders = folders
        super().__init__((host, port), Handler)
        self.local_only = host in ("127.0.0.1", "localhost", "::1")

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A connection the browser dropped is no error; anything else is one line."""
        kind, exc = sys.exc_info()[:2]
        if kind is not None and not issubclass(kind, ConnectionError | TimeoutError):
            print(f"dashboard: {client_address[0]}: {kind.__name__}: {exc}", file=sys.stderr)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}/"

    def host_allowed(self, value: str) -> bool:
        """On a local address, only local Host headers (a web page elsewhere cannot point
        a name of its own at this port and read it: DNS rebinding); any on another one."""
        if not self.local_only:
            return True
        name = value.rsplit(":", 1)[0] if not value.endswith("]") else value
        return name in ("127.0.0.1", "localhost", "[::1]")


def start(store: ResultsStore, folders: RunFolders, host: str, port: int) -> DashboardServer:
    """A server bound to (host, port) (port 0: a free one); a port that cannot be bound is a
    one-line `UserError` naming --port or --host. The caller runs `serve_forever`. The plugin
    registry (objective and optimizer orders of the tables) is loaded first, so the first
    page is as quick as the next."""
    from coadapt_core.plugins import get_registry

    get_registry()
    try:
        return DashboardServer(store, folders, host, port)
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        if exc.errno in (98, 48, 10048):  # in use (Linux, macOS, Windows)
            raise UserError(
                f"--port {port} is in use on {host}; give another port (--port 0 picks a free one)",
                field="port",
            ) from None
        raise UserError(
            f"--host {host} --port {port} cannot be served ({reason}); give an address of this "
            "machine (the default 127.0.0.1) and a port from 1024 to 65535",
            field="host",
        ) from None
