"""Uploading a SUMO network: POST /intersections/upload (multipart, field ``file``).

Checks, in order, before anything is stored: the size limit (the Content-Length header, then the
bytes actually read); no compressed file; UTF-8 text; no DOCTYPE or ENTITY declaration anywhere in
the raw bytes (entity expansion and external entities need one, so refusing them outright
defuses both without a hardened parser); well-formed XML; a ``<net>`` root; and finally the
junction reader (:func:`crossroads.network.junction.read_junction`), whose message a junction it
cannot handle gets back as the 422. Only then is the file moved into place as
``<data_dir>/uploads/<sha256>.net.xml`` (atomically: nothing half-made is ever visible there),
with ``<sha256>.json`` beside it keeping the name it was uploaded under (GET /intersections/uploads).

The multipart body is parsed with the standard library (python-multipart is not a dependency).
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import os
import re
import tempfile
import xml.etree.ElementTree as ET
from email import policy
from email.parser import BytesParser
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response

from crossroads.api.body_limit import reads_own_body
from crossroads.api.deps import OptionsDep, SettingsDep
from crossroads.api.params import Page, paging
from crossroads.scenario.network_checks import program_json, uploaded_name
from crossroads.api.routes.intersections import (
    JunctionId,
    choices_of,
    geometry_with_program,
    internal_lanes_of,
    junction_of,
    paths_of,
    signal_links,
)
from crossroads.constants import RHO_BEZIER
from crossroads.network.export import junction_geometry
from crossroads.network.junction import JunctionError, read_junction
from crossroads.network.road import Junction
from crossroads.intersections.resolve import open_junction

router = APIRouter(prefix="/intersections", tags=["intersections"])

UPLOADS = "uploads"
FIELD = "file"
MULTIPART_SLACK_BYTES = 64 * 1024  # [bytes] room for the multipart framing around the file
_DECLARATION = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
_ENCODING = re.compile(rb"^(?:\xef\xbb\xbf)?\s*<\?xml[^>]*?encoding\s*=\s*[\"']([^\"']*)[\"']")
_GZIP_MAGIC = b"\x1f\x8b"
_SHA256 = re.compile(r"^[0-9a-f]{64}$")


def _bad(message: str, field: str = FIELD, code: int = 422) -> HTTPException:
    return HTTPException(status_code=code, detail=[{"loc": ["body", field], "msg": message,
                                                    "type": "value_error"}])


async def _read_body(request: Request, limit: int) -> bytes:
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise _bad(f"the upload is {int(declared)} bytes, above the limit of {limit} bytes", code=413)
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise _bad(f"the upload is above the limit of {limit} bytes", code=413)
        chunks.append(chunk)
    return b"".join(chunks)


def _file_part(content_type: str, body: bytes) -> tuple[str, bytes]:
    """The filename and bytes of the multipart part named ``file``."""
    message = BytesParser(policy=policy.HTTP).parsebytes(
        f"Content-Type: {content_type}\r\nMIME-Version: 1.0\r\n\r\n".encode("latin-1") + body)
    if not message.is_multipart():
        raise _bad("the multipart body cannot be read")
    for part in message.iter_parts():
        if part.get_param("name", header="content-disposition") == FIELD:
            payload = part.get_payload(decode=True)
            return part.get_filename() or "", payload if isinstance(payload, bytes) else b""
    raise _bad("missing: send the network as the multipart field 'file'")


def check_net_bytes(data: bytes, filename: str, limit: int) -> None:
    """Every check that needs no parser's trust, then XML and a <net> root (422/413 on failure)."""
    if not filename.endswith(".net.xml"):
        raise _bad(f"the file must be a SUMO network ending in .net.xml, got {filename or 'no name'!r}")
    if len(data) > limit:
        raise _bad(f"the file is {len(data)} bytes, above the limit of {limit} bytes", code=413)
    if not data.strip():
        raise _bad("the file is empty")
    if data.startswith(_GZIP_MAGIC):
        raise _bad("compressed networks are not accepted; upload the plain .net.xml")
    # UTF-8 only, and no NUL: UTF-16/32 would hide a declaration from the byte check below.
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _bad(f"the file is not UTF-8 text (byte {exc.start})") from None
    if b"\x00" in data:
        raise _bad("the file is not UTF-8 text (it holds NUL bytes)")
    declared = _ENCODING.match(data)
    if declared and declared.group(1).lower().replace(b"_", b"-") not in (b"utf-8", b"utf8", b"us-ascii", b"ascii"):
        raise _bad(f"the file declares encoding {declared.group(1).decode()!r}; only UTF-8 is accepted")
    found = _DECLARATION.search(data)
    if found:
        raise _bad(f"XML {found.group(1).decode().upper()} declarations are not accepted "
                   "(SUMO networks have none)")
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise _bad(f"not well-formed XML: {exc}") from None
    if root.tag != "net":
        raise _bad(f"not a SUMO network: the root element is <{root.tag}>, not <net>")


