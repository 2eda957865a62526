"""Uploading an ONNX policy: POST /policies/upload (multipart: ``file``, ``name``, ``card``).

Checks, in order, before anything is stored: the size limit (the Content-Length header, then the
bytes actually read); the name (letters, digits, ``_ . -``; not a built-in, shipped or uploaded
policy's); the card (short text); then the model: parsed as protobuf and checked by
``onnx.checker``, its input and outputs matched against the IDC state layout and the action, and a
trial run by onnxruntime (:class:`crossroads.evaluation.onnx_policy.OnnxNetworks`). Nothing is ever
unpickled. Only then is it stored as ``<data_dir>/policies/<name>.onnx`` (atomically) with
``<name>.card.json`` beside it (the card, the sha256, the signature found), and listed by
GET /policies as ``<name>`` and ``<name>+shield`` beside the shipped checkpoints, so batches and
live runs take it by name. DELETE /policies/uploads/{name} removes it; the batches that ran it keep
their results (the store keeps its hash and card).

The multipart body is parsed with the standard library (python-multipart is not a dependency).
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import os
import re
import tempfile
import threading
from datetime import UTC, datetime
from email import policy as email_policy
from email.parser import BytesParser
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Request, Response, status
from fastapi import Path as PathParam
from pydantic import BaseModel, Field

from crossroads.api.body_limit import reads_own_body
from crossroads.api.deps import OptionsDep, SettingsDep
from crossroads.api.schemas import PolicyPublic
from crossroads.evaluation.onnx_policy import OnnxError, OnnxNetworks
from crossroads.policy.ref import SHIELD_SUFFIX, PolicyRef

router = APIRouter(prefix="/policies", tags=["policies"])

UPLOADS = "policies"  # <data_dir>/policies
MAX_POLICY_BYTES = 64 * 2**20  # [bytes] largest ONNX policy accepted (the shipped APG: 2.4 MB)
MULTIPART_SLACK_BYTES = 64 * 1024  # [bytes] room for the framing and the name and card fields
MAX_CARD_CHARS = 2000
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$"
_NAME = re.compile(NAME_PATTERN)
_WRITE = threading.Lock()  # name check and write, one upload at a time


class PolicyUpload(BaseModel):
    """An uploaded ONNX policy."""

    name: str = Field(description="what POST /batches takes as `policy` (and `<name>+shield`)")
    sha256: str = Field(description="sha256 of the ONNX file, hex")
    size_bytes: int
    card: str = Field(description="the short description given with the upload")
    uploaded_at: str
    filename: str = Field(description="the file name it was uploaded under")
    signature: dict[str, Any] = Field(description="input, outputs and state width found in the graph")


def policy_uploads_dir(data_dir: Path) -> Path:
    return data_dir / UPLOADS


def _bad(field: str, message: str, code: int = status.HTTP_422_UNPROCESSABLE_CONTENT) -> HTTPException:
    return HTTPException(status_code=code, detail=[{"loc": ["body", field], "msg": message, "type": "value_error"}])


def _read_card(path: Path) -> dict[str, Any] | None:
    try:
        card = json.loads(path.with_name(path.stem + ".card.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return card if isinstance(card, dict) else None


def uploaded(data_dir: Path) -> list[PolicyUpload]:
    """The uploaded policies with a readable card, by name."""
    directory = policy_uploads_dir(data_dir)
    found = []
    for path in sorted(directory.glob("*.onnx")) if directory.is_dir() else []:
        card = _read_card(path)
        if card is None or not _NAME.match(path.stem):
            continue
        try:
            found.append(PolicyUpload.model_validate(card))
        except ValueError:
            continue
    return found


def uploaded_policies(data_dir: Path) -> list[PolicyPublic]:
    """GET /policies entries of the uploads: each plain, then with the safety shield."""
    return [PolicyPublic(name=up.name + (SHIELD_SUFFIX if shield else ""), kind="onnx", file=f"{up.name}.onnx",
                         shield=shield, size_bytes=up.size_bytes, sha256=up.sha256,
                         card={"card": up.card, "uploaded_at": up.uploaded_at, "signature": up.signature})
            for up in uploaded(data_dir) for shield in (False, True)]


def uploaded_ref(policy: PolicyPublic, data_dir: Path) -> str:
    """The policy reference of an uploaded policy listed by :func:`uploaded_policies`."""
    return str(PolicyRef("onnx", str(policy_uploads_dir(data_dir) / (policy.file or "")), policy.shield))


async def _read_body(request: Request, limit: int) -> bytes:
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise _bad("file", f"the upload is {int(declared)} bytes, above the limit of {limit} bytes",
                   status.HTTP_413_CONTENT_TOO_LARGE)
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise _bad("file", f"the upload is above the limit of {limit} bytes", status.HTTP_413_CONTENT_TOO_LARGE)
        chunks.append(chunk)
    return b"".join(chunks)


def _fields(content_type: str, body: bytes) -> dict[str, tuple[str, bytes]]:
    """The multipart fields by name: (filename, bytes)."""
    message = BytesParser(policy=email_policy.HTTP).parsebytes(
        f"Content-Type: {content_type}\r\nMIME-Version: 1.0\r\n\r\n".encode("latin-1") + body)
    if not message.is_multipart():
        raise _bad("file", "the multipart body cannot be read")
    out: dict[str, tuple[str, bytes]] = {}
    for part in message.iter_parts():
        name = part.get_param("name", header="content-disposition")
        if isinstance(name, str) and name not in out:
            payload = part.get_payload(decode=True)
            out[name] = (part.get_filename() or "", payload if isinstance(payload, bytes) else b"")
    return out


def _text(fields: dict[str, tuple[str, bytes]], field: str) -> str:
    if field not in fields:
        raise _bad(field, f"missing: send the policy's {field} as the multipart field {field!r}")
    try:
        return fields[field][1].decode("utf-8").strip()
    except UnicodeDecodeError:
        raise _bad(field, "not UTF-8 text") from None


def _taken(name: str, data_dir: Path, models: Path | None) -> bool:
    from crossroads.api.routes.policies import available_policies, models_dir

    return any(p.name in (name, name + SHIELD_SUFFIX) for p in available_policies(models_dir(models))) or (
        policy_uploads_dir(data_dir) / f"{name}.onnx").exists()


def _write_atomically(directory: Path, final: Path, data: bytes) -> None:
    fd, tmp_name = tempfile.mkstemp(prefix=".upload-", suffix=final.suffix, dir=directory)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp_name, final)
    finally:
        Path(tmp_name).unlink(missing_ok=True)


def _check_and_store(data: bytes, name: str, card: str, filename: str, data_dir: Path,
                     models: Path | None) -> PolicyPublic:
    try:
        signature = OnnxNetworks(data, source=filename or "the file").signature
    except OnnxError as exc:
        raise _bad("file", str(exc)) from None
    record = PolicyUpload(name=name, sha256=hashlib.sha256(data).hexdigest(), size_bytes=len(data), card=card,
                          uploaded_at=datetime.now(UTC).isoformat(timespec="seconds"), filename=filename,
                          signature=signature.to_json())
    directory = policy_uploads_dir(data_dir)
    with _WRITE:
        if _taken(name, data_dir, models):
            raise _bad("name", f"a policy named {name!r} exists; choose another name", status.HTTP_409_CONFLICT)
        directory.mkdir(parents=True, exist_ok=True)
        # the card first: a listed model always has its card
        _write_atomically(directory, directory / f"{name}.card.json", record.model_dump_json().encode("utf-8"))
        _write_atomically(directory, directory / f"{name}.onnx", data)
    return next(p for p in uploaded_policies(data_dir) if p.name == name)


@router.post(
    "/upload", status_code=status.HTTP_201_CREATED,
    openapi_extra={"requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
        "type": "object", "required": ["file", "name", "card"],
        "properties": {
            "file": {"type": "string", "format": "binary", "description": "an ONNX policy (.onnx)"},
            "name": {"type": "string", "pattern": NAME_PATTERN, "description": "its name in the studio"},
            "card": {"type": "string", "maxLength": MAX_CARD_CHARS,
                     "description": "a short card: what it is, how it was trained"}}}}}}},
    responses={409: {"description": "a policy of that name exists"},
               413: {"description": "the file is above the size limit"},
               422: {"description": "not an ONNX policy of the state layout, or a bad name or card"}},
)
@reads_own_body  # its limit is the policy upload's, not the API's JSON limit
async def upload_policy(request: Request, settings: SettingsDep, options: OptionsDep) -> PolicyPublic:
    """Upload an ONNX policy (the state → action contract of docs/guide/own-driver.md); it is checked,
    stored and listed by GET /policies (with ``<name>+shield``), its sha256 beside it."""
    content_type = request.headers.get("content-type", "")
    if not content_type.lower().startswith("multipart/form-data"):
        raise _bad("file", "send multipart/form-data with the model in 'file', its 'name' and 'card'")
    body = await _read_body(request, MAX_POLICY_BYTES + MULTIPART_SLACK_BYTES)
    fields = _fields(content_type, body)
    if "file" not in fields:
        raise _bad("file", "missing: send the model as the multipart field 'file'")
    filename, data = fields["file"]
    filename = Path(filename.replace("\\", "/")).name  # never a path
    if len(data) > MAX_POLICY_BYTES:
        raise _bad("file", f"the file is {len(data)} bytes, above the limit of {MAX_POLICY_BYTES} bytes",
                   status.HTTP_413_CONTENT_TOO_LARGE)
    if not data:
        raise _bad("file", "the file is empty")
    name, card = _text(fields, "name"), _text(fields, "card")
    if not _NAME.match(name):
        raise _bad("name", "1 to 64 letters, digits, '_', '.' or '-', starting with a letter or digit")
    if not card:
        raise _bad("card", "give a short card: what the policy is and how it was made")
    if len(card) > MAX_CARD_CHARS:
        raise _bad("card", f"{len(card)} characters; a card has at most {MAX_CARD_CHARS}")
    # onnx.checker, the session and its trial run take a moment: off the event loop
    return await asyncio.to_thread(_check_and_store, data, name, card, filename, settings.data_dir,
                                   options.models_dir)


UploadName = Annotated[str, PathParam(pattern=NAME_PATTERN, max_length=64, description="an uploaded policy's name")]


@router.get("/uploads")
def list_policy_uploads(settings: SettingsDep) -> list[PolicyUpload]:
    """The uploaded ONNX policies, by name, with their card, sha256 and signature."""
    return uploaded(settings.data_dir)


@router.delete("/uploads/{name}", status_code=status.HTTP_204_NO_CONTENT,
               responses={404: {"description": "no uploaded policy of that name"}})
def delete_policy_upload(name: UploadName, settings: SettingsDep) -> Response:
    """Remove an uploaded policy (batches that ran it keep their results)."""
    directory = policy_uploads_dir(settings.data_dir)
    model = directory / f"{name}.onnx"
    with _WRITE:
        if not model.is_file():
            raise HTTPException(status_code=404, detail=f"no uploaded policy {name!r}")
        model.unlink()
        model.with_name(f"{name}.card.json").unlink(missing_ok=True)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
