"""The one door to SUMO: a :class:`SumoSession` over libsumo.

This is the ONLY module of Crossroads that imports ``libsumo`` (docs/guide/architecture.md). Everything else talks
to SUMO through the session's methods, which take and return our conventions:

* positions [m] in SUMO's network frame; for vehicles the **footprint centre** (SUMO reports the
  centre of the front bumper; we shift by half the length along the heading, both ways);
* headings [rad] counter-clockwise from +x (SUMO: degrees clockwise from north);
* speeds [m/s], times [s].

libsumo runs the simulation inside this process and holds exactly one simulation per process, so
at most one session may be running at a time (a second ``start`` raises :class:`SumoError`). Run
several simulations in parallel with processes, not threads.

Every libsumo failure is turned into :class:`SumoError` in one place (:func:`_sumo_errors`). SUMO
writes its load errors to the C ``stderr`` rather than into the exception, so ``start`` captures
file descriptor 2 while loading and puts SUMO's own message into the error.

Known libsumo behaviours this module works around (SUMO 1.28):

* the snapshot reads each alive participant's pose with the plain getters, not subscriptions:
  measured with ~110 participants (c_three_lane), ``getAllSubscriptionResults`` alone took 120 µs
  a step and keeping the subscriptions 65 µs more inside ``simulationStep``, while the getters take
  ~60 µs (libsumo's getters are direct calls; its subscription results are converted to Python
  dicts of dicts). The alive ids are tracked from the departed/arrived lists. The getters are
  called as the compiled functions of ``libsumo._libsumo`` (:data:`_GET`): libsumo's public
  ``vehicle.getPosition`` etc. are Python staticmethods that only forward to them, and that extra
  Python call was a quarter of the snapshot (measured 63 against 86 µs, ~110 participants);
* ``close()`` after a failed ``start()`` is harmless, but a second failing start in one process
  can crash on some malformed nets, so ``start`` checks the input files exist first.
"""

from __future__ import annotations

import functools
import math
import os
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import chain
from pathlib import Path
from typing import ParamSpec, TypeVar

import libsumo
import numpy as np
from numpy.typing import NDArray

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M, SIM_STEP_S
from crossroads.geometry import heading_to_sumo_angle, point_at, project_onto_polyline
from crossroads.sim.snapshot import KIND_CODE, KINDS, Kind, Snapshot

_KIND_NAMES = np.array(KINDS, dtype="<U10")  # KIND_CODE inverted, for column lookups

EGO_TYPE_ID = "ego"
SUMO_EGO_TYPE_ID = "ego_sumo_driven"  # the ego's footprint, driven by SUMO's models (policy "sumo")
LANE_CHANGE_MODE_DEFAULT = 1621  # SUMO's default lane-change mode (strategic, cooperative, ...)


@dataclass(frozen=True)
class SumoDriver:
    """The parameters SUMO's own driver gets when it drives the ego (policy ``sumo``).

    A Krauss driver without dawdling (``sigma`` 0) at the ego's own speed limit, otherwise as the
    world's cars (acceleration, braking, gap, and the impatience with which a driver waiting to
    turn across traffic accepts a gap that makes a foe brake): the baseline of what the world
    lets through."""

    max_speed_mps: float  # [m/s] the ego's speed limit
    accel_mps2: float = 2.6  # [m/s²] as the world's cars
    decel_mps2: float = 4.5  # [m/s²] as the world's cars
    sigma: float = 0.0  # Krauss imperfection
    min_gap_m: float = 2.5  # [m] standstill gap to the leader
    impatience: float = 0.5  # as the world's cars (sim/traffic.py IMPATIENCE)
    # [m/s] a foe with right of way moving no faster than this is not waited for: SUMO's junction
    # model otherwise has a driver waiting to turn left wait for a foe that itself stands (a car
    # held at its own line, a queue that does not move), through whole cycles with its link open —
    # on the nominal left turn of c_three_lane, 4 of 30 runs timed out so (base seed 20261206);
    # with it 2 of those 4 passed in the next cycle. None: wait for every foe.
    ignore_foes_below_mps: float | None = 1.0
    # brake for a pedestrian, cyclist or vehicle in the way ahead, or about to be (sim/look_ahead.py)
    look_ahead: bool = True
    # once its light is no longer green while it is inside the junction, drive on regardless of
    # the junction's right of way (the look-ahead still keeps it from driving into anyone): SUMO's
    # driver otherwise stands at its left turn's waiting point, yielding to the cross street's
    # green and then to the oncoming stream again, through whole cycles. On the nominal left turn
    # of c_three_lane (the first 60 runs of base seed 20261206) 9 timeouts became 3, no collision.
    clear_junction: bool = True
    # [s] ... and once it has stood that long clearing it with no one in its way (the look-ahead not
    # braking), past the foes SUMO counts inside the junction too (speed mode 55 instead of 23):
    # otherwise it stood at e_irregular_oblique's waiting point after its green, no one in its
    # way, to the timeout (runs 1696336797 and 780574059 of base seed 20261206; 200 runs: 193 ->
    # 199 passes, no collision). At once rather than after standing, it drove into the oncoming
    # cars still inside the junction as its yellow ended (157 of 200, 41 collisions). The cross
    # street waits at its line meanwhile (sim/letting_out.py). None: never.
    clear_through_after_s: float | None = 5.0

