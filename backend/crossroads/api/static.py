"""The studio page: frontend/dist (built by ``npm run build``) served at /, and the API docs
pages (/docs, /redoc) with their scripts from that build (dist/vendor).

Any path outside /api, /docs, /redoc and /openapi.json that is not a file of the build answers with
index.html, so the page's own links keep working on reload. Without a build the page says how
to make one.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI, HTTPException
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, Response

from crossroads.settings import frontend_dist_dir

MISSING_BUILD = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Crossroads studio</title></head>
<body style="font-family: sans-serif; max-width: 40em; margin: 3em auto">
<h1>Crossroads studio</h1>
<p>The studio page has not been built yet. Run <code>make serve</code> (it runs
<code>scripts/setup.sh</code>, which builds <code>frontend/</code> with npm), then reload.</p>
<p>The API is up: see <a href="/docs">/docs</a>.</p>
</body></html>
"""


VENDOR = "/vendor"  # the doc pages' scripts, copied into the build by frontend/vite.config.js


def mount_docs(app: FastAPI) -> None:
    """/docs (Swagger UI) and /redoc (ReDoc), their scripts served from the studio's build rather
    than a CDN, so they work offline. Create the app with ``docs_url=None, redoc_url=None``."""
    title = f"{app.title} API"

    @app.get("/docs", include_in_schema=False)
    def swagger_ui() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=app.openapi_url or "/openapi.json", title=title,
            swagger_js_url=f"{VENDOR}/swagger-ui/swagger-ui-bundle.js",
            swagger_css_url=f"{VENDOR}/swagger-ui/swagger-ui.css",
            swagger_favicon_url=f"{VENDOR}/swagger-ui/favicon-32x32.png")

    @app.get("/redoc", include_in_schema=False)
    def redoc() -> HTMLResponse:
        return get_redoc_html(openapi_url=app.openapi_url or "/openapi.json", title=title,
                              redoc_js_url=f"{VENDOR}/redoc/redoc.standalone.js",
                              redoc_favicon_url=f"{VENDOR}/swagger-ui/favicon-32x32.png",
                              with_google_fonts=False)


def mount_frontend(app: FastAPI, dist: Path | None = None) -> None:
    """Add the catch-all route serving the built page; call it after every API router."""
    root = (dist or frontend_dist_dir()).resolve()

    @app.get("/{path:path}", include_in_schema=False)
    def frontend(path: str) -> Response:
        if path == "api" or path.startswith("api/"):
            raise HTTPException(status_code=404, detail="Not Found")
        index = root / "index.html"
        if not index.is_file():
            return HTMLResponse(MISSING_BUILD, status_code=503)
        if path:
            candidate = (root / path).resolve()
            if candidate.is_relative_to(root) and candidate.is_file():
                return FileResponse(candidate)
        return FileResponse(index, headers={"Cache-Control": "no-cache"})
