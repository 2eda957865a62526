"""The API docs pages render offline: /docs (Swagger UI) and /redoc (ReDoc) load their scripts
from the studio's own build, and the browser here may reach nothing but the server."""

from __future__ import annotations

from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest

pytestmark = pytest.mark.slow

REDOC_LOGO = "https://cdn.redoc.ly/redoc/logo-mini.svg"


def _offline_page(browser: Any, studio_url: str) -> tuple[Any, list[str]]:
    """A page whose requests beyond the studio's server fail (as without a network); answers it
    and the list of the URLs it tried out there."""
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    ours = urlsplit(studio_url).netloc
    elsewhere: list[str] = []

    def route(r: Any) -> None:
        if urlsplit(r.request.url).netloc == ours:
            r.continue_()
        else:
            elsewhere.append(r.request.url)
            r.abort()

    page.route("**/*", route)
    return page, elsewhere


def test_swagger_ui_and_redoc_render_offline(studio_url: str, browser: Any, artifacts: Path) -> None:
    page, elsewhere = _offline_page(browser, studio_url)
    page.goto(studio_url + "/docs")
    page.wait_for_selector(".swagger-ui .opblock-summary-path[data-path='/api/batches']", timeout=30_000)
    assert page.locator(".swagger-ui .opblock").count() > 10
    page.screenshot(path=str(artifacts / "16-docs-offline.png"))

    page.goto(studio_url + "/redoc")
    page.wait_for_selector(".api-content h1", timeout=30_000)
    assert "Crossroads" in page.inner_text("body")
    page.screenshot(path=str(artifacts / "17-redoc-offline.png"))
    # only ReDoc's attribution logo is fetched from its CDN; it hides itself when that fails
    assert all(url == REDOC_LOGO for url in elsewhere), elsewhere
    page.close()
