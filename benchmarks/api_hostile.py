"""The hostile and clumsy-client test of the studio's API (issue 35), replayed against a real
`crossroads serve` on 127.0.0.1 (a free port, a temporary data directory; loopback only).

    .venv/bin/python benchmarks/api_hostile.py [--loop 1000] [--seed 0] [--wall-limit-s 5]

What it does, in order:

1. unbounded numbers (runs 10^12 and 10^30, warm-up 10^7 s, excess 1e308, densities, speeds,
   256 workers), ids of 2^31, 2^63 and beyond in paths, query strings and bodies, NaN and
   Infinity in POST /api/batches and /api/live, file names as intersection names;
2. another web page: a cross-site ``text/plain`` POST that cancels a running batch, a multipart
   upload from a foreign Origin, a request under a rebound DNS name, GET /api/playback/...;
3. a 100 MB JSON body, with a Content-Length and chunked, while the server's memory is read from
   /proc (VmRSS now, VmHWM: its peak over the whole run);
4. batches that must stop: cancelled while running, while starting, after a restart (resuming),
   one whose cancel is followed at once by kill -9 of the server (it must stay cancelled after the
   restart), and one whose episodes outlast the per-episode wall-clock limit;
5. a bounded loop of ``--loop`` requests drawn (seeded) from the hostile shapes above.

Printed: server errors (5xx answers, and tracebacks in the server's log), runaway batches (a batch
not ended 60 s after its cancel, grown after it ended, or left running at the end), cross-origin
state changes (a foreign request answered 2xx, or a state it would have changed that did change),
and the server's memory with the 100 MB body refused. Target (issue 35): 0, 0, 0 and < 300 MB.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import random
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
HOST = "127.0.0.1"
START_TIMEOUT_S = 60.0
CANCEL_TIMEOUT_S = 60.0
MB = 1 << 20
FOREIGN = "http://evil.example"
SCENARIO: dict[str, Any] = {
    "version": 1, "name": "hostile", "intersection": "a_single_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 100, "cyclists_per_hour": 0, "pedestrians_per_hour": 0},
    "warmup_s": 5.0, "timeout_s": 20.0, "runs": 20, "seed": 7,
}
FINISHED = ("done", "cancelled", "failed")


@dataclass
class Tally:
    answers: Counter[int] = field(default_factory=Counter)
    server_errors: list[str] = field(default_factory=list)
    accepted_hostile: list[str] = field(default_factory=list)  # bad input answered 2xx
    cross_origin_changes: list[str] = field(default_factory=list)
    runaway: list[str] = field(default_factory=list)


class Server:
    """A `crossroads serve` subprocess on a free loopback port."""

    def __init__(self, data_dir: Path, wall_limit_s: float) -> None:
        self.data_dir = data_dir
        self.wall_limit_s = wall_limit_s
        with socket.socket() as s:
            s.bind((HOST, 0))
            self.port = int(s.getsockname()[1])
        self.proc: subprocess.Popen[bytes] | None = None
        self.logs: list[Path] = []

    def start(self) -> None:
        env = {**os.environ, "CROSSROADS_DATA_DIR": str(self.data_dir),
               "CROSSROADS_EPISODE_WALL_LIMIT_S": str(self.wall_limit_s)}
        log = self.data_dir / f"serve-{len(self.logs)}.log"
        self.logs.append(log)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "crossroads.cli", "serve", "--host", HOST, "--port", str(self.port)],
            env=env, stdout=log.open("wb"), stderr=subprocess.STDOUT, cwd=REPO)
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            try:
                if request(self, "GET", "/api/health", tally=None)[0] == 200:
                    return
            except OSError:
                pass
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise SystemExit(f"crossroads serve did not start:\n{log.read_text(errors='replace')}")
            time.sleep(0.3)

    def kill9(self) -> None:
        assert self.proc is not None
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def memory_mb(self) -> tuple[float, float]:
        """(VmRSS, VmHWM) of the server process [MB]."""
        assert self.proc is not None
        fields = dict(line.split(":", 1) for line in Path(f"/proc/{self.proc.pid}/status").read_text().splitlines()
                      if ":" in line)
        return (int(fields["VmRSS"].split()[0]) / 1024, int(fields["VmHWM"].split()[0]) / 1024)

    def descendants(self) -> list[int]:
        """Processes below the server (batch workers, their episode children, SUMO)."""
        assert self.proc is not None
        parents: dict[int, int] = {}
        for entry in Path("/proc").iterdir():
            if entry.name.isdigit():
                try:
                    stat = (entry / "stat").read_text()
                except OSError:
                    continue
                parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
        found, frontier = [], [self.proc.pid]
        while frontier:
            pid = frontier.pop()
            children = [c for c, p in parents.items() if p == pid]
            found += children
            frontier += children
        return found

    def traceback_count(self) -> int:
        return sum(log.read_text(errors="replace").count("Traceback (most recent call last)") for log in self.logs)


def request(server: Server, method: str, path: str, *, body: Any = None, raw: bytes | None = None,
            headers: dict[str, str] | None = None, tally: Tally | None, label: str = "") -> tuple[int, Any]:
    """One request; its status and its JSON body (or text). 5xx answers are counted."""
    conn = http.client.HTTPConnection(HOST, server.port, timeout=60)
    sent = dict(headers or {})
    data = raw
    if body is not None:
        data = json.dumps(body).encode()
        sent.setdefault("content-type", "application/json")
    try:
        conn.request(method, path, body=data, headers=sent)
        response = conn.getresponse()
        text = response.read().decode(errors="replace")
    finally:
        conn.close()
    try:
        payload: Any = json.loads(text) if text else None
    except ValueError:
        payload = text
    if tally is not None:
        tally.answers[response.status] += 1
        if response.status >= 500:
            tally.server_errors.append(f"{response.status} {method} {path} {label}: {text[:200]}")
    return response.status, payload


def expect_refused(server: Server, tally: Tally, method: str, path: str, label: str, **kw: Any) -> int:
    status, payload = request(server, method, path, tally=tally, label=label, **kw)
    if 200 <= status < 300:
        tally.accepted_hostile.append(f"{status} {method} {path} {label}: {str(payload)[:120]}")
    return status


def big_body(server: Server, size: int, *, chunked: bool) -> int | str:
    """POST a JSON body of ``size`` bytes (a scenario whose description is x's), 1 MB at a time,
    stopping as soon as the server answers; its status, or how the connection ended."""
    sock = socket.create_connection((HOST, server.port), timeout=60)
    head = (f"POST /api/scenarios HTTP/1.1\r\nHost: {HOST}:{server.port}\r\nContent-Type: application/json\r\n"
            + ("Transfer-Encoding: chunked\r\n" if chunked else f"Content-Length: {size}\r\n") + "\r\n")
    body = b'{"version": 1, "name": "big", "intersection": "a_single_lane", "task": "left", "description": "'
    body += b"x" * (MB - len(body))
    try:
        sock.sendall(head.encode())
        for _ in range(size // MB):
            sock.sendall(f"{len(body):x}\r\n".encode() + body + b"\r\n" if chunked else body)
            body = b"x" * MB
            if select.select([sock], [], [], 0)[0]:
                break  # the server has answered already
        else:
            sock.sendall(b'2\r\n"}\r\n0\r\n\r\n' if chunked else b"")
    except (BrokenPipeError, ConnectionResetError):
        pass
    try:
        reply = sock.recv(4096).decode(errors="replace")
    except OSError:
        return "connection closed"
    finally:
        sock.close()
    return int(reply.split()[1]) if reply.startswith("HTTP/") else f"no answer ({reply[:40]!r})"


def wait_status(server: Server, batch_id: int, statuses: tuple[str, ...], timeout_s: float) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        status, body = request(server, "GET", f"/api/batches/{batch_id}", tally=None)
        if status == 200 and body["status"] in statuses:
            return body
        if time.monotonic() > deadline:
            return body if status == 200 else {"status": f"HTTP {status}", "progress": {"done": -1}}
        time.sleep(0.2)


def start_batch(server: Server, tally: Tally, name: str, **extra: Any) -> int:
    scenario = {**SCENARIO, "name": name, **extra.pop("scenario", {})}
    status, body = request(server, "POST", "/api/batches", tally=tally,
                           body={"scenario": scenario, "workers": 1, "traces": "none", **extra})
    if status != 202:
        raise SystemExit(f"batch {name} not accepted: {status} {body}")
    return int(body["id"])


# --- the parts ------------------------------------------------------------------------------------


def hostile_inputs(server: Server, tally: Tally) -> None:
    """Issue 35, items 1-5 and 7: each must be a 4xx, never stored, never a 500."""
    stored = request(server, "POST", "/api/scenarios", body={**SCENARIO, "name": "hostile-base"}, tally=tally)[1]["id"]
    for patch in ({"runs": 10**12}, {"runs": 10**30}, {"warmup_s": 1e7}, {"timeout_s": 1e9},
                  {"abnormal": {"overspeed": {"share": 0.1, "excess": 1e308}}},
                  {"traffic": {"vehicles_per_hour": 1e9}}, {"ego": {"start_speed_mps": 1e6}}):
        expect_refused(server, tally, "POST", "/api/scenarios", f"scenario {patch}", body={**SCENARIO, **patch})
        expect_refused(server, tally, "POST", "/api/batches", f"inline {patch}",
                       body={"scenario": {**SCENARIO, **patch}})
    for body in ({"scenario_id": stored, "runs": 10**12}, {"scenario_id": stored, "runs": 10**30},
                 {"scenario_id": stored, "workers": 256}, {"scenario_id": 2**63}, {"scenario_id": 2**31}):
        expect_refused(server, tally, "POST", "/api/batches", str(body), body=body)
    for literal in ("NaN", "Infinity", "-Infinity"):
        for path, text in (("/api/batches", f'{{"scenario_id": {stored}, "runs": {literal}}}'),
                           ("/api/live", f'{{"scenario_id": {stored}, "speed": {literal}}}'),
                           ("/api/live", f'{{"scenario_id": {stored}, "seed": {literal}}}')):
            expect_refused(server, tally, "POST", path, literal, raw=text.encode(),
                           headers={"content-type": "application/json"})
    for big in (2**31, 2**63, 2**64, 10**30):
        for method, path in (("GET", f"/api/batches/{big}"), ("GET", f"/api/scenarios/{big}"),
                             ("GET", f"/api/episodes/{big}/{big}"), ("POST", f"/api/batches/{big}/cancel"),
                             ("GET", f"/api/batches?scenario_id={big}"), ("GET", f"/api/reports?batch={big}"),
                             ("GET", f"/api/playback/{big}/0"), ("GET", f"/api/live/{big}")):
            expect_refused(server, tally, method, path, "big id")
        expect_refused(server, tally, "POST", "/api/live", "big id", body={"scenario_id": big})
    for name in ("docker-compose.yml", "Makefile", "pytest.ini", "x.net.xml"):
        expect_refused(server, tally, "GET", f"/api/intersections/{name}", "file name")
    status, _ = request(server, "GET", "/api/scenarios?limit=100000", tally=tally)
    if status != 422:
        tally.accepted_hostile.append(f"{status} GET /api/scenarios?limit=100000 (no maximum)")


def cross_origin(server: Server, tally: Tally) -> None:
    """Issue 35, item 6: another page drives nothing; a rebound DNS name reaches nothing."""
    batch_id = start_batch(server, tally, "hostile-target", runs=200)
    wait_status(server, batch_id, ("running",), 60)
    uploads = request(server, "GET", "/api/intersections/uploads", tally=tally)[1]
    net = (REPO / "scenarios" / "README.md").read_bytes()[:200]  # any bytes: it must not even be read
    attempts = [
        ("POST", f"/api/batches/{batch_id}/cancel", {"origin": FOREIGN, "content-type": "text/plain"}, b"x"),
        ("POST", f"/api/batches/{batch_id}/cancel", {"sec-fetch-site": "cross-site"}, None),
        ("POST", f"/api/batches/{batch_id}/cancel", {"origin": "null"}, None),
        ("POST", f"/api/batches/{batch_id}/cancel", {"host": f"evil.example:{server.port}"}, None),
        ("POST", "/api/intersections/upload",
         {"origin": FOREIGN, "content-type": "multipart/form-data; boundary=b"},
         b'--b\r\nContent-Disposition: form-data; name="file"; filename="x.net.xml"\r\n\r\n' + net + b"\r\n--b--\r\n"),
        ("POST", "/api/scenarios", {"origin": FOREIGN, "content-type": "text/plain"},
         json.dumps({**SCENARIO, "name": "planted"}).encode()),
        ("GET", "/api/scenarios", {"host": "attacker.example"}, None),
        ("GET", "/", {"host": "attacker.example"}, None),
    ]
    for method, path, headers, raw in attempts:
        status, _ = request(server, method, path, raw=raw, headers=headers, tally=tally, label=str(headers))
        if 200 <= status < 300:
            tally.cross_origin_changes.append(f"{status} {method} {path} {headers}")
    body = request(server, "GET", f"/api/batches/{batch_id}", tally=tally)[1]
    if body["status"] != "running" or body.get("cancel_requested"):
        tally.cross_origin_changes.append(f"batch {batch_id} is {body['status']} after foreign cancels")
    if request(server, "GET", "/api/intersections/uploads", tally=tally)[1] != uploads:
        tally.cross_origin_changes.append("an upload from a foreign origin was stored")
    names = [s["name"] for s in request(server, "GET", "/api/scenarios?limit=1000", tally=tally)[1]]
    if "planted" in names:
        tally.cross_origin_changes.append("a scenario from a foreign origin was stored")
    request(server, "POST", f"/api/batches/{batch_id}/cancel", tally=tally)
    wait_status(server, batch_id, FINISHED, CANCEL_TIMEOUT_S)


def memory(server: Server, tally: Tally) -> dict[str, Any]:
    """Issue 35, item 4: a 100 MB body, declared and chunked, while the memory is read."""
    before, _ = server.memory_mb()
    declared = big_body(server, 100 * MB, chunked=False)
    chunked = big_body(server, 100 * MB, chunked=True)
    after, peak = server.memory_mb()
    for label, status in (("declared", declared), ("chunked", chunked)):
        if status != 413:
            tally.accepted_hostile.append(f"100 MB body ({label}): {status}")
    return {"rss_before_mb": before, "rss_after_mb": after, "peak_mb": peak,
            "declared": declared, "chunked": chunked}


def batches_that_stop(server: Server, tally: Tally) -> dict[str, Any]:
    """Issue 35, items 1-2: cancel in every state, durable across kill -9; the wall-clock limit."""
    out: dict[str, Any] = {}
    ended: dict[int, int] = {}  # batch id → episodes recorded when it ended

    def ended_cancelled(batch_id: int, label: str) -> None:
        body = wait_status(server, batch_id, FINISHED, CANCEL_TIMEOUT_S)
        if body["status"] != "cancelled":
            tally.runaway.append(f"{label}: batch {batch_id} is {body['status']} {CANCEL_TIMEOUT_S:.0f} s after its cancel")
        ended[batch_id] = body["progress"]["done"]

    running = start_batch(server, tally, "stop-running", runs=10_000)
    wait_status(server, running, ("running",), 60)
    t0 = time.monotonic()
    request(server, "POST", f"/api/batches/{running}/cancel", tally=tally)
    ended_cancelled(running, "running")
    out["cancel_running_s"] = round(time.monotonic() - t0, 2)

    starting = start_batch(server, tally, "stop-starting", runs=10_000)
    request(server, "POST", f"/api/batches/{starting}/cancel", tally=tally)  # before it runs anything
    ended_cancelled(starting, "starting")

    slow = start_batch(server, tally, "stop-slow", runs=2,
                       scenario={"warmup_s": 600.0, "timeout_s": 3600.0,
                                 "traffic": {"vehicles_per_hour": 1800, "cyclists_per_hour": 1800,
                                             "pedestrians_per_hour": 3600}})
    body = wait_status(server, slow, FINISHED, 120)
    episodes = request(server, "GET", f"/api/batches/{slow}/episodes", tally=tally)[1]
    limited = sum(1 for e in episodes if (e["error_message"] or "").startswith("wall-clock limit"))
    out["wall_clock_limited"] = f"{limited} of {len(episodes)} episodes ({body['status']})"
    if body["status"] not in FINISHED:
        tally.runaway.append(f"slow: batch {slow} still {body['status']}")

    killed = start_batch(server, tally, "stop-killed", runs=10_000)
    resumed = start_batch(server, tally, "stop-resumed", runs=10_000)
    wait_status(server, killed, ("running",), 60)
    request(server, "POST", f"/api/batches/{killed}/cancel", tally=tally)
    server.kill9()  # at once: its runner had no time to record the cancel
    time.sleep(1.0)
    server.start()
    ended_cancelled(killed, "cancelled, then kill -9")
    body = wait_status(server, resumed, ("running",), 60)  # resumed after the restart
    out["resumed_after_restart"] = body["status"]
    request(server, "POST", f"/api/batches/{resumed}/cancel", tally=tally)
    ended_cancelled(resumed, "resuming")

    time.sleep(5.0)  # nothing may grow after its end
    for batch_id, done in ended.items():
        now = request(server, "GET", f"/api/batches/{batch_id}", tally=tally)[1]
        if now["progress"]["done"] != done or now["status"] not in FINISHED:
            tally.runaway.append(f"batch {batch_id} went on after its end: {done} → {now['progress']['done']}")
    unfinished = request(server, "GET", "/api/batches?status=queued&status=running", tally=tally)[1]
    tally.runaway += [f"batch {b['id']} still {b['status']} at the end" for b in unfinished]
    time.sleep(2.0)
    left = []
    for pid in server.descendants():
        try:
            command = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
        except OSError:
            continue
        if "multiprocessing.resource_tracker" not in command:  # Python's own helper, not a worker
            left.append(command[:80])
    out["processes_left"] = f"{len(left)} {left}" if left else "0"
    return out


def hostile_loop(server: Server, tally: Tally, n: int, seed: int) -> None:
    """A bounded loop of requests drawn from the hostile shapes, with seeded numbers."""
    rng = random.Random(seed)
    numbers = [0, -1, 1, 2**31 - 1, 2**31, 2**53, 2**63 - 1, 2**63, 2**64, 10**30, 1e308, -1e308, 0.5]
    literals = ["NaN", "Infinity", "-Infinity", "1e999", "null", '"x"', "[]", "{}", "true"]
    fields = ["runs", "warmup_s", "timeout_s", "seed", "rho"]
    for _ in range(n):
        x = rng.choice(numbers)
        kind = rng.randrange(7)
        if kind == 0:
            path = rng.choice(["/api/batches/{}", "/api/scenarios/{}", "/api/episodes/{}/{}", "/api/live/{}",
                               "/api/batches/{}/episodes", "/api/episodes/1/{}/trace", "/api/playback/{}/1"])
            request(server, "GET", path.format(x, x), tally=tally)
        elif kind == 1:
            request(server, "GET", f"/api/{rng.choice(['scenarios', 'batches', 'policies', 'live'])}"
                                   f"?limit={x}&offset={rng.choice(numbers)}", tally=tally)
        elif kind == 2:
            text = json.dumps({**SCENARIO, "name": f"loop-{rng.randrange(10**6)}"})[:-1]
            text += f', "{rng.choice(fields)}": {rng.choice(literals + [str(x)])}}}'
            request(server, "POST", rng.choice(["/api/scenarios", "/api/scenarios/validate"]), raw=text.encode(),
                    headers={"content-type": "application/json"}, tally=tally)
        elif kind == 3:
            body = f'{{"scenario_id": {rng.choice(literals + [str(x)])}, "runs": {rng.choice(literals + [str(x)])}}}'
            request(server, "POST", rng.choice(["/api/batches", "/api/live"]), raw=body.encode(),
                    headers={"content-type": "application/json"}, tally=tally)
        elif kind == 4:
            request(server, "POST", f"/api/batches/{x}/cancel", tally=tally,
                    headers=rng.choice([{}, {"origin": FOREIGN}, {"content-type": "text/plain"}]))
        elif kind == 5:
            request(server, "GET", f"/api/reports?batch={x}&format={rng.choice(['html', 'csv', 'pdf'])}", tally=tally)
        else:
            request(server, "GET", f"/api/intersections/{rng.choice(['a_single_lane', 'nope', '..', 'x.yaml'])}"
                                   f"/paths?task={rng.choice(['left', 'up'])}&rho={x}", tally=tally)
    # nothing the loop started may keep running
    for b in request(server, "GET", "/api/batches?status=queued&status=running", tally=tally)[1]:
        tally.runaway.append(f"the loop started batch {b['id']}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--loop", type=int, default=1000, help="requests of the bounded hostile loop")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--wall-limit-s", type=float, default=5.0, help="the server's per-episode wall-clock limit")
    args = parser.parse_args()
    tally = Tally()
    with tempfile.TemporaryDirectory(prefix="crossroads-hostile-") as tmp:
        server = Server(Path(tmp), args.wall_limit_s)
        server.start()
        started = time.monotonic()
        try:
            hostile_inputs(server, tally)
            cross_origin(server, tally)
            mem = memory(server, tally)
            stops = batches_that_stop(server, tally)
            hostile_loop(server, tally, args.loop, args.seed)
            final_rss, peak = server.memory_mb()
        finally:
            server.stop()
        tracebacks = server.traceback_count()
    print(f"requests: {sum(tally.answers.values())} in {time.monotonic() - started:.0f} s; "
          f"answers {dict(sorted(tally.answers.items()))}")
    print(f"server errors: {len(tally.server_errors)} (5xx answers), {tracebacks} tracebacks in the server's log")
    print(f"runaway batches: {len(tally.runaway)}")
    print(f"cross-origin state changes: {len(tally.cross_origin_changes)}")
    print(f"hostile inputs accepted: {len(tally.accepted_hostile)}")
    print(f"server RSS: {mem['rss_before_mb']:.0f} MB before the 100 MB bodies, {mem['rss_after_mb']:.0f} MB after "
          f"(answered {mem['declared']} with Content-Length, {mem['chunked']} chunked); "
          f"peak (VmHWM, whole run of the first server process) {mem['peak_mb']:.0f} MB; "
          f"{final_rss:.0f} MB at the end (restarted process, peak {peak:.0f} MB)")
    print(f"batches: cancel of a running batch took {stops['cancel_running_s']} s; wall-clock limit: "
          f"{stops['wall_clock_limited']}; after kill -9 and restart the uncancelled batch was "
          f"{stops['resumed_after_restart']}; worker processes left below the server: {stops['processes_left']}")
    for title, items in (("server errors", tally.server_errors), ("runaway", tally.runaway),
                         ("cross-origin", tally.cross_origin_changes), ("accepted", tally.accepted_hostile)):
        for item in items[:10]:
            print(f"  {title}: {item}")


if __name__ == "__main__":
    main()