def uploads_dir(data_dir: Path) -> Path:
    return data_dir / UPLOADS


@router.post(
    "/upload",
    openapi_extra={"requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
        "type": "object", "required": [FIELD],
        "properties": {FIELD: {"type": "string", "format": "binary",
                               "description": "a SUMO network (.net.xml)"}}}}}}},
    responses={413: {"description": "the file is above the size limit"},
               422: {"description": "not a SUMO network, an XML declaration, or a junction the "
                                    "reader cannot handle"}},
)
@reads_own_body  # its limit is the upload's (options.upload_max_bytes), not the API's JSON limit
async def upload_network(request: Request, settings: SettingsDep, options: OptionsDep) -> dict[str, Any]:
    """Upload a SUMO network; its signalised junction is read and stored. Answers like
    GET /intersections/{name}, with the ``net`` to use in a scenario's ``intersection``."""
    content_type = request.headers.get("content-type", "")
    if not content_type.lower().startswith("multipart/form-data"):
        raise _bad("send multipart/form-data with the network in the field 'file'")
    body = await _read_body(request, options.upload_max_bytes + MULTIPART_SLACK_BYTES)
    filename, data = _file_part(content_type, body)
    filename = Path(filename.replace("\\", "/")).name  # never a path
    check_net_bytes(data, filename, options.upload_max_bytes)
    digest = hashlib.sha256(data).hexdigest()
    target_dir = uploads_dir(settings.data_dir)
    # Parsing a large net takes a while: off the event loop.
    return await asyncio.to_thread(_read_and_store, data, digest, filename, target_dir)


def _read_and_store(data: bytes, digest: str, filename: str, target_dir: Path) -> dict[str, Any]:
    target_dir.mkdir(parents=True, exist_ok=True)
    final = target_dir / f"{digest}.net.xml"
    fd, tmp_name = tempfile.mkstemp(prefix=".upload-", suffix=".net.xml", dir=target_dir)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        try:
            junction = read_junction(tmp)
        except JunctionError as exc:
            raise _bad(str(exc).replace(str(tmp), filename)) from None
        geometry = {**junction_geometry(junction), "signal_links": signal_links(junction)}
        lanes = internal_lanes_of(junction, filename)
        os.replace(tmp, final)
    finally:
        tmp.unlink(missing_ok=True)
    _write_name(target_dir, digest, filename)
    return {"name": filename, "id": digest, "net": f"{UPLOADS}/{final.name}", "size_bytes": len(data),
            "junction": junction.id, **geometry, "program": program_json(final, junction.tl_id),
            **choices_of(open_junction(final), filename),
            "internal_lanes": {"max_m": lanes["max_m"], "warning": lanes["warning"]}}


def _write_name(target_dir: Path, digest: str, filename: str) -> None:
    """Remember the name the network was uploaded under (the first one), for the catalogue of
    uploads; written atomically beside the network."""
    meta = target_dir / f"{digest}.json"
    if meta.is_file():
        return
    fd, tmp_name = tempfile.mkstemp(prefix=".upload-", suffix=".json", dir=target_dir)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        json.dump({"name": filename}, f)
    os.replace(tmp_name, meta)


