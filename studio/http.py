"""The studio's small, safe HTTP server: exact routes, file trees that cannot be escaped, clean stop.

Role: the one place where requests meet the file system. Both pages
(``studio/gallery.py`` for ``decollage view``, ``studio/painter.py`` for
``decollage paint``) describe themselves as an ``App``: exact routes (method and
path → handler) and file trees (URL prefix → folder). Everything else is 404.

Safety rules, applied to every request before any handler runs:

- the server binds to 127.0.0.1 unless told otherwise;
- the ``Host`` header must name the address the server listens on (or
  ``localhost``), so a web page on another site cannot reach the server
  through DNS rebinding (403 otherwise);
- a POST must carry ``Content-Type: application/json``, at most ``MAX_BODY``
  bytes, and no ``Origin`` other than the server's own (403 otherwise), so
  another site's page cannot make the painter write the recipe;
- a path whose segments, decoded once or twice, hold ``..``, ``.``, a segment
  starting with a dot, an empty segment, a backslash, a NUL or a ``%`` left
  after decoding is refused (404) before routing; a file tree only serves
  regular files that still lie inside its folder once symlinks are resolved;
- unknown paths are 404 and known paths with another method are 405;
- pages get a Content-Security-Policy that allows scripts from the server
  itself (and the page's import map, by hash) only.

``serve`` runs an app until Ctrl-C (or SIGTERM), then closes the socket and
the app (``App.close``) and returns.
"""

from __future__ import annotations

import json
import mimetypes
import signal
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, unquote, urlsplit

from core.errors import DecollageError, StudioError

#: Largest request body the studio reads (a painted 64³ grid as JSON is ~2 MB).
MAX_BODY = 16 * 1024 * 1024

_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".mjs": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".json": "application/json",
    ".png": "image/png",
    ".glb": "model/gltf-binary",
    ".svg": "image/svg+xml",
}


class HttpError(StudioError):
    """A request the studio answers with an error status (``status``) and a one-line message."""

    def __init__(self, status: HTTPStatus, message: str, **kw) -> None:
        super().__init__(message, **kw)
        self.status = status


@dataclass
class Request:
    """One parsed request: ``path`` decoded and checked, ``query`` as lists, ``body`` parsed JSON (POST)."""

    method: str
    path: str
    query: dict[str, list[str]]
    body: object = None

    def arg(self, name: str, default: str | None = None) -> str | None:
        """The first value of query argument ``name``, or ``default``."""
        values = self.query.get(name)
        return values[0] if values else default


@dataclass
class Response:
    """What a handler returns: status, body bytes and content type (plus extra headers)."""

    body: bytes
    content_type: str = "application/json"
    status: HTTPStatus = HTTPStatus.OK
    headers: dict[str, str] = field(default_factory=dict)

    @classmethod
    def json(cls, data, status: HTTPStatus = HTTPStatus.OK) -> "Response":
        return cls(json.dumps(data).encode("utf-8"), "application/json", status, {"Cache-Control": "no-store"})


Handler = Callable[[Request], Response]


@dataclass
class App:
    """Routes of one page: exact ``(method, path)`` handlers and read-only file trees.

    Attributes:
        routes: ``("GET", "/api/manifest")`` → handler.
        trees: URL prefix ending in ``/`` (``"/files/"``) → folder served below it.
        csp: Content-Security-Policy sent with every response.
        close: called once when the server stops (stop workers, remove scratch files).
    """

    routes: dict[tuple[str, str], Handler] = field(default_factory=dict)
    trees: dict[str, Path] = field(default_factory=dict)
    csp: str = "default-src 'self'"
    close: Callable[[], None] = lambda: None


def clean_segments(raw_path: str) -> list[str]:
    """The path's segments, percent-decoded; raises 404 for anything that could climb or hide.

    ``raw_path`` is the request target's path as sent (still percent-encoded).
    ``"/"`` gives ``[]``.
    """
    not_found = HttpError(HTTPStatus.NOT_FOUND, "not found")
    if not raw_path.startswith("/"):
        raise not_found
    try:
        decoded = unquote(raw_path, errors="strict")
        twice = unquote(decoded, errors="strict")
    except UnicodeDecodeError:
        raise not_found from None
    if "%" in decoded or "\\" in twice or "\x00" in twice:
        raise not_found
    if decoded == "/":
        return []
    segments = decoded[1:].split("/")
    for seg in segments + twice[1:].split("/"):
        if seg in ("", ".", "..") or seg.startswith("."):
            raise not_found
    return segments


def resolve_in_tree(root: Path, segments: list[str]) -> Path:
    """``root/segments...`` if it is a regular file that stays inside ``root`` (symlinks resolved); else 404."""
    base = root.resolve()
    try:
        target = base.joinpath(*segments).resolve(strict=True)
    except (OSError, RuntimeError):
        raise HttpError(HTTPStatus.NOT_FOUND, "not found") from None
    if not target.is_relative_to(base) or not target.is_file():
        raise HttpError(HTTPStatus.NOT_FOUND, "not found")
    return target