# SUMO speed-mode bits (sumo.dlr.de/docs/TraCI/Change_Vehicle_State.html#speed_mode_0xb3).
SPEED_MODE_DEFAULT = 31  # all checks on
SPEED_MODE_IGNORE_ALL = 0  # no safe speed, no limits, no lights, no junctions
SPEED_MODE_CLEARING = 23  # all checks but the right of way at intersections (bit 3)
SPEED_MODE_CLEARING_THROUGH = 55  # and disregarding foes already inside the junction (bit 5)
GREEN_LINK_STATES = frozenset("Gg")  # a link's green in a light's state string (with and without priority)

# moveToXY keepRoute values (libsumo docstring of vehicle.moveToXY):
KEEP_ROUTE_ON_ROUTE = 1  # map onto the closest lane of the vehicle's own route (incl. internal lanes)
KEEP_ROUTE_ANY_EDGE = 0  # may map onto any edge; the route then becomes that edge
KEEP_ROUTE_OFF_ROAD = 2  # like 0 but may also leave the road network
# Bits 1|2: stay on the own route AND keep the exact x, y. Without bit 2 SUMO snaps the vehicle
# onto the lane centre unless the sublane model is on (measured: 0.3 m offset lost with 1).
KEEP_ROUTE_EXACT = KEEP_ROUTE_ON_ROUTE | KEEP_ROUTE_OFF_ROAD

# [m] a snapped ego is placed exactly again once its bumper is this far inside the off-road limit
# (move_ego): a margin, so that a pose near the limit does not alternate between on and off the road
EGO_SNAP_RELEASE_M = 0.5

_INVALID = libsumo.INVALID_DOUBLE_VALUE


def _raw_getter(domain: str, name: str) -> Callable[..., object]:
    """libsumo's compiled ``<domain>_<name>`` (same function, same errors, one Python call less
    per participant); the public ``libsumo.<domain>.<name>`` where a build has no such symbol."""
    raw = getattr(getattr(libsumo, "_libsumo", None), f"{domain}_{name}", None)
    return raw if callable(raw) else getattr(getattr(libsumo, domain), name)


@dataclass(frozen=True)
class _Getters:
    """The per-participant getters the snapshot maps over the alive ids every step."""

    vehicle_position: Callable[[str], tuple[float, float]]
    vehicle_angle: Callable[[str], float]
    vehicle_speed: Callable[[str], float]
    person_position: Callable[[str], tuple[float, float]]
    person_angle: Callable[[str], float]
    person_speed: Callable[[str], float]


_GET = _Getters(*(_raw_getter(domain, name) for domain in ("vehicle", "person")  # type: ignore[arg-type]
                  for name in ("getPosition", "getAngle", "getSpeed")))


class SumoError(RuntimeError):
    """SUMO refused a command or failed to load; the message is SUMO's own."""


P = ParamSpec("P")
R = TypeVar("R")