def _uploaded_name(target_dir: Path, digest: str) -> str:
    return uploaded_name(target_dir / f"{digest}.net.xml") or f"{digest[:12]}.net.xml"


def _uploaded_path(digest: str, data_dir: Path) -> Path:
    """The stored network of ``digest``; 422 for a malformed digest, 404 for an unknown one."""
    if not _SHA256.match(digest):
        raise HTTPException(status_code=422, detail=[{"loc": ["path", "digest"],
                                                      "msg": "a sha256 in hex (64 characters)",
                                                      "type": "value_error"}])
    path = uploads_dir(data_dir) / f"{digest}.net.xml"
    if not path.is_file():
        raise HTTPException(status_code=404, detail=f"no uploaded network {digest}")
    return path


@router.get("/uploads")
def list_uploads(settings: SettingsDep, response: Response,
                 page: Annotated[Page, Depends(paging(100, 1000))]) -> list[dict[str, Any]]:
    """The uploaded networks, oldest first: ``id`` (sha256), the ``name`` it was uploaded under,
    and the ``net`` to use in a scenario's ``intersection``."""
    directory = uploads_dir(settings.data_dir)
    if not directory.is_dir():
        return page.slice([], response)
    files = [p for p in directory.glob("*.net.xml") if _SHA256.match(p.name.removesuffix(".net.xml"))]
    files.sort(key=lambda p: p.stat().st_mtime_ns)
    return [{"id": (digest := p.name.removesuffix(".net.xml")), "name": _uploaded_name(directory, digest),
             "net": f"{UPLOADS}/{p.name}", "size_bytes": p.stat().st_size} for p in page.slice(files, response)]


def _uploaded_junction(digest: str, data_dir: Path, junction: str | None) -> tuple[Path, str, Junction]:
    """The stored network of ``digest``, the name it was uploaded under, and its junction
    ``junction`` (None: the default; a 422 naming ``junction`` when it has no such one)."""
    path = _uploaded_path(digest, data_dir)
    name = _uploaded_name(path.parent, digest)
    return path, name, junction_of(path, junction, name)


@router.get("/uploads/{digest}")
def uploaded_geometry(digest: str, settings: SettingsDep, junction: JunctionId = None) -> dict[str, Any]:
    """The geometry of an uploaded network (by the sha256 POST /intersections/upload gave): of its
    default junction, or of ``junction`` (one of the answer's ``junctions``)."""
    path, name, chosen = _uploaded_junction(digest, settings.data_dir, junction)
    return {"name": name, "id": digest, "net": f"{UPLOADS}/{path.name}",
            "size_bytes": path.stat().st_size, "junction": chosen.id, **geometry_with_program(chosen, name)}


@router.get("/uploads/{digest}/internal-lanes")
def uploaded_internal_lanes(digest: str, settings: SettingsDep, junction: JunctionId = None) -> dict[str, Any]:
    """How far SUMO's internal lanes of an uploaded network run from the candidate paths."""
    _, name, chosen = _uploaded_junction(digest, settings.data_dir, junction)
    return internal_lanes_of(chosen, name)


@router.get("/uploads/{digest}/paths")
def uploaded_paths(
    digest: str, settings: SettingsDep,
    task: Literal["left", "straight", "right"],
    junction: JunctionId = None,
    approach: Annotated[str | None, Query(max_length=200, description="incoming edge id; default: from the south")] = None,
    rho: Annotated[float | None, Query(gt=0.0, lt=1.0, description=(
        f"ρ of the Bezier construction for every path (the paper: {RHO_BEZIER}); default: chosen "
        "per path within the ego's steering limit"))] = None,
) -> list[dict[str, Any]]:
    """The candidate paths of a task on an uploaded network."""
    return paths_of(_uploaded_junction(digest, settings.data_dir, junction)[2], task, approach, rho)
