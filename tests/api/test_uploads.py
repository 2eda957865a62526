"""Uploading a SUMO network: checked (size, XML declarations, XML, a <net>, a junction the reader
handles) before anything is stored; a good one answers with its geometry and can be used in a
scenario."""

from __future__ import annotations

import gzip
import hashlib
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from support import SUMO_CROSS_NET, sumo_example

from .conftest import UPLOAD_LIMIT_BYTES  # noqa: TID252

BILLION_LAUGHS = b"""<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
]>
<net>&lol3;</net>
"""
EXTERNAL_ENTITY = b'<?xml version="1.0"?>\n<!doctype net [<!ENTITY x SYSTEM "file:///etc/passwd">]><net>&x;</net>'


def _upload(client: TestClient, data: bytes, filename: str = "mine.net.xml") -> Any:
    return client.post("/api/intersections/upload", files={"file": (filename, data, "application/xml")})


def _stored(data_dir: Path) -> list[str]:
    uploads = data_dir / "uploads"
    return sorted(p.name for p in uploads.iterdir()) if uploads.is_dir() else []


@pytest.fixture(scope="module")
def no_light_net(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """A plain crossing of two roads with a priority junction: no traffic light (netconvert)."""
    tmp = tmp_path_factory.mktemp("no-light")
    (tmp / "n.nod.xml").write_text(
        '<nodes><node id="C" x="0" y="0" type="priority"/><node id="N" x="0" y="100"/>'
        '<node id="S" x="0" y="-100"/><node id="E" x="100" y="0"/><node id="W" x="-100" y="0"/></nodes>')
    edges = "".join(f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="1" speed="13.9"/>'
                    for o in "NSEW" for a, b in ((o, "C"), ("C", o)))
    (tmp / "e.edg.xml").write_text(f"<edges>{edges}</edges>")
    netconvert = Path(sys.executable).with_name("netconvert")
    subprocess.run([str(netconvert), "--node-files", str(tmp / "n.nod.xml"), "--edge-files",
                    str(tmp / "e.edg.xml"), "-o", str(tmp / "plain.net.xml"), "--no-warnings"],
                   check=True, capture_output=True, timeout=60)
    return (tmp / "plain.net.xml").read_bytes()


def test_good_network(client: TestClient, data_dir: Path, tiny_scenario: dict[str, Any]) -> None:
    data = sumo_example(SUMO_CROSS_NET).read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    response = _upload(client, data, "cross.net.xml")
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["id"] == digest and body["net"] == f"uploads/{digest}.net.xml" and body["name"] == "cross.net.xml"
    assert body["polygon"] and len(body["approaches"]) >= 3
    assert f"{digest}.net.xml" in _stored(data_dir)
    assert (data_dir / body["net"]).read_bytes() == data

    assert _upload(client, data, "again.net.xml").json()["id"] == digest, "same bytes: same file"
    geometry = client.get(f"/api/intersections/uploads/{digest}").json()
    assert geometry["approaches"] == body["approaches"]
    assert client.get(f"/api/intersections/uploads/{'0' * 64}").status_code == 404
    assert client.get("/api/intersections/uploads/../../etc").status_code in (404, 422)

    scenario = {**tiny_scenario, "name": "on-upload", "intersection": {"net": body["net"]}}
    created = client.post("/api/scenarios", json=scenario)
    assert created.status_code == 201, created.text


@pytest.mark.parametrize(("data", "filename", "status", "words"), [
    (b"x" * (UPLOAD_LIMIT_BYTES + 1), "big.net.xml", 413, "limit"),             # too big
    (b"x" * (2 * UPLOAD_LIMIT_BYTES), "huge.net.xml", 413, "limit"),           # refused unread
    (BILLION_LAUGHS, "bomb.net.xml", 422, "DOCTYPE"),                           # entity bomb
    (EXTERNAL_ENTITY, "xxe.net.xml", 422, "DOCTYPE"),                           # external entity
    (b'<net><!ENTITY x "y"></net>', "ent.net.xml", 422, "ENTITY"),
    ('<?xml version="1.0"?><!DOCTYPE net><net/>'.encode("utf-16"), "u16.net.xml", 422, "UTF-8"),
    ('<?xml version="1.0"?><!DOCTYPE net><net/>'.encode("utf-16-le"), "le.net.xml", 422, "NUL"),
    ('<?xml version="1.0" encoding="latin-1"?><net/>'.encode(), "l1.net.xml", 422, "encoding"),
    (b"this is not XML at all", "text.net.xml", 422, "well-formed"),            # not XML
    (b"<net><edge></net>", "broken.net.xml", 422, "well-formed"),
    (b'<routes><vehicle id="a"/></routes>', "routes.net.xml", 422, "not a SUMO network"),
    (b"", "empty.net.xml", 422, "empty"),
    (gzip.compress(b"<net/>"), "c.net.xml", 422, "compressed"),
    (b"<net/>", "notes.txt", 422, ".net.xml"),                                  # wrong name
    (b"<net/>", "../../evil.net.xml", 422, "without edges"),                    # a name is never a path
])
def test_bad_upload_is_refused_and_nothing_is_stored(
        client: TestClient, data_dir: Path, field_named: Any,
        data: bytes, filename: str, status: int, words: str) -> None:
    before = _stored(data_dir)
    response = _upload(client, data, filename)
    assert response.status_code == status, response.text
    detail = response.json()["detail"]
    message = detail if isinstance(detail, str) else detail[0]["msg"]
    assert words in message, message
    if status == 422:
        assert field_named(response, "file")
    assert _stored(data_dir) == before
    assert not (data_dir.parent / "evil.net.xml").exists()


def test_network_without_a_traffic_light(client: TestClient, data_dir: Path, field_named: Any,
                                         no_light_net: bytes) -> None:
    before = _stored(data_dir)
    response = _upload(client, no_light_net, "plain.net.xml")
    assert field_named(response, "file")
    message = response.json()["detail"][0]["msg"]
    assert "no traffic-light junction" in message and "plain.net.xml" in message
    assert ".upload-" not in message, "the reader's message names the upload, not a temp file"
    assert _stored(data_dir) == before


def test_not_multipart_or_no_file_field(client: TestClient, field_named: Any) -> None:
    assert field_named(client.post("/api/intersections/upload", json={"file": "<net/>"}), "file")
    response = client.post("/api/intersections/upload", files={"other": ("a.net.xml", b"<net/>")})
    assert field_named(response, "file")
    assert "missing" in response.json()["detail"][0]["msg"]


def test_uploads_are_listed_with_their_paths_and_program(client: TestClient, field_named: Any) -> None:
    data = sumo_example(SUMO_CROSS_NET).read_bytes()
    digest = _upload(client, data, "cross.net.xml").json()["id"]
    listed = {u["id"]: u for u in client.get("/api/intersections/uploads").json()}
    assert listed[digest]["name"] == "cross.net.xml" and listed[digest]["net"] == f"uploads/{digest}.net.xml"
    geometry = client.get(f"/api/intersections/uploads/{digest}").json()
    assert geometry["name"] == "cross.net.xml" and geometry["program"]["phases"]
    paths = client.get(f"/api/intersections/uploads/{digest}/paths", params={"task": "left"})
    assert paths.status_code == 200 and paths.json() and paths.json()[0]["points"]
    assert field_named(client.get(f"/api/intersections/uploads/{digest}/paths",
                                  params={"task": "up"}), "task")
    bad = client.get(f"/api/intersections/uploads/{digest}/paths", params={"task": "left", "approach": "x"})
    assert bad.status_code == 422 and bad.json()["detail"].startswith("approach:")
    assert client.get(f"/api/intersections/uploads/{'0' * 64}/paths", params={"task": "left"}).status_code == 404


def test_a_net_whose_internal_lanes_run_off_the_paths_is_flagged(
        client: TestClient, data_dir: Path, tiny_scenario: dict[str, Any]) -> None:
    """netconvert drew some of cross.net.xml's internal lanes nearly 3 m from the candidate paths:
    the upload answer says so, the full list is one GET away, and validating a scenario on it
    warns — here the left turn from 3si with the paper's fixed ρ, whose paths SUMO's lane leaves by
    up to 3 m (the per-candidate ρ follows it within a metre) — the scenario stays valid: it runs,
    SUMO just sees the ego elsewhere."""
    body = _upload(client, sumo_example(SUMO_CROSS_NET).read_bytes(), "cross.net.xml").json()
    lanes = body["internal_lanes"]
    assert lanes["max_m"] > 2.0 and "cross.net.xml" in lanes["warning"]
    listed = client.get(f"/api/intersections/uploads/{body['id']}/internal-lanes").json()
    assert listed["max_m"] == lanes["max_m"] and listed["warning"] == lanes["warning"]
    flagged = [m for m in listed["movements"] if m["above_warning"]]
    assert flagged and all(m["max_m"] > 1.0 for m in flagged)
    assert {m["turn"] for m in listed["movements"]} >= {"left", "straight", "right"}

    scenario = {**tiny_scenario, "name": "warned", "task": "left", "intersection": {"net": body["net"]},
                "rho": 0.6}
    checked = client.post("/api/scenarios/validate", json=scenario).json()
    assert checked["valid"] and checked["problems"] == []
    assert [w["field"] for w in checked["warnings"]] == ["intersection"]
    assert "left from" in checked["warnings"][0]["message"]
    # named as the user uploaded it, not by its digest alone
    assert f"cross.net.xml (upload {body['id'][:12]})" in checked["warnings"][0]["message"]
    assert str(data_dir) not in checked["warnings"][0]["message"]