def _sumo_errors(fn: Callable[P, R]) -> Callable[P, R]:
    """Re-raise libsumo's exceptions as :class:`SumoError` (the one place this is done)."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return fn(*args, **kwargs)
        except (libsumo.TraCIException, libsumo.FatalTraCIError) as exc:
            raise SumoError(f"{fn.__name__}: {exc}") from exc

    return wrapper


@contextmanager
def _captured_stderr() -> Iterator[Callable[[], str]]:
    """Redirect the process's fd 2 into a temporary file; yields a reader of what was written.

    SUMO (C++) writes its error messages there, not into the Python exception.
    """
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        saved = os.dup(2)
        os.dup2(tmp.fileno(), 2)

        def read() -> str:
            tmp.seek(0)
            return tmp.read().decode("utf-8", "replace")

        try:
            yield read
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def _option_pairs(extra_args: Sequence[str]) -> dict[str, str]:
    """``["--a", "1", "--flag", "--b", "x"]`` → ``{"--a": "1", "--flag": "true", "--b": "x"}``."""
    out: dict[str, str] = {}
    toks = list(extra_args)
    i = 0
    while i < len(toks):
        key = toks[i]
        if not key.startswith("-"):
            raise SumoError(f"extra SUMO argument {key!r} is not an option")
        if i + 1 < len(toks) and not toks[i + 1].startswith("--"):
            out[key] = toks[i + 1]
            i += 2
        else:
            out[key] = "true"
            i += 1
    return out


@dataclass(frozen=True)
class _Static:
    """What never changes for one participant while it lives (read once, on first sight)."""

    kind: Kind
    length_m: float
    width_m: float
    route: tuple[str, ...]


class _StaticTable:
    """The static values of every participant seen in this run, one row each (rows never move).

    When the participants change (a fifth of the steps with ~100 of them), a snapshot's static
    columns are a few fancy indexes of these rows instead of a Python look-up per participant and
    column (measured: 17 against 33 µs per rebuild, ~110 participants).
    """

    def __init__(self) -> None:
        self.row: dict[str, int] = {}  # participant id -> its row
        self.route: dict[str, tuple[str, ...]] = {}
        self.size = 0  # rows used (rows of forgotten participants stay, unused)
        self.kind_code = np.zeros(0, np.int8)
        self.length = np.zeros(0)
        self.width = np.zeros(0)
        self.half_length = np.zeros(0)

    def add(self, pid: str, st: _Static) -> None:
        if self.size == len(self.length):  # grow by doubling
            grown = max(256, 2 * self.size)
            for name in ("kind_code", "length", "width", "half_length"):
                old = getattr(self, name)
                new = np.zeros(grown, old.dtype)
                new[: self.size] = old[: self.size]
                setattr(self, name, new)
        k = self.size
        self.kind_code[k] = KIND_CODE[st.kind]
        self.length[k] = st.length_m
        self.width[k] = st.width_m
        self.half_length[k] = 0.5 * st.length_m
        self.route[pid] = st.route
        self.row[pid] = k
        self.size += 1

    def forget(self, pid: str) -> None:
        self.row.pop(pid, None)
        self.route.pop(pid, None)

    def rows(self, ids: tuple[str, ...]) -> NDArray[np.intp]:
        """Rows of ``ids`` (KeyError for an id not added)."""
        return np.fromiter(map(self.row.__getitem__, ids), np.intp, len(ids))


@dataclass(frozen=True)
class _StaticColumns:
    """Per-participant columns of a snapshot that only change when participants come or go."""

    key: tuple[str, ...]
    ids: NDArray[np.str_]
    kind: NDArray[np.str_]
    kind_code: NDArray[np.int8]
    length: NDArray[np.float64]
    width: NDArray[np.float64]
    half_length: NDArray[np.float64]  # 0.5 * length: the centre's offset from the front bumper
    route: tuple[tuple[str, ...], ...]


_ACTIVE: SumoSession | None = None  # libsumo: one simulation per process


class SumoSession:
    """One SUMO simulation in this process, started and closed any number of times.

    Use as a context manager::

        with SumoSession().start(net, [routes], seed=7) as sim:
            sim.step(); snap = sim.snapshot()

    Collisions (choice): ``--collision.action warn``, as a test bench does: SUMO reports them
    (:meth:`collisions`) but removes and teleports nobody, so a scene stays as it was; whether the
    ego collided is judged by the project on the true footprints (so junction-internal checks
    between SUMO's own participants are off unless asked for, see :meth:`start`).
    ``--time-to-teleport -1`` keeps jammed vehicles where they are instead of teleporting them.
    """

    def __init__(self) -> None:
        self._running = False
        self._step_length_s = SIM_STEP_S
        self._vehicles: dict[str, None] = {}  # alive, in departure order (dict keeps order)
        self._persons: dict[str, None] = {}
        self._static = _StaticTable()
        self._vehicle_holders: dict[str, set[str]] = {}  # vehicle id -> who holds it (hold_vehicle)
        self._egos: dict[str, float] = {}  # ego id -> length [m]
        self._egos_inserted: set[str] = set()  # egos SUMO has put on the road (after their first step)
        self._egos_snapped: set[str] = set()  # egos mapped onto their route's lane centres (move_ego)
        self._departed: tuple[str, ...] = ()
        self._step_index = 0  # steps since start; a snapshot reads its lanes only in its own step
        self._snapshot: Snapshot | None = None
        self._columns: _StaticColumns | None = None  # reused while the participants stay the same
        self._args: list[str] = []

    # --- life cycle ------------------------------------------------------------------------

    def start(
        self,
        net_file: str | Path,
        route_files: Sequence[str | Path] = (),
        *,
        seed: int,
        step_length_s: float = SIM_STEP_S,
        begin_s: float = 0.0,
        extra_args: Sequence[str] = (),
        check_junction_collisions: bool = False,
    ) -> SumoSession:
        """Load a network and its demand; returns ``self`` for ``with ... .start(...) as sim``.

        ``seed`` goes to SUMO's ``--seed`` (its own RNG: driver imperfection, speed factors).
        ``extra_args`` (``["--option", "value", ...]``) override the defaults set here.
        ``check_junction_collisions`` turns on SUMO's collision checks inside junctions between
        its own participants: off by default because it doubles the step time (measured 2.2 vs
        1.1 ms per step with ~150 participants on c_three_lane) and the ego's collisions are
        judged by the project on true footprints anyway.
        """
        global _ACTIVE
        if _ACTIVE is not None:
            raise SumoError(
                "a SUMO session is already running in this process (libsumo holds one "
                "simulation per process): close it first, or run simulations in separate processes"
            )
        files = [Path(net_file), *(Path(r) for r in route_files)]
        for f in files:
            if not f.is_file():
                raise SumoError(f"SUMO input file not found: {f}")
        options: dict[str, str] = {
            "--net-file": str(files[0]),
            "--seed": str(int(seed)),
            "--step-length": f"{step_length_s:g}",
            "--begin": f"{begin_s:g}",
            "--pedestrian.model": "striping",
            "--collision.action": "warn",
            "--collision.check-junctions": "true" if check_junction_collisions else "false",
            "--time-to-teleport": "-1",
            "--no-step-log": "true",
            "--no-warnings": "true",
            "--duration-log.disable": "true",
            "--xml-validation": "never",
        }
        if len(files) > 1:
            options["--route-files"] = ",".join(str(f) for f in files[1:])
        options.update(_option_pairs(extra_args))  # SUMO refuses an option given twice
        args = ["sumo", *(tok for kv in options.items() for tok in kv)]
        with _captured_stderr() as sumo_output:
            try:
                libsumo.start(args)
            except (libsumo.TraCIException, libsumo.FatalTraCIError) as exc:
                message = sumo_output().strip() or str(exc)
                raise SumoError(f"SUMO failed to start: {message}") from exc
        _ACTIVE = self
        self._running = True
        self._step_length_s = step_length_s
        self._vehicles.clear()
        self._persons.clear()
        self._static = _StaticTable()
        self._vehicle_holders.clear()
        self._egos.clear()
        self._egos_inserted.clear()
        self._egos_snapped.clear()
        self._departed = ()
        self._step_index = 0
        self._snapshot = None
        self._columns = None  # ids repeat across runs ("veh0"): never reuse another run's columns
        self._args = args
        return self

    def close(self) -> None:
        """End the simulation (idempotent)."""
        global _ACTIVE
        if not self._running:
            return
        try:
            libsumo.close()
        except (libsumo.TraCIException, libsumo.FatalTraCIError):
            pass  # closing a simulation that already ended is not an error for us
        finally:
            self._running = False
            if _ACTIVE is self:
                _ACTIVE = None

    def __enter__(self) -> SumoSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def running(self) -> bool:
        return self._running

    @property
    def args(self) -> tuple[str, ...]:
        """The command line SUMO was started with (for the trace)."""
        return tuple(self._args)

    # --- time ------------------------------------------------------------------------------

    @property
    def time_s(self) -> float:
        return libsumo.simulation.getTime()

    @property
    def step_length_s(self) -> float:
        return self._step_length_s

    @_sumo_errors
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps, keeping the set of alive participants."""
        sim = libsumo.simulation
        for _ in range(n):
            libsumo.simulationStep()
            self._step_index += 1
            for vid in sim.getArrivedIDList():
                self._forget(vid, self._vehicles)
            for pid in sim.getArrivedPersonIDList():
                self._forget(pid, self._persons)
            departed = sim.getDepartedIDList()
            for vid in departed:
                if vid not in self._egos:
                    self._vehicles[vid] = None
                else:
                    self._egos_inserted.add(vid)
            pdeparted = sim.getDepartedPersonIDList()
            for pid in pdeparted:
                self._persons[pid] = None
            self._departed = tuple(departed) + tuple(pdeparted)
        self._snapshot = None

    def _forget(self, pid: str, alive: dict[str, None]) -> None:
        alive.pop(pid, None)
        self._vehicle_holders.pop(pid, None)
        self._static.forget(pid)
        self._egos.pop(pid, None)
        self._egos_inserted.discard(pid)
        self._egos_snapped.discard(pid)

    @property
    def departed_last_step(self) -> tuple[str, ...]:
        """Vehicles and persons that entered the network in the last step (ego excluded)."""
        return self._departed

    # --- the snapshot ----------------------------------------------------------------------

    def _read_static(self, pid: str, is_person: bool) -> _Static:
        """What never changes for a participant, from SUMO (once, on first sight)."""
        if is_person:
            dom = libsumo.person
            kind: Kind = "pedestrian"
            route = tuple(dom.getEdges(pid))
        else:
            dom = libsumo.vehicle
            kind = "cyclist" if dom.getVehicleClass(pid) == "bicycle" else "vehicle"
            route = tuple(dom.getRoute(pid))
        return _Static(kind, dom.getLength(pid), dom.getWidth(pid), route)

    def _static_columns(self, ids: tuple[str, ...], n_vehicles: int) -> _StaticColumns:
        """The snapshot's columns that never change for a participant, rebuilt only when the set
        of participants changed since the last step (most steps it has not)."""
        cached = self._columns
        if cached is not None and cached.key == ids:
            return cached
        table = self._static
        try:
            rows = table.rows(ids)
        except KeyError:  # someone new: read them first
            for k, pid in enumerate(ids):
                if pid not in table.row:
                    table.add(pid, self._read_static(pid, k >= n_vehicles))
            rows = table.rows(ids)
        kind_code = table.kind_code[rows]
        self._columns = _StaticColumns(
            key=ids,
            ids=np.array(ids, dtype=np.str_),
            kind=_KIND_NAMES[kind_code],  # a lookup: cheaper than an array of n Python strings
            kind_code=kind_code,
            length=table.length[rows],
            width=table.width[rows],
            half_length=table.half_length[rows],
            route=tuple(map(table.route.__getitem__, ids)),
        )
        return self._columns

    @_sumo_errors
    def snapshot(self) -> Snapshot:
        """All participants now (ego excluded), read once per step and cached.

        Vehicle and pedestrian positions from SUMO are the middle of the front edge; the centre is
        half a length behind it along the heading. (For pedestrians that is ≤ 0.11 m.)
        """
        if self._snapshot is not None:
            return self._snapshot
        get = _GET
        vehicles, persons = tuple(self._vehicles), tuple(self._persons)
        n = len(vehicles) + len(persons)
        # fromiter over map() of the compiled getters: no per-call attribute lookups, no tuples
        # (measured 76 µs against 94 µs for a generator over (domain, id) pairs, ~110 participants)
        pos = np.fromiter(chain(chain.from_iterable(map(get.vehicle_position, vehicles)),
                                chain.from_iterable(map(get.person_position, persons))),
                          np.float64, 2 * n).reshape(n, 2)
        angle = np.fromiter(chain(map(get.vehicle_angle, vehicles), map(get.person_angle, persons)),
                            np.float64, n)
        speed = np.fromiter(chain(map(get.vehicle_speed, vehicles), map(get.person_speed, persons)),
                            np.float64, n)
        ids, n_vehicles = vehicles + persons, len(vehicles)  # vehicles first, then persons
        # known but not on the network (e.g. waiting to be inserted): left out. Rare, so one
        # reduction tells first (when the smallest x is above the invalid value, nobody has it)
        if n and np.minimum.reduce(pos[:, 0]) <= _INVALID:
            keep = np.flatnonzero(pos[:, 0] != _INVALID)
            ids = tuple(ids[k] for k in keep)
            pos, angle, speed = pos[keep], angle[keep], speed[keep]
            n_vehicles = int(np.count_nonzero(keep < len(vehicles)))
        static = self._static_columns(ids, n_vehicles)
        heading = np.radians(90.0 - angle)
        heading += np.pi  # in place: the same (heading + π) % 2π − π, fewer temporaries
        heading %= 2.0 * np.pi
        heading -= np.pi
        half = static.half_length
        snap = Snapshot(
            time_s=self.time_s,
            ids=static.ids,
            kind=static.kind,
            kind_code=static.kind_code,
            x=pos[:, 0] - half * np.cos(heading),
            y=pos[:, 1] - half * np.sin(heading),
            heading=heading,
            speed=speed,
            length=static.length,
            width=static.width,
            read_lanes=self._lane_reader(ids, n_vehicles),
            route=static.route,
        )
        self._snapshot = snap
        return snap

    def _lane_reader(self, ids: tuple[str, ...], n_vehicles: int) -> Callable[[], tuple[str, ...]]:
        """Reads the lanes of ``ids`` (the first ``n_vehicles`` vehicles, then persons), in this step only."""
        step = self._step_index

        def read() -> tuple[str, ...]:
            if not self._running or self._step_index != step:
                raise SumoError("the lanes of a snapshot can only be read in the step it was taken")
            return (tuple(map(libsumo.vehicle.getLaneID, ids[:n_vehicles]))
                    + tuple(map(libsumo.person.getLaneID, ids[n_vehicles:])))

        return read

    @property
    def vehicle_ids(self) -> tuple[str, ...]:
        """Alive SUMO vehicles (cars and bicycles), ego excluded, in departure order."""
        return tuple(self._vehicles)

    @property
    def person_ids(self) -> tuple[str, ...]:
        return tuple(self._persons)

    @_sumo_errors
    def vehicle_lanes(self) -> dict[str, str]:
        """Every alive vehicle's lane now (ego excluded), by id."""
        ids = tuple(self._vehicles)
        return dict(zip(ids, map(libsumo.vehicle.getLaneID, ids), strict=True))

    # --- the ego ---------------------------------------------------------------------------

    @_sumo_errors
    def add_ego(
        self,
        ego_id: str,
        route_edges: Sequence[str],
        *,
        depart_lane: int = 0,
        depart_pos_m: float = 0.0,
        depart_speed_mps: float = 0.0,
        length_m: float = EGO_LENGTH_M,
        width_m: float = EGO_WIDTH_M,
        sumo_driver: SumoDriver | None = None,
    ) -> None:
        """Insert the ego as a SUMO vehicle of type "ego" with its real footprint.

        It departs "now" (inserted in the next step); place it exactly with :meth:`move_ego`
        right after adding. ``depart_pos_m`` is the front bumper's position along the lane [m].

        Without ``sumo_driver`` SUMO never drives it: its speed mode and lane-change mode are 0
        and every step's pose comes from :meth:`move_ego`. With one, SUMO's own driver models
        drive it (car following, junction and lane-change models, all checks on) with that
        driver's parameters, once :meth:`release_ego` hands it over after the exact placement.
        """
        vt = libsumo.vehicletype
        type_id = EGO_TYPE_ID if sumo_driver is None else SUMO_EGO_TYPE_ID
        if type_id not in vt.getIDList():
            vt.copy("DEFAULT_VEHTYPE", type_id)
            vt.setVehicleClass(type_id, "passenger")
        vt.setLength(type_id, length_m)
        vt.setWidth(type_id, width_m)
        vt.setColor(type_id, (255, 0, 0, 255))
        if sumo_driver is not None:
            vt.setAccel(type_id, sumo_driver.accel_mps2)
            vt.setDecel(type_id, sumo_driver.decel_mps2)
            vt.setMaxSpeed(type_id, sumo_driver.max_speed_mps)
            vt.setImperfection(type_id, sumo_driver.sigma)
            vt.setMinGap(type_id, sumo_driver.min_gap_m)
            vt.setImpatience(type_id, sumo_driver.impatience)
            if sumo_driver.ignore_foes_below_mps is not None:
                vt.setParameter(type_id, "junctionModel.jmIgnoreFoeProb", "1")
                vt.setParameter(type_id, "junctionModel.jmIgnoreFoeSpeed", f"{sumo_driver.ignore_foes_below_mps:g}")
            vt.setSpeedFactor(type_id, 1.0)
            vt.setSpeedDeviation(type_id, 0.0)
        route_id = f"__route_{ego_id}"
        libsumo.route.add(route_id, list(route_edges))
        libsumo.vehicle.add(
            ego_id, route_id, typeID=type_id, depart="now", departLane=str(depart_lane),
            departPos=f"{depart_pos_m:g}", departSpeed=f"{depart_speed_mps:g}",
        )
        # a SUMO-driven ego too: placed exactly by move_ego first, no checks until release_ego
        libsumo.vehicle.setSpeedMode(ego_id, SPEED_MODE_IGNORE_ALL)
        libsumo.vehicle.setLaneChangeMode(ego_id, 0)
        self._egos[ego_id] = length_m

    @_sumo_errors
    def release_ego(self, ego_id: str) -> None:
        """Hand an ego added with a ``sumo_driver`` to SUMO's driver models from now on: all
        speed checks on, SUMO's default lane changing, no commanded speed."""
        libsumo.vehicle.setSpeed(ego_id, -1.0)
        libsumo.vehicle.setSpeedMode(ego_id, SPEED_MODE_DEFAULT)
        libsumo.vehicle.setLaneChangeMode(ego_id, LANE_CHANGE_MODE_DEFAULT)

    def has_vehicle(self, vehicle_id: str) -> bool:
        """Whether ``vehicle_id`` (an ego or any other vehicle) is still in the simulation: the
        departed and arrived lists :meth:`step` keeps, no call into SUMO."""
        return vehicle_id in self._egos or vehicle_id in self._vehicles

    @_sumo_errors
    def move_ego(
        self,
        ego_id: str,
        x: float,
        y: float,
        heading_rad: float,
        speed_mps: float,
        *,
        edge_hint: str = "",
        lane_hint: int = -1,
        keep_route: int = KEEP_ROUTE_EXACT,
    ) -> None:
        """Mirror the ego's pose (footprint centre ``x``, ``y`` [m], heading) and speed into SUMO.

        keepRoute (choice) = 3 (:data:`KEEP_ROUTE_EXACT`): the ego stays mapped onto the lanes of
        its own route (internal lanes included), so SUMO drivers behind it see it as their leader
        and junction foes see it on its link, and SUMO keeps the exact commanded x, y even off the
        lane centre (with keepRoute=1 alone it would snap onto the centre line).
        ``setSpeed`` first so SUMO reports (and followers use) the ego's true speed.

        Except off the road: SUMO keeps an exact pose on a lane only while it lies within half the
        lane's width and half the ego's of the lane's centre line; further off, it takes the ego off
        its road network, where no follower and no junction foe sees it. From the step after SUMO
        did so, the ego is mapped onto its route's lanes (keepRoute=1, the lane centre) until its
        pose is back within ``EGO_SNAP_RELEASE_M`` of that limit (:meth:`_ego_keep_route`). Why:
        the ego drove off SUMO's road for up to 10 s on the nominal left turn (its path swerving
        around a queued car, or cutting a turn inside SUMO's internal lane), and two followers
        drove into it (seeds 2090914255, 1809821748 at 60 s; docs/tried/world.md).
        """
        length = self._egos.get(ego_id, EGO_LENGTH_M)
        half = 0.5 * length
        fx = x + half * math.cos(heading_rad)
        fy = y + half * math.sin(heading_rad)
        libsumo.vehicle.setSpeed(ego_id, max(0.0, speed_mps))
        if keep_route == KEEP_ROUTE_EXACT and ego_id in self._egos_inserted:
            keep_route = self._ego_keep_route(ego_id, fx, fy)
        libsumo.vehicle.moveToXY(ego_id, edge_hint, lane_hint, fx, fy,
                                 heading_to_sumo_angle(heading_rad), keep_route)
        self._snapshot = None

    def _ego_keep_route(self, ego_id: str, fx: float, fy: float) -> int:
        """keepRoute for placing the ego's front bumper at ``fx``, ``fy`` (:meth:`move_ego`): exact,
        or mapped onto its route's lanes from the step after SUMO took it off its road until the
        bumper is back within the lane SUMO has it on."""
        lane = libsumo.vehicle.getLaneID(ego_id)
        if lane == "":
            self._egos_snapped.add(ego_id)
        elif ego_id in self._egos_snapped:
            shape = np.asarray(libsumo.lane.getShape(lane), float)
            _, s, _ = project_onto_polyline(shape, (fx, fy))
            off = float(np.hypot(*(point_at(shape, s) - (fx, fy))))
            limit = 0.5 * (libsumo.lane.getWidth(lane) + libsumo.vehicle.getWidth(ego_id))
            if off < limit - EGO_SNAP_RELEASE_M:
                self._egos_snapped.discard(ego_id)
        return KEEP_ROUTE_ON_ROUTE if ego_id in self._egos_snapped else KEEP_ROUTE_EXACT

    @_sumo_errors
    def vehicle_pose(self, vehicle_id: str) -> tuple[float, float, float, float]:
        """(x, y, heading, speed) of any vehicle, ego included, straight from SUMO (centre)."""
        v = libsumo.vehicle
        fx, fy = v.getPosition(vehicle_id)
        heading = math.radians(90.0 - v.getAngle(vehicle_id))
        half = 0.5 * v.getLength(vehicle_id)
        return (fx - half * math.cos(heading), fy - half * math.sin(heading),
                math.atan2(math.sin(heading), math.cos(heading)), v.getSpeed(vehicle_id))

    @_sumo_errors
    def vehicle_size(self, vehicle_id: str) -> tuple[float, float]:
        """(length, width) [m] SUMO uses for a vehicle, ego included."""
        return libsumo.vehicle.getLength(vehicle_id), libsumo.vehicle.getWidth(vehicle_id)

    # --- other vehicles --------------------------------------------------------------------

    @_sumo_errors
    def move_vehicle(self, vehicle_id: str, x: float, y: float, heading_rad: float, *,
                     edge_hint: str = "", lane_hint: int = -1,
                     keep_route: int = KEEP_ROUTE_EXACT) -> None:
        """Place any vehicle by its footprint centre for this step (as :meth:`move_ego`)."""
        half = 0.5 * libsumo.vehicle.getLength(vehicle_id)
        libsumo.vehicle.moveToXY(
            vehicle_id, edge_hint, lane_hint, x + half * math.cos(heading_rad),
            y + half * math.sin(heading_rad), heading_to_sumo_angle(heading_rad), keep_route)
        self._snapshot = None

    @_sumo_errors
    def set_speed(self, vehicle_id: str, speed_mps: float) -> None:
        """Command a speed [m/s] (−1 gives control back to the car-following model)."""
        libsumo.vehicle.setSpeed(vehicle_id, speed_mps)

    @_sumo_errors
    def hold_vehicle(self, vehicle_id: str, holder: str) -> None:
        """Stop a vehicle where it is (its speed 0, braking as SUMO lets it) on behalf of
        ``holder`` (a rule of the world: ``"courtesy"``, ``"letting_out"``); it stays held until
        every holder has released it (:meth:`release_vehicle`). Why shared: two rules commanding
        one vehicle's speed each on their own undid each other's hold — one released a car the
        other had just stopped for the standing ego, and it drove on into the ego's side
        (b_two_lane left, seed 1771952177 of base 20261206)."""
        holders = self._vehicle_holders.setdefault(vehicle_id, set())
        if not holders:
            libsumo.vehicle.setSpeed(vehicle_id, 0.0)
        holders.add(holder)

    @_sumo_errors
    def release_vehicle(self, vehicle_id: str, holder: str) -> None:
        """``holder`` no longer holds the vehicle; once no one does, SUMO's driver model takes its
        speed back. Releasing a vehicle ``holder`` does not hold does nothing."""
        holders = self._vehicle_holders.get(vehicle_id)
        if holders is None or holder not in holders:
            return
        holders.discard(holder)
        if not holders:
            del self._vehicle_holders[vehicle_id]
            libsumo.vehicle.setSpeed(vehicle_id, -1.0)

    def vehicle_holders(self, vehicle_id: str) -> frozenset[str]:
        """Who holds the vehicle now (:meth:`hold_vehicle`; empty: no one)."""
        return frozenset(self._vehicle_holders.get(vehicle_id, ()))

    @_sumo_errors
    def speed_without_traci(self, vehicle_id: str) -> float:
        """The speed [m/s] SUMO's own driver model would choose now (ignoring our commands)."""
        return libsumo.vehicle.getSpeedWithoutTraCI(vehicle_id)

    @_sumo_errors
    def set_speed_factor(self, vehicle_id: str, factor: float) -> None:
        """Desired speed = factor × lane speed limit (capped by the vehicle's max speed)."""
        libsumo.vehicle.setSpeedFactor(vehicle_id, factor)

    @_sumo_errors
    def set_speed_mode(self, vehicle_id: str, mode: int) -> None:
        libsumo.vehicle.setSpeedMode(vehicle_id, mode)

    @_sumo_errors
    def set_max_speed(self, vehicle_id: str, speed_mps: float) -> None:
        libsumo.vehicle.setMaxSpeed(vehicle_id, speed_mps)

    @_sumo_errors
    def set_lane_change_mode(self, vehicle_id: str, mode: int) -> None:
        libsumo.vehicle.setLaneChangeMode(vehicle_id, mode)

    @_sumo_errors
    def lane_change_mode(self, vehicle_id: str) -> int:
        """The vehicle's lane-change mode now (:data:`LANE_CHANGE_MODE_DEFAULT` unless changed)."""
        return libsumo.vehicle.getLaneChangeMode(vehicle_id)

    @_sumo_errors
    def pending_vehicle_ids(self) -> tuple[str, ...]:
        """Vehicles whose departure time has come but which SUMO has not inserted yet (no room on
        their lane); :meth:`remove` takes one out of that queue."""
        return tuple(libsumo.simulation.getPendingVehicles())

    @_sumo_errors
    def vehicle_route(self, vehicle_id: str) -> tuple[str, ...]:
        return tuple(libsumo.vehicle.getRoute(vehicle_id))

    @_sumo_errors
    def vehicle_lane(self, vehicle_id: str) -> str:
        return libsumo.vehicle.getLaneID(vehicle_id)

    @_sumo_errors
    def vehicle_lane_position(self, vehicle_id: str) -> float:
        """[m] of its front bumper along its lane."""
        return libsumo.vehicle.getLanePosition(vehicle_id)

    @_sumo_errors
    def vehicle_next_link(self, vehicle_id: str) -> tuple[str, str] | None:
        """(internal lane, light state) of the next link on the vehicle's way, as SUMO's
        ``getNextLinks`` gives its first; None when it has none ahead on its lane."""
        links = libsumo.vehicle.getNextLinks(vehicle_id)
        if not links:
            return None
        return str(links[0][4]), str(links[0][5])  # (lane, priority, open, foe, via, state, dir, length)

    @_sumo_errors
    def vehicle_class(self, vehicle_id: str) -> str:
        return libsumo.vehicle.getVehicleClass(vehicle_id)

    @_sumo_errors
    def vehicle_type(self, vehicle_id: str) -> str:
        return libsumo.vehicle.getTypeID(vehicle_id)

    @_sumo_errors
    def hold_person(self, person_id: str) -> None:
        """Stop a pedestrian where it is (its speed 0) until :meth:`release_person`."""
        libsumo.person.setSpeed(person_id, 0.0)

    @_sumo_errors
    def person_lane(self, person_id: str) -> str:
        """The lane (a crossing, walking area or sidewalk) a pedestrian is on now."""
        return libsumo.person.getLaneID(person_id)

    @_sumo_errors
    def release_person(self, person_id: str) -> None:
        """Let a held pedestrian walk on at its own speed."""
        libsumo.person.setSpeed(person_id, -1.0)

    @_sumo_errors
    def remove(self, participant_id: str) -> None:
        """Take a vehicle or a person out of the simulation now."""
        if participant_id in self._persons:
            libsumo.person.remove(participant_id)
            self._forget(participant_id, self._persons)
        else:
            libsumo.vehicle.remove(participant_id)
            self._forget(participant_id, self._vehicles)
        self._snapshot = None

    @_sumo_errors
    def collisions(self) -> list[tuple[str, str, str]]:
        """Collisions SUMO detected in the last step: (collider, victim, type)."""
        return [(c.collider, c.victim, c.type) for c in libsumo.simulation.getCollisions()]

    @_sumo_errors
    def standing_on(self, vehicle_lanes: tuple[str, ...],
                    person_lanes: tuple[str, ...]) -> list[tuple[str, float, str]]:
        """(id, how long it has stood [s], lane) of every participant but the ego now standing
        (SUMO's waiting time: below 0.1 m/s since it last moved): vehicles on a lane whose id
        starts with one of ``vehicle_lanes``, persons on one that starts with ``person_lanes``."""
        out: list[tuple[str, float, str]] = []
        for domain, ids, prefixes in ((libsumo.vehicle, self._vehicles, vehicle_lanes),
                                      (libsumo.person, self._persons, person_lanes)):
            if not prefixes:
                continue
            for pid in ids:
                waited = domain.getWaitingTime(pid)
                if waited > 0.0:
                    lane = domain.getLaneID(pid)
                    if lane.startswith(prefixes):
                        out.append((pid, waited, lane))
        return out

    @_sumo_errors
    def standing_s(self, participant_id: str) -> float:
        """How long a vehicle or person has stood [s] (0 while it moves)."""
        if participant_id in self._persons:
            return libsumo.person.getWaitingTime(participant_id)
        return libsumo.vehicle.getWaitingTime(participant_id)

    # --- traffic lights --------------------------------------------------------------------

    @_sumo_errors
    def tl_ids(self) -> tuple[str, ...]:
        return tuple(libsumo.trafficlight.getIDList())

    @_sumo_errors
    def tl_state(self, tl_id: str) -> str:
        """The signal state string now, one character per link index (SUMO's rRgGyYuoOs)."""
        return libsumo.trafficlight.getRedYellowGreenState(tl_id)

    @_sumo_errors
    def tl_phase(self, tl_id: str) -> int:
        return libsumo.trafficlight.getPhase(tl_id)

    @_sumo_errors
    def tl_time_to_switch_s(self, tl_id: str) -> float:
        """Seconds until the current phase ends."""
        return libsumo.trafficlight.getNextSwitch(tl_id) - libsumo.simulation.getTime()

    @_sumo_errors
    def tl_program(self, tl_id: str) -> str:
        """The id of the program the light runs now (of several a net may hold)."""
        return libsumo.trafficlight.getProgram(tl_id)

    @_sumo_errors
    def set_tl_program(self, tl_id: str, program_id: str) -> None:
        """Switch the light to another of its programs (it starts that program's phase 0)."""
        libsumo.trafficlight.setProgram(tl_id, program_id)

    @_sumo_errors
    def set_tl_phase(self, tl_id: str, phase_index: int) -> None:
        libsumo.trafficlight.setPhase(tl_id, phase_index)

    @_sumo_errors
    def set_tl_phase_duration(self, tl_id: str, remaining_s: float) -> None:
        """Make the *current* phase end ``remaining_s`` from now (later cycles are unchanged)."""
        libsumo.trafficlight.setPhaseDuration(tl_id, remaining_s)

    @_sumo_errors
    def tl_controlled_links(self, tl_id: str) -> list[list[tuple[str, str, str]]]:
        """Per link index, the (from lane, to lane, via lane) triples it controls."""
        return [[tuple(t) for t in links] for links in libsumo.trafficlight.getControlledLinks(tl_id)]

    # --- lanes -----------------------------------------------------------------------------

    @_sumo_errors
    def lane_ids(self) -> tuple[str, ...]:
        """Every lane of the network, internal lanes (":<junction>_…") included."""
        return tuple(libsumo.lane.getIDList())

    @_sumo_errors
    def lane_successors(self, lane_id: str) -> tuple[str, ...]:
        """The lanes a vehicle on ``lane_id`` drives onto next, one per link: the link's internal
        lane where it has one (a left turn's part beyond its waiting point), else the lane it
        leads to."""
        return tuple(str(link[4] or link[0]) for link in libsumo.lane.getLinks(lane_id))

    @_sumo_errors
    def lane_next(self, lane_id: str) -> str | None:
        """The lane a vehicle on ``lane_id`` drives onto next along its first link: the link's
        internal lane where it has one, else the lane it leads to; None without a link. For an
        internal lane, which has one link, its way on."""
        links = libsumo.lane.getLinks(lane_id)
        if not links:
            return None
        return str(links[0][4] or links[0][0])

    @_sumo_errors
    def lane_vehicle_ids(self, lane_id: str) -> tuple[str, ...]:
        """The vehicles (cars and bicycles) on ``lane_id`` after the last step."""
        return tuple(libsumo.lane.getLastStepVehicleIDs(lane_id))

    @_sumo_errors
    def lane_halting(self, lane_id: str) -> int:
        """How many vehicles on ``lane_id`` stood (below 0.1 m/s) in the last step."""
        return int(libsumo.lane.getLastStepHaltingNumber(lane_id))

    @_sumo_errors
    def lane_max_speed(self, lane_id: str) -> float:
        return libsumo.lane.getMaxSpeed(lane_id)

    @_sumo_errors
    def set_lane_max_speed(self, lane_id: str, speed_mps: float) -> None:
        libsumo.lane.setMaxSpeed(lane_id, speed_mps)

    @_sumo_errors
    def lane_allowed(self, lane_id: str) -> tuple[str, ...]:
        return tuple(libsumo.lane.getAllowed(lane_id))

    @_sumo_errors
    def forbid_lane_changes(self, lane_ids: Iterable[str]) -> None:
        """No vehicle changes lanes from any of ``lane_ids``, to either side, from now on (SUMO's
        lane change permissions, left to the class ``ignoring`` alone, which no participant has)."""
        for lane in lane_ids:
            libsumo.lane.setChangePermissions(lane, ["ignoring"], 1)  # SUMO then lists no class
            libsumo.lane.setChangePermissions(lane, ["ignoring"], -1)

    @_sumo_errors
    def lane_length(self, lane_id: str) -> float:
        return libsumo.lane.getLength(lane_id)

    @_sumo_errors
    def lane_shape(self, lane_id: str) -> NDArray[np.float64]:
        return np.array(libsumo.lane.getShape(lane_id), dtype=np.float64)


def active_session() -> SumoSession | None:
    """The session running in this process, if any."""
    return _ACTIVE
