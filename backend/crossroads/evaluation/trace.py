"""The trace of an episode: everything needed to replay and show it, compact and serialisable.

A :class:`Trace` is a header (JSON: scenario, seed, network, task, candidate paths, Δt, result)
plus per-step frames stored **columnar**: one numpy array per field, the participants of all steps
concatenated (CSR style: ``offsets[i]:offsets[i+1]`` are the rows of step ``i``), participant
ids and signal strings interned in tables. :class:`TraceRecorder` builds one step by step.

File format (``save``/``load``): one ``numpy.savez_compressed`` archive (zip + deflate; suggested
suffix ``.trace.npz``), no pickles, readable by any numpy. Arrays (T steps, M participant rows,
K perceived rows):

=====================  ============  =========  =====================================================
key                    shape         dtype      meaning
=====================  ============  =========  =====================================================
header                 (bytes,)      uint8      UTF-8 JSON of the header (``trace_version`` = 1)
ids                    (P,)          str        participant id table (first appearance order)
signal_states          (S,)          str        table of the tlLogic state strings met
time_s                 (T,)          float64    [s] ego time of the step
signal                 (T,)          int32      index into ``signal_states``
light                  (T,)          uint8      ego's light: index into ``LIGHTS``
light_remaining_s      (T,)          float32    [s] until the ego's light changes
speed_mode             (T,)          uint8      index into ``SPEED_MODES`` ("none": no decision)
path_index             (T,)          int16      chosen candidate (-1: no decision)
shield                 (T,)          int8       the safety shield: 1 braking, 0 not, -1 no shield or no decision
                                                (optional: traces written before it read as all -1)
ego                    (T, 8)        float32    [p_x m, p_y m, v_x m/s, v_y m/s, φ rad, ω rad/s, δ rad, a m/s²]
action                 (T, 2)        float32    [Δδ rad/s, Δa m/s³]; NaN when no decision
offsets                (T+1,)        int64      row range of each step
pid                    (M,)          int32      index into ``ids``
kind                   (M,)          uint8      index into ``KINDS``
x, y                   (M,)          float32    [m] footprint centre, network frame
heading                (M,)          float32    [rad] CCW from +x
speed                  (M,)          float32    [m/s]
length, width          (M,)          float32    [m]
abnormal               (M,)          bool       over-speeding / rounding vehicle (SPEC §8)
perceived              (M,)          bool       covered by a sensor this step
obs                    (K, 6)        float32    noisy [p_x, p_y, v, φ, L, W] of the perceived rows, in row order
=====================  ============  =========  =====================================================

Precision: floats are stored as float32 (≈7 significant digits: 0.1 mm at 1 km), time as float64;
a saved and loaded trace equals its source exactly once recorded (recording casts to float32).
JSON views (:meth:`Trace.frame`, :meth:`Trace.to_json`) round to ``JSON_DECIMALS`` decimals.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crossroads.constants import EGO_STATE_DIM, OTHER_STATE_DIM, PARTICIPANT_KINDS, SIM_STEP_S

TRACE_VERSION = 1
LIGHTS: tuple[str, ...] = ("green", "yellow", "red")
SPEED_MODES: tuple[str, ...] = ("pass", "stop", "none")  # "none": a frame without a decision
KINDS: tuple[str, ...] = PARTICIPANT_KINDS
ACTION_DIM = 2  # [Δδ, Δa]
JSON_DECIMALS = 4  # decimals of floats in the JSON views (0.1 mm, 0.1 mrad)
PARTICIPANT_FLOATS = ("x", "y", "heading", "speed", "length", "width")

# Keys of the per-step and per-row arrays, in file order (the tables and header come first).
STEP_KEYS = ("time_s", "signal", "light", "light_remaining_s", "speed_mode", "path_index",
             "ego", "action", "offsets")
ROW_KEYS = ("pid", "kind", *PARTICIPANT_FLOATS, "abnormal", "perceived", "obs")
SHIELD_KEY = "shield"  # optional per-step array (the module docstring's table)
NO_SHIELD = -1


def _code(table: Sequence[str], value: str, what: str) -> int:
    try:
        return table.index(value)
    except ValueError:
        raise ValueError(f"unknown {what} {value!r}; expected one of {', '.join(table)}") from None


def _rounded(values: NDArray[Any]) -> Any:
    """float32 → Python floats rounded for JSON (NaN → None, JSON has no NaN)."""
    out = np.round(values.astype(np.float64), JSON_DECIMALS)
    if np.isnan(out).any():
        return np.where(np.isnan(out), None, out).tolist()
    return out.tolist()


@dataclass(eq=False)
class Trace:
    """An episode's trace (see the module docstring for every array, its unit and dtype)."""

    header: dict[str, Any]
    arrays: dict[str, NDArray[Any]]

    # --- size and access ----------------------------------------------------------------------

    def __len__(self) -> int:
        """Number of steps (frames)."""
        return len(self.arrays["time_s"])

    @property
    def ids(self) -> NDArray[np.str_]:
        """Participant id table."""
        return self.arrays["ids"]

    @property
    def n_rows(self) -> int:
        """Participant rows over all steps (M)."""
        return len(self.arrays["pid"])

    def rows(self, i: int) -> slice:
        """Rows of step ``i`` in the per-row arrays."""
        off = self.arrays["offsets"]
        return slice(int(off[i]), int(off[i + 1]))

    def steps_of(self, participant_id: str) -> NDArray[np.int64]:
        """The steps at which a participant is present (empty if never)."""
        where = np.flatnonzero(self.ids == participant_id)
        if len(where) == 0:
            return np.zeros(0, dtype=np.int64)
        rows = np.flatnonzero(self.arrays["pid"] == where[0])
        return np.searchsorted(self.arrays["offsets"], rows, side="right") - 1

    def frame(self, i: int) -> dict[str, Any]:
        """Step ``i`` as a JSON-ready dict (floats rounded to ``JSON_DECIMALS``)::

            {"i", "t", "signal": {"state", "light", "remaining_s"}, "speed_mode", "path_index",
             "shield_braking": bool | None, "ego": [8], "action": [2] | [None, None],
             "participants": [{"id", "kind", "x", "y", "heading", "speed", "length", "width",
                               "abnormal", "perceived", "obs": [6] | None}, ...]}
        """
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"frame {i} out of range for a trace of {n} steps")
        i %= n
        a = self.arrays
        sl = self.rows(i)
        perceived = a["perceived"]
        # Observations are stored for perceived rows only: their position = perceived rows before.
        k0 = int(np.count_nonzero(perceived[: sl.start]))
        obs = _rounded(a["obs"][k0: k0 + int(np.count_nonzero(perceived[sl]))])
        floats = {key: _rounded(a[key][sl]) for key in PARTICIPANT_FLOATS}
        ids, kinds = a["ids"][a["pid"][sl]], a["kind"][sl]
        flags_ab, flags_pc = a["abnormal"][sl].tolist(), perceived[sl].tolist()
        participants = []
        k = 0
        for j in range(sl.stop - sl.start):
            p = {"id": str(ids[j]), "kind": KINDS[kinds[j]]}
            p.update({key: floats[key][j] for key in PARTICIPANT_FLOATS})
            p["abnormal"] = flags_ab[j]
            p["perceived"] = flags_pc[j]
            if flags_pc[j]:
                p["obs"] = obs[k]
                k += 1
            else:
                p["obs"] = None
            participants.append(p)
        return {
            "i": i,
            "t": round(float(a["time_s"][i]), 6),
            "signal": {
                "state": str(a["signal_states"][a["signal"][i]]),
                "light": LIGHTS[a["light"][i]],
                "remaining_s": _rounded(a["light_remaining_s"][i]),
            },
            "speed_mode": SPEED_MODES[a["speed_mode"][i]],
            "path_index": int(a["path_index"][i]),
            "shield_braking": None if a[SHIELD_KEY][i] == NO_SHIELD else bool(a[SHIELD_KEY][i]),
            "ego": _rounded(a["ego"][i]),
            "action": _rounded(a["action"][i]),
            "participants": participants,
        }

    def to_json(self, stride: int = 1) -> dict[str, Any]:
        """``{"header": ..., "frames": [frame(i) ...]}`` for the API: every ``stride``-th step,
        and always the last one (where the episode's outcome shows)."""
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        indices = list(range(0, len(self), stride))
        if len(self) and indices[-1] != len(self) - 1:
            indices.append(len(self) - 1)
        return {"header": self.header, "frames": [self.frame(i) for i in indices]}

    # --- files ------------------------------------------------------------------------------------

    def save(self, path: str | Path) -> Path:
        """Write one compressed ``.npz`` (exactly this path; no suffix is added)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        header = np.frombuffer(json.dumps(self.header, allow_nan=False).encode("utf-8"), dtype=np.uint8)
        with path.open("wb") as f:
            np.savez_compressed(f, header=header, **self.arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Trace:
        """Read a file written by :meth:`save` (no pickles are ever loaded)."""
        with np.load(Path(path), allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
        header = json.loads(arrays.pop("header").tobytes().decode("utf-8"))
        version = header.get("trace_version")
        if version != TRACE_VERSION:
            raise ValueError(f"{path}: trace_version {version!r}; this Crossroads reads {TRACE_VERSION}")
        missing = {"ids", "signal_states", *STEP_KEYS, *ROW_KEYS} - set(arrays)
        if missing:
            raise ValueError(f"{path}: not a trace, missing arrays {sorted(missing)}")
        if SHIELD_KEY not in arrays:  # written before the shield was recorded
            arrays[SHIELD_KEY] = np.full(len(arrays["time_s"]), NO_SHIELD, np.int8)
        return cls(header, arrays)

    def nbytes(self) -> int:
        """Uncompressed size of the arrays [bytes] (the file is smaller)."""
        return int(sum(a.nbytes for a in self.arrays.values()))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Trace):
            return NotImplemented
        if self.header != other.header or set(self.arrays) != set(other.arrays):
            return False
        for key, a in self.arrays.items():
            b = other.arrays[key]
            if a.dtype != b.dtype or a.shape != b.shape:
                return False
            nan_ok = a.dtype.kind == "f"
            if not np.array_equal(a, b, equal_nan=nan_ok):
                return False
        return True

    __hash__ = None  # type: ignore[assignment]  # mutable arrays


@dataclass
class TraceRecorder:
    """Builds a :class:`Trace` one step at a time (the episode runner calls it).

    Plain use::

        rec = TraceRecorder()
        rec.header(scenario="overspeed-10", seed=123, net="/path/net.net.xml", junction="J0",
                   task="left", candidates=[c.to_json() for c in candidates], dt_s=0.1)
        for each step: rec.record(time_s=..., signal_state=..., ...)   # see record()
        rec.finish(outcome="passed", time_s=12.3)
        trace = rec.trace()

    Adapters for :mod:`crossroads.evaluation.episode`: ``start(world, seed)``,
    ``record(observation, decision)`` (positional) and ``finish(observation, outcome)``.
    """

    _header: dict[str, Any] = field(default_factory=dict)
    _ids: dict[str, int] = field(default_factory=dict)
    _signals: dict[str, int] = field(default_factory=dict)
    _steps: dict[str, list[Any]] = field(default_factory=lambda: {k: [] for k in (*STEP_KEYS[:-1], SHIELD_KEY)})
    _rows: dict[str, list[NDArray[Any]]] = field(default_factory=lambda: {k: [] for k in ROW_KEYS})
    _counts: list[int] = field(default_factory=list)

    # --- header -----------------------------------------------------------------------------------

    def header(self, *, scenario: str, seed: int, net: str | Path, task: str,
               candidates: Sequence[Any] = (), junction: str | None = None,
               dt_s: float = SIM_STEP_S, **extra: Any) -> None:
        """Set the header.

        ``scenario``: scenario name; ``seed``: the episode's seed; ``net``: the network reference
        (path of the .net.xml or a catalogue name, stored as a string); ``junction``: junction id;
        ``task``: left | straight | right; ``candidates``: the candidate paths, as JSON dicts or
        objects with ``to_json()`` (e.g. :class:`crossroads.planning.CandidatePath`); ``dt_s`` [s]:
        the step; ``extra``: anything JSON-serialisable to keep (policy name, content hash, ...).
        """
        self._header = {
            "trace_version": TRACE_VERSION,
            "scenario": scenario,
            "seed": int(seed),
            "net": str(net),
            "junction": junction,
            "task": task,
            "dt_s": float(dt_s),
            "candidates": [c if isinstance(c, Mapping) else c.to_json() for c in candidates],
            **extra,
        }
        json.dumps(self._header, allow_nan=False)  # fail now, not at save time

    def start(self, world: Any, seed: int, scenario: str | None = None) -> None:
        """Header from a :class:`crossroads.sim.world.World` (duck-typed) and the episode's seed."""
        config = world.config
        self.header(
            scenario=scenario if scenario is not None else str(getattr(world, "scenario_name", "")),
            seed=seed, net=config.net_file, junction=world.junction.id, task=config.task,
            candidates=world.candidates, dt_s=SIM_STEP_S,
            approach=getattr(getattr(world, "approach", None), "id", None),
        )

    # --- steps ------------------------------------------------------------------------------------

    def record(self, observation: Any = None, decision: Any = None, truth: Any = None, /, **step: Any) -> None:
        """Append one step: ``record(observation, decision, truth)`` (world objects: the
        controller's Observation and Decision, the world's GroundTruth) or keywords.

        Keywords (arrays are anything ``numpy.asarray`` takes; n = participants this step):

        * ``time_s`` float [s]: ego time of the step.
        * ``signal_state`` str: the whole tlLogic state string (e.g. ``"GGgrrrGGgrrr"``).
        * ``light`` str: the ego's light, ``"green" | "yellow" | "red"``.
        * ``light_remaining_s`` float [s]: until the ego's light changes.
        * ``speed_mode`` str: ``"pass" | "stop"``; ``"none"`` (or None) when nothing was decided.
        * ``path_index`` int: index of the chosen candidate path, -1 for none.
        * ``shield_braking`` bool or None (default): the safety shield braked this step; None when
          the controller has no shield (or nothing was decided).
        * ``ego`` (8,): ``[p_x m, p_y m, v_x m/s, v_y m/s, φ rad, ω rad/s, δ rad, a m/s²]``.
        * ``action`` (2,) or None: ``[Δδ rad/s, Δa m/s³]``; None is stored as NaN.
        * ``ids`` (n,) str; ``kinds`` (n,) str in ``"vehicle" | "cyclist" | "pedestrian"``.
        * ``x``, ``y`` (n,) [m] footprint centres; ``heading`` (n,) [rad] CCW from +x;
          ``speed`` (n,) [m/s]; ``length``, ``width`` (n,) [m] — the true values.
        * ``abnormal`` (n,) bool, default all False: over-speeding / rounding vehicles.
        * ``perceived`` (n,) bool, default all False: covered by a sensor.
        * ``observations``: the noisy ``[p_x, p_y, v, φ, L, W]`` of the perceived participants,
          either (k, 6) for the k perceived rows in participant order, or (n, 6) aligned with
          ``ids`` (rows of unperceived participants are ignored). Default: none perceived.
        """
        if observation is not None:
            if step:
                raise TypeError("record(): give either (observation, decision, truth) or keywords, not both")
            step = _step_of_observation(observation, truth, decision)
        self._record(**step)

    def _record(self, *, time_s: float, signal_state: str, light: str, light_remaining_s: float,
                speed_mode: str | None, path_index: int, ego: ArrayLike, action: ArrayLike | None,
                shield_braking: bool | None = None,
                ids: ArrayLike = (), kinds: ArrayLike = (), x: ArrayLike = (), y: ArrayLike = (),
                heading: ArrayLike = (), speed: ArrayLike = (), length: ArrayLike = (),
                width: ArrayLike = (), abnormal: ArrayLike | None = None,
                perceived: ArrayLike | None = None, observations: ArrayLike | None = None) -> None:
        ego_a = np.asarray(ego, dtype=np.float32).reshape(-1)
        if ego_a.shape != (EGO_STATE_DIM,):
            raise ValueError(f"ego must have {EGO_STATE_DIM} values, got shape {np.shape(ego)}")
        act = (np.full(ACTION_DIM, np.nan, np.float32) if action is None
               else np.asarray(action, dtype=np.float32).reshape(-1))
        if act.shape != (ACTION_DIM,):
            raise ValueError(f"action must have {ACTION_DIM} values, got shape {np.shape(action)}")
        id_list = [str(v) for v in np.asarray(ids).reshape(-1)]
        n = len(id_list)
        if len(set(id_list)) != n:
            raise ValueError("ids must be unique within a step")
        cols = {key: np.asarray(val, dtype=np.float32).reshape(-1) for key, val in
                zip(PARTICIPANT_FLOATS, (x, y, heading, speed, length, width))}
        kind_codes = np.array([_code(KINDS, str(k), "kind") for k in np.asarray(kinds).reshape(-1)],
                              dtype=np.uint8)
        ab = np.zeros(n, bool) if abnormal is None else np.asarray(abnormal, dtype=bool).reshape(-1)
        pc = np.zeros(n, bool) if perceived is None else np.asarray(perceived, dtype=bool).reshape(-1)
        for key, arr in {**cols, "kinds": kind_codes, "abnormal": ab, "perceived": pc}.items():
            if len(arr) != n:
                raise ValueError(f"{key} has {len(arr)} values for {n} ids")
        k = int(np.count_nonzero(pc))
        if observations is None:
            if k:
                raise ValueError(f"{k} participants are perceived but no observations were given")
            obs = np.zeros((0, OTHER_STATE_DIM), np.float32)
        else:
            obs = np.asarray(observations, dtype=np.float32).reshape(-1, OTHER_STATE_DIM)
            if len(obs) == n and n != k:
                obs = obs[pc]  # aligned with ids: keep the perceived rows
            if len(obs) != k:
                raise ValueError(f"observations has {len(obs)} rows for {k} perceived of {n} participants")

        s = self._steps
        s["time_s"].append(float(time_s))
        s["signal"].append(self._signals.setdefault(str(signal_state), len(self._signals)))
        s["light"].append(_code(LIGHTS, str(light), "light"))
        s["light_remaining_s"].append(float(light_remaining_s))
        s["speed_mode"].append(_code(SPEED_MODES, speed_mode or "none", "speed_mode"))
        s["path_index"].append(int(path_index))
        s[SHIELD_KEY].append(NO_SHIELD if shield_braking is None else int(bool(shield_braking)))
        s["ego"].append(ego_a)
        s["action"].append(act)
        r = self._rows
        r["pid"].append(np.array([self._ids.setdefault(i, len(self._ids)) for i in id_list], np.int32))
        r["kind"].append(kind_codes)
        for key, arr in cols.items():
            r[key].append(arr)
        r["abnormal"].append(ab)
        r["perceived"].append(pc)
        r["obs"].append(obs)
        self._counts.append(n)

    def finish(self, observation: Any = None, outcome: Any = None, truth: Any = None, /, **result: Any) -> None:
        """End the episode. ``observation`` and ``truth`` (optional): the state after the last
        step, recorded as a frame without a decision (so a collision shows); ``outcome``
        (optional): an object with ``kind``, ``time_s``, ``detail``, ``other_kind`` (the world's
        Outcome) stored as ``header["result"]``, updated by the keywords ``result``."""
        if observation is not None:
            self._record(**_step_of_observation(observation, truth, None))
        info: dict[str, Any] = {}
        if outcome is not None:
            info = {key: getattr(outcome, key) for key in ("kind", "time_s", "detail", "other_kind")
                    if hasattr(outcome, key)}
        info.update(result)
        if info:
            self._header["result"] = info
            json.dumps(self._header, allow_nan=False)

    def __len__(self) -> int:
        return len(self._counts)

    def trace(self) -> Trace:
        """The trace recorded so far (the recorder may go on recording)."""
        if not self._header:
            raise ValueError("TraceRecorder.header() (or start()) was never called")
        s, r = self._steps, self._rows
        n_steps = len(self._counts)

        def cat(parts: list[NDArray[Any]], dtype: Any, width: int | None = None) -> NDArray[Any]:
            if parts:
                return np.concatenate(parts).astype(dtype, copy=False)
            return np.zeros((0,) if width is None else (0, width), dtype)

        arrays: dict[str, NDArray[Any]] = {
            "ids": np.array(list(self._ids), dtype=np.str_),
            "signal_states": np.array(list(self._signals), dtype=np.str_),
            "time_s": np.array(s["time_s"], np.float64),
            "signal": np.array(s["signal"], np.int32),
            "light": np.array(s["light"], np.uint8),
            "light_remaining_s": np.array(s["light_remaining_s"], np.float32),
            "speed_mode": np.array(s["speed_mode"], np.uint8),
            "path_index": np.array(s["path_index"], np.int16),
            SHIELD_KEY: np.array(s[SHIELD_KEY], np.int8),
            "ego": np.array(s["ego"], np.float32).reshape(n_steps, EGO_STATE_DIM),
            "action": np.array(s["action"], np.float32).reshape(n_steps, ACTION_DIM),
            "offsets": np.concatenate([[0], np.cumsum(self._counts, dtype=np.int64)]).astype(np.int64),
            "pid": cat(r["pid"], np.int32),
            "kind": cat(r["kind"], np.uint8),
            **{key: cat(r[key], np.float32) for key in PARTICIPANT_FLOATS},
            "abnormal": cat(r["abnormal"], bool),
            "perceived": cat(r["perceived"], bool),
            "obs": cat(r["obs"], np.float32, OTHER_STATE_DIM).reshape(-1, OTHER_STATE_DIM),
        }
        return Trace(dict(self._header), arrays)


