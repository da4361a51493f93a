"""The viewer and the API docs are served by the service itself, offline: every script, style and
module they load comes from the service (no CDN), and every import resolves."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from urllib.parse import urljoin

import httpx
import pytest

from tests.helpers.servers import running

IMPORT = re.compile(r"""(?:^|[;\s])(?:import|export)\s[^'"]*?from\s*['"]([^'"]+)['"]"""  # static
                    r"""|import\(\s*['"]([^'"]+)['"]\s*\)""", re.MULTILINE)  # dynamic
ASSET = re.compile(r"""(?:src|href)=["']([^"']+)["']|new Worker\(\s*['"]([^'"]+)['"]""")


@pytest.fixture(scope="module")
def url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with running(tmp_path_factory.mktemp("viewer")) as (url, _):
        yield url


def fetch_ok(url: str) -> httpx.Response:
    response = httpx.get(url)
    assert response.status_code == 200, f"{url}: {response.status_code}"
    return response


def test_root_redirects_to_the_viewer_and_the_viewer_page_answers(url: str) -> None:
    root = httpx.get(f"{url}/")
    assert root.status_code in (302, 307) and root.headers["location"] == "/viewer"
    assert httpx.head(f"{url}/viewer").status_code == 200
    page = fetch_ok(f"{url}/viewer")
    assert page.headers["content-type"].startswith("text/html")
    assert "quadsynth-client" in page.text and "importmap" in page.text


def test_every_module_the_viewer_loads_is_served_locally_and_its_imports_resolve(url: str) -> None:
    page = fetch_ok(f"{url}/viewer").text
    importmap = re.search(r'<script type="importmap">(.*?)</script>', page, re.S)
    assert importmap is not None
    imports = json.loads(importmap.group(1))["imports"]
    assert set(imports) == {"three", "@msgpack/msgpack", "quadsynth-client"}
    todo = [urljoin(f"{url}/viewer", a or b) for a, b in ASSET.findall(page)]
    todo += [url + path for path in imports.values()]
    seen: set[str] = set()
    while todo:
        asset = todo.pop()
        if asset in seen:
            continue
        seen.add(asset)
        assert asset.startswith(url), f"{asset}: loaded from outside the service"
        response = fetch_ok(asset)
        if asset.endswith(".js"):
            assert "javascript" in response.headers["content-type"], asset
            if "/vendor/" in asset:  # minified bundles: no imports of their own
                continue
            for a, b in IMPORT.findall(response.text):
                spec = a or b
                if spec.startswith(("/", ".")):
                    todo.append(urljoin(asset, spec))
                else:  # a bare name: only the page's import map can resolve it (not in a worker)
                    assert spec in imports and "worker" not in asset, f"{asset} imports {spec!r}"
                    todo.append(url + imports[spec])
        todo += [urljoin(asset, b) for _, b in ASSET.findall(response.text) if b]
    for module in ("/viewer/static/main.js", "/viewer/static/stream-worker.js", "/viewer/client/client.js",
                   "/vendor/three/three.bundle.min.js", "/vendor/msgpack/msgpack.min.js"):
        assert url + module in seen, f"{module} never reached"


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_api_docs_load_their_assets_from_the_service_not_a_cdn(url: str, page: str) -> None:
    html = fetch_ok(f"{url}{page}").text
    assert "cdn." not in html and "https://" not in html.replace("https://github.com", "")
    assets = [a for a, _ in ASSET.findall(html) if a]
    assert any(a.endswith(".js") for a in assets)
    for asset in assets:
        fetch_ok(urljoin(f"{url}{page}", asset))
    assert fetch_ok(f"{url}/openapi.json").json()["paths"].keys().isdisjoint({"/docs", "/redoc", "/viewer"})


def test_vendored_code_keeps_its_licences_and_pinned_versions(url: str) -> None:
    licences = {"three": "Permission is hereby granted", "msgpack": "Permission to use, copy",
                "swagger-ui": "Apache License", "redoc": "Permission is hereby granted"}
    for package, phrase in licences.items():
        assert phrase in fetch_ok(f"{url}/vendor/{package}/LICENSE").text, package
    versions = fetch_ok(f"{url}/vendor/VERSIONS").text
    assert all(re.search(rf"^{name} \d+\.\d+\.\d+", versions, re.M)
               for name in ("three", "@msgpack/msgpack", "swagger-ui-dist", "redoc"))
