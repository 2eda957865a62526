"""The process a live run's episode runs in (started by :mod:`crossroads.api.live`, spawn context).

libsumo runs one simulation per process, and a simulation that crashes takes its process with it,
so the API never runs an episode itself: this process builds the world, waits for the go, runs
the episode and sends each step's frame (a :meth:`Trace.frame`-shaped dict) to the API, which
shows it in the 3D view. Messages on ``conn``, all ``(kind, payload)``:

* ``("ready", {"net", "junction", "candidates"})`` once the world is built;
* ``("frame", frame)`` per step, paced to ``speed`` × real time (0: as fast as it runs);
* ``("result", EpisodeResult.to_json())``, ``("stopped", {})`` or ``("error", message)`` last.

Kept free of FastAPI and viser imports: it starts in a fresh interpreter.
"""

from __future__ import annotations

import time
from typing import Any

from crossroads.constants import SIM_STEP_S
from crossroads.evaluation.trace import TraceRecorder
from crossroads.viz.viewer import frame_of_observation

GO_POLL_S = 0.2  # [s] how often a ready world looks for the go (or a stop)


class Stopped(Exception):
    """The API asked the run to stop."""


class FrameStreamer(TraceRecorder):
    """A recorder that keeps nothing: it sends every step's frame down ``conn``, paced."""

    def __init__(self, conn: Any, stop: Any, speed: float) -> None:
        super().__init__()
        self.conn = conn
        self.stop = stop
        self.speed = float(speed)
        self.index = 0
        self._last = time.monotonic()

    def start(self, world: Any, seed: int, scenario: str | None = None) -> None:
        self._last = time.monotonic()

    def _send(self, observation: Any, truth: Any, decision: Any) -> None:
        if self.stop.is_set():
            raise Stopped
        self.conn.send(("frame", frame_of_observation(observation, truth, decision, index=self.index)))
        self.index += 1
        if self.speed > 0.0:  # real time × speed: sleep what is left of this step's share
            wait = SIM_STEP_S / self.speed - (time.monotonic() - self._last)
            if wait > 0.0:
                time.sleep(wait)
        self._last = time.monotonic()

    def record(self, observation: Any = None, decision: Any = None, truth: Any = None, /, **step: Any) -> None:
        self._send(observation, truth, decision)

    def finish(self, observation: Any = None, outcome: Any = None, truth: Any = None, /, **result: Any) -> None:
        if observation is not None:
            self._send(observation, truth, None)


def main(conn: Any, stop: Any, go: Any, job: dict[str, Any]) -> None:
    """Run one episode of ``job`` (``spec``, ``base_dir``, ``policy``, ``seed``, ``speed``)."""
    try:
        conn.send(_run(conn, stop, go, job))
    except Stopped:
        conn.send(("stopped", {}))
    except BaseException as exc:  # noqa: BLE001 - the API shows the reason, whatever it is
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def _run(conn: Any, stop: Any, go: Any, job: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    from crossroads.evaluation.episode import run_episode
    from crossroads.evaluation.policies import load_controller
    from crossroads.policy.ref import parse_policy
    from crossroads.scenario.spec import to_world_config, validate_scenario
    from crossroads.sim.world import World

    spec = validate_scenario(job["spec"], source="live run", check_references=False)
    config = to_world_config(spec, base_dir=job["base_dir"])
    controller = load_controller(parse_policy(job["policy"]))
    with World(config) as world:
        conn.send(("ready", {"net": str(config.net_file), "junction": world.junction.id,
                             "candidates": [c.to_json() for c in world.candidates]}))
        while not go.wait(GO_POLL_S):
            if stop.is_set():
                raise Stopped
        streamer = FrameStreamer(conn, stop, job["speed"])
        result = run_episode(world, controller, int(job["seed"]), recorder=streamer,
                             scenario_name=spec.name)
    return "result", result.to_json()