def _step_of_observation(observation: Any, truth: Any, decision: Any) -> dict[str, Any]:
    """Keywords of :meth:`TraceRecorder.record` from a world Observation and GroundTruth and a
    controller Decision (duck-typed: :mod:`crossroads.sim.observation`,
    :mod:`crossroads.idc.controller`)."""
    if truth is None:
        raise TypeError("record(observation, decision, truth): the trace keeps the true state (World.truth)")
    snap = truth.participants
    n = len(snap.ids)
    perceived = np.zeros(n, dtype=bool)
    obs = np.zeros((n, OTHER_STATE_DIM), dtype=np.float32)
    rows = np.asarray(observation.perceived.rows, dtype=np.int64)
    if len(rows):
        perceived[rows] = True
        obs[rows] = np.asarray(observation.perceived.observations, dtype=np.float32)
    abnormal_ids = truth.abnormal_ids
    abnormal = np.array([str(i) in abnormal_ids for i in snap.ids], dtype=bool)
    light = observation.light
    return {
        "time_s": float(observation.time_s),
        "signal_state": light.state,
        "light": light.light,
        "light_remaining_s": float(light.remaining_s),
        "speed_mode": None if decision is None else decision.speed_mode,
        "path_index": -1 if decision is None else int(decision.path_index),
        "shield_braking": None if decision is None else getattr(decision, "shield_braking", None),
        "ego": observation.ego,
        "action": None if decision is None else decision.action,
        "ids": snap.ids, "kinds": snap.kind, "x": snap.x, "y": snap.y, "heading": snap.heading,
        "speed": snap.speed, "length": snap.length, "width": snap.width,
        "abnormal": abnormal, "perceived": perceived, "observations": obs,
    }
