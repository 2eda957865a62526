"""The studio page: frontend/dist (built by ``npm run build``) served at /.

Any path outside /api, /docs and /openapi.json that is not a file of the build answers with
index.html, so the page's own links keep working on reload. Without a build the page says how
to make one.
"""

from __future__ import annotations

import os
from pathlib import Path

from fastapi import FastAPI, HTTPException
from fastapi.responses import FileResponse, HTMLResponse, Response

REPO_DIST = Path(__file__).resolve().parents[3] / "frontend" / "dist"  # <repo>/backend/crossroads/api

MISSING_BUILD = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Crossroads studio</title></head>
<body style="font-family: sans-serif; max-width: 40em; margin: 3em auto">
<h1>Crossroads studio</h1>
<p>The studio page has not been built yet. Run <code>make serve</code> (it runs
<code>scripts/setup.sh</code>, which builds <code>frontend/</code> with npm), then reload.</p>
<p>The API is up: see <a href="/docs">/docs</a>.</p>
</body></html>
"""


def dist_dir() -> Path:
    configured = os.environ.get("CROSSROADS_FRONTEND_DIST")
    return Path(configured) if configured else REPO_DIST


def mount_frontend(app: FastAPI, dist: Path | None = None) -> None:
    """Add the catch-all route serving the built page; call it after every API router."""
    root = (dist or dist_dir()).resolve()

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
