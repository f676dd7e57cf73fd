"""The studio server's safety rules: only its own files, the build folder's and its API; nothing else."""

from __future__ import annotations

import http.client
import json
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from studio.gallery import gallery_app
from studio.http import clean_segments, HttpError
from tests.studio.conftest import serving

TRAVERSALS = [
    "/../../etc/passwd",
    "/../../../../../../etc/passwd",
    "/%2e%2e/%2e%2e/etc/passwd",
    "/%2E%2E/%2E%2E/etc/passwd",
    "/..%2f..%2fetc%2fpasswd",
    "/%2e%2e%2f%2e%2e%2fetc%2fpasswd",
    "/%252e%252e/%252e%252e/etc/passwd",
    "/files/../../../../etc/passwd",
    "/files/..%2f..%2f..%2f..%2fetc%2fpasswd",
    "/files/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
    "/files/%252e%252e%252f%252e%252e%252fetc%252fpasswd",
    "/files/..\\..\\..\\etc\\passwd",
    "/files/%5c..%5c..%5cetc%5cpasswd",
    "/static/../../../../etc/passwd",
    "/static/%2e%2e/%2e%2e/pages.py",
    "/static/..%2fpages.py",
    "/vendor/three/build/../../../../../../etc/passwd",
    "/vendor/three/build/..%2f..%2fpackage.json",
    "//etc/passwd",
    "/files//etc/passwd",
    "/files/%2fetc%2fpasswd",
    "/files/secret.txt%00.png",
    "/files/./manifest.json",
    "/files/.decollage/anything",
    "/files/outside_link.txt",
    "/etc/passwd",
    "/api/../files/manifest.json",
    "/files/%ff%fe",
    "/files/%c0%ae%c0%ae/%c0%ae%c0%ae/etc/passwd",
]


@pytest.fixture
def build_dir(tmp_path) -> Path:
    out = tmp_path / "build"
    (out / ".decollage").mkdir(parents=True)
    (out / ".decollage" / "anything").write_text("cache record")
    (out / "manifest.json").write_text(json.dumps({"format": 1, "assets": [], "summary": {}}))
    (out / "asset.glb").write_bytes(b"glTF-not-really")
    (tmp_path / "secret.txt").write_text("outside the build folder")
    (out / "outside_link.txt").symlink_to(tmp_path / "secret.txt")
    return out


def _raw(url: str, method: str, path: str, headers: dict | None = None, body: bytes | None = None):
    """Send ``path`` exactly as given (no client-side normalisation); returns (status, body bytes)."""
    parts = urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=10)
    try:
        conn.putrequest(method, path, skip_host=headers is not None and "Host" in headers, skip_accept_encoding=True)
        for key, value in (headers or {}).items():
            conn.putheader(key, value)
        if body is not None:
            conn.putheader("Content-Length", str(len(body)))
        conn.endheaders(body)
        response = conn.getresponse()
        return response.status, response.read()
    finally:
        conn.close()


def test_traversal_and_hidden_paths_are_refused(build_dir):
    with serving(gallery_app(build_dir)) as url:
        assert _raw(url, "GET", "/files/manifest.json")[0] == 200
        assert _raw(url, "GET", "/files/asset.glb")[0] == 200
        for path in TRAVERSALS:
            status, body = _raw(url, "GET", path)
            assert status in (403, 404), (path, status)
            assert b"root:" not in body and b"outside the build folder" not in body and b"cache record" not in body


def test_unknown_routes_and_methods(build_dir):
    with serving(gallery_app(build_dir)) as url:
        for path in ("/api/nope", "/admin", "/files/", "/files/missing.glb", "/static/nope.js", "/favicon.ico"):
            assert _raw(url, "GET", path)[0] == 404, path
        assert _raw(url, "POST", "/api/manifest", {"Content-Type": "application/json"}, b"{}")[0] == 405
        assert _raw(url, "DELETE", "/files/asset.glb")[0] == 405
        assert _raw(url, "PUT", "/")[0] == 405
        status, body = _raw(url, "GET", "/api/manifest")
        assert status == 200 and json.loads(body)["studio"]["folder"] == "build"
        assert _raw(url, "HEAD", "/files/asset.glb")[0] == 200


def test_host_header_must_name_the_server(build_dir):
    """A page on another site that resolves its own name to 127.0.0.1 (DNS rebinding) is refused."""
    with serving(gallery_app(build_dir)) as url:
        port = urlsplit(url).port
        assert _raw(url, "GET", "/", {"Host": "evil.example:%d" % port})[0] == 403
        assert _raw(url, "GET", "/api/manifest", {"Host": "evil.example"})[0] == 403
        assert _raw(url, "GET", "/", {"Host": f"localhost:{port}"})[0] == 200


def test_pages_carry_a_strict_content_security_policy(build_dir):
    with serving(gallery_app(build_dir)) as url:
        parts = urlsplit(url)
        conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=10)
        conn.request("GET", "/")
        response = conn.getresponse()
        page = response.read().decode()
        csp = response.getheader("Content-Security-Policy")
        conn.close()
    # WebAssembly may compile (the meshopt decoder of compressed GLBs); no eval, no inline scripts
    assert "script-src 'self' 'wasm-unsafe-eval' 'sha256-" in csp and "object-src 'none'" in csp
    assert "unsafe" not in csp.replace("'wasm-unsafe-eval'", "")
    assert response.getheader("X-Content-Type-Options") == "nosniff"
    assert "http://" not in page and "https://" not in page  # nothing from a CDN


def test_clean_segments_rules():
    assert clean_segments("/") == []
    assert clean_segments("/files/a%20b.glb") == ["files", "a b.glb"]
    for bad in ("files/x", "/a/../b", "/a/%2e%2e/b", "/a//b", "/.git/config", "/a/%252e%252e/b", "/a\\b", "/a%00b"):
        with pytest.raises(HttpError):
            clean_segments(bad)


def test_a_missing_or_foreign_folder_is_refused_at_start(tmp_path):
    from core.errors import StudioError

    with pytest.raises(StudioError, match="no manifest.json"):
        gallery_app(tmp_path)
    (tmp_path / "manifest.json").write_text("[1, 2]")
    with pytest.raises(StudioError, match="not a decollage manifest"):
        gallery_app(tmp_path)