def file_response(path: Path) -> Response:
    """A file's bytes with its content type (unknown kinds as octet-stream)."""
    kind = _TYPES.get(path.suffix.lower()) or mimetypes.guess_type(path.name)[0] or "application/octet-stream"
    return Response(path.read_bytes(), kind, headers={"Cache-Control": "no-cache"})


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    app: App
    allowed_hosts: frozenset[str]


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    server_version = "decollage-studio"
    sys_version = ""
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args) -> None:  # noqa: A002 - the base class's name
        pass  # quiet: the CLI prints what people need

    def do_GET(self) -> None:  # noqa: N802 - http.server's naming
        self._dispatch("GET")

    def do_HEAD(self) -> None:  # noqa: N802
        self._dispatch("HEAD")

    def do_POST(self) -> None:  # noqa: N802
        self._dispatch("POST")

    def do_PUT(self) -> None:  # noqa: N802
        self._dispatch("PUT")

    def do_DELETE(self) -> None:  # noqa: N802
        self._dispatch("DELETE")

    def _dispatch(self, method: str) -> None:
        try:
            response = self._answer(method)
        except HttpError as exc:
            response = Response.json({"error": exc.one_line()}, exc.status)
        except DecollageError as exc:  # a bad edit, a recipe that stopped validating, a source error...
            response = Response.json({"error": exc.one_line()}, HTTPStatus.BAD_REQUEST)
        except (ConnectionError, TimeoutError):
            return
        except Exception as exc:  # a bug: say so briefly; the server keeps serving
            response = Response.json({"error": f"internal error {type(exc).__name__}: {exc} (please report it)"},
                                     HTTPStatus.INTERNAL_SERVER_ERROR)
        self._send(response, head=method == "HEAD")

    def _answer(self, method: str) -> Response:
        app = self.server.app
        host = (self.headers.get("Host") or "").lower()
        if host not in self.server.allowed_hosts:
            raise HttpError(HTTPStatus.FORBIDDEN, f"unexpected Host header {host!r}")
        split = urlsplit(self.path)
        if split.scheme or split.netloc:
            raise HttpError(HTTPStatus.NOT_FOUND, "not found")
        segments = clean_segments(split.path)
        path = "/" + "/".join(segments)
        request = Request(method, path, parse_qs(split.query))
        lookup = "GET" if method == "HEAD" else method
        handler = app.routes.get((lookup, path))
        if handler is None:
            for prefix, root in app.trees.items():
                if path.startswith(prefix) and lookup == "GET":
                    return file_response(resolve_in_tree(root, segments[prefix.count("/") - 1:]))
            if any(p == path for (_, p) in app.routes) or any(path.startswith(p) for p in app.trees):
                raise HttpError(HTTPStatus.METHOD_NOT_ALLOWED, f"{method} is not allowed here")
            raise HttpError(HTTPStatus.NOT_FOUND, "not found")
        if method == "POST":
            request.body = self._json_body()
        return handler(request)

    def _json_body(self) -> object:
        origin = self.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc.lower() not in self.server.allowed_hosts:
            raise HttpError(HTTPStatus.FORBIDDEN, f"cross-origin request from {origin!r}")
        if (self.headers.get("Content-Type") or "").split(";")[0].strip().lower() != "application/json":
            raise HttpError(HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "send the body as application/json")
        try:
            length = int(self.headers.get("Content-Length") or "0")
        except ValueError:
            raise HttpError(HTTPStatus.BAD_REQUEST, "bad Content-Length") from None
        if length < 0 or length > MAX_BODY:
            raise HttpError(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"the body is larger than {MAX_BODY} bytes")
        try:
            return json.loads(self.rfile.read(length) or b"null")
        except (ValueError, UnicodeDecodeError):
            raise HttpError(HTTPStatus.BAD_REQUEST, "the body is not JSON") from None

    def _send(self, response: Response, head: bool) -> None:
        try:
            self.send_response(response.status)
            headers = {
                "Content-Type": response.content_type,
                "Content-Length": str(len(response.body)),
                "X-Content-Type-Options": "nosniff",
                "X-Frame-Options": "DENY",
                "Referrer-Policy": "no-referrer",
                "Cross-Origin-Resource-Policy": "same-origin",
                "Content-Security-Policy": self.server.app.csp,
                **response.headers,
            }
            for key, value in headers.items():
                self.send_header(key, value)
            self.end_headers()
            if not head:
                self.wfile.write(response.body)
        except (ConnectionError, TimeoutError):
            pass


def allowed_hosts(host: str, port: int) -> frozenset[str]:
    """The ``Host`` header values the server answers: its own address, plus localhost names on loopback."""
    names = {host}
    if host in ("127.0.0.1", "localhost", "::1"):
        names |= {"127.0.0.1", "localhost", "[::1]"}
    return frozenset(f"{n}:{port}" for n in names)


def make_server(app: App, host: str = "127.0.0.1", port: int = 0) -> _Server:
    """Bind (``port`` 0 = any free port); raises StudioError naming the address when it is taken."""
    server_class = type("_Server6", (_Server,), {"address_family": socket.AF_INET6}) if ":" in host else _Server
    try:
        server = server_class((host, port), _Handler)
    except OSError as exc:
        raise StudioError(f"cannot listen on {host}:{port}: {exc.strerror or exc}",
                          hint="choose another --port (0 picks a free one)") from None
    server.app = app
    bound_port = server.server_address[1]
    server.allowed_hosts = allowed_hosts(host, bound_port)
    return server


def url_of(server: _Server) -> str:
    """``http://host:port/`` of a bound server (IPv6 hosts in brackets)."""
    host, port = server.server_address[:2]
    shown = f"[{host}]" if ":" in host else host
    return f"http://{shown}:{port}/"


def serve(server: _Server, on_ready: Callable[[str], None] = lambda url: None) -> None:
    """Serve until Ctrl-C or SIGTERM, then close the socket and the app; returns normally."""

    def _terminate(signum, frame) -> None:
        raise KeyboardInterrupt

    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminate)
    on_ready(url_of(server))
    try:
        server.serve_forever(poll_interval=0.2)
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
        server.app.close()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def port_is_free(host: str, port: int) -> bool:
    """Whether ``host:port`` can be bound now (tests and messages)."""
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as sock:
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True
