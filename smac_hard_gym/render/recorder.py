"""Episode files: record a battle step by step, save it as one compressed ``.npz``, load it back and render it.

Frame ``t`` is the battle after ``t`` env steps (frame 0: the reset state). With it go the actions that led to it and
the reward received for that step (none for frame 0), and the opponent's name. A file holds, as plain arrays (no
pickle):

=================  ==========  ============================================================================
key                shape       what
=================  ==========  ============================================================================
``meta``           bytes       JSON: format, version, map name and size, step_mul, unit names, user metadata
``side``           (U,)        int8, RED 0 / BLUE 1 per unit slot
``pathable``       (X, Y)      bool terrain grid, so a replay needs no map file
``cliff``          (X, Y)      float32 cliff levels
``loop``/``step``  (T,)        game loop and env step of each frame
unit fields        (T, U)      ``x y health shield energy`` float32, ``alive burst`` bool, ``fired_at`` int16
``rewards``        (T, K)      float32, NaN where none was given (absent if no frame had one)
``opponent``       (T,)        int16 index into ``meta["opponents"]``, -1 when unknown
``actions...``     (T, ...)    each action stream given to :meth:`EpisodeRecorder.capture` (-1 / NaN = none)
=================  ==========  ============================================================================
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED, Commands
from smac_hard_gym.engine.units import UNITS, unit_index
from smac_hard_gym.files import atomic_write

FORMAT = "smac-hard-gym-episode"
FORMAT_VERSION = 1
UNIT_FIELDS = {
    "x": np.float32, "y": np.float32, "health": np.float32, "shield": np.float32, "energy": np.float32,
    "alive": np.bool_, "burst": np.bool_, "fired_at": np.int16,
}
_COMMAND_FIELDS = {"kind": np.int8, "target": np.int16, "x": np.float32, "y": np.float32}


class EpisodeError(ValueError):
    """An episode file or a capture is malformed (the message names the file or the value)."""


class MapTerrain(NamedTuple):
    """The map facts a :class:`~smac_hard_gym.render.BattleRenderer` needs, as stored in an episode file."""

    name: str
    size: tuple[int, int]
    pathable: np.ndarray
    cliff: np.ndarray


class EpisodeFrame(NamedTuple):
    """One recorded frame as a one-battle state (arrays (1, U)), which a renderer draws like a live state."""

    utype: np.ndarray
    side: np.ndarray
    alive: np.ndarray
    x: np.ndarray
    y: np.ndarray
    health: np.ndarray
    shield: np.ndarray
    energy: np.ndarray
    fired_at: np.ndarray
    burst: np.ndarray
    loop: np.ndarray  # (1,)


@dataclass(frozen=True)
class Episode:
    """A loaded episode: ``len(episode)`` frames of every unit, plus rewards, actions and opponents per frame."""

    terrain: MapTerrain
    step_mul: int
    unit_names: tuple[str, ...]  # unit table keys per slot ("marine_rl")
    utype: np.ndarray  # (U,) rows of this install's unit table
    side: np.ndarray  # (U,)
    loop: np.ndarray  # (T,)
    step: np.ndarray  # (T,)
    units: dict[str, np.ndarray]  # UNIT_FIELDS -> (T, U)
    rewards: np.ndarray | None  # (T, K)
    opponent: np.ndarray  # (T,) index into opponents, -1 = unknown
    opponents: tuple[str, ...]
    actions: dict[str, np.ndarray] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.loop)

    def __repr__(self) -> str:
        return (f"Episode(map={self.map_name!r}, frames={len(self)}, units={len(self.utype)}, "
                f"opponents={list(self.opponents)})")

    @property
    def map_name(self) -> str:
        return self.terrain.name

    @property
    def n_red(self) -> int:
        return int(np.sum(self.side == RED))

    @property
    def n_blue(self) -> int:
        return int(np.sum(self.side == BLUE))

    def opponent_at(self, t: int) -> str | None:
        k = int(self.opponent[t])
        return self.opponents[k] if k >= 0 else None

    def frame(self, t: int) -> EpisodeFrame:
        """Frame ``t`` as a one-battle state for :meth:`BattleRenderer.render`."""
        if not -len(self) <= t < len(self):
            raise IndexError(f"frame {t} out of range for an episode of {len(self)} frames")
        t = range(len(self))[t]
        u = {name: values[t][None] for name, values in self.units.items()}
        return EpisodeFrame(utype=self.utype[None], side=self.side[None], loop=self.loop[t: t + 1], **u)

    def render(self, renderer: Any = None, scale: int | None = None) -> Iterator[np.ndarray]:
        """Yield every frame drawn by ``renderer`` (default: a new renderer of the stored terrain at ``scale``)."""
        if renderer is None:
            from smac_hard_gym.render.renderer import BattleRenderer

            renderer = BattleRenderer(self.terrain, scale=scale, step_mul=self.step_mul)
        for t in range(len(self)):
            yield renderer.render(self.frame(t), 0, int(self.step[t]), self.opponent_at(t))


class EpisodeRecorder:
    """Collects one battle's frames with :meth:`capture` and writes them with :meth:`save`.

    >>> from smac_hard_gym.engine import BattleEngine
    >>> engine = BattleEngine("3m")
    >>> recorder = EpisodeRecorder(engine.spec, step_mul=engine.step_mul)
    >>> recorder.capture(engine.state, battle=0, opponent="base")
    >>> engine.step(); recorder.capture(engine.state, battle=0, rewards=0.0, actions=engine.commands)
    >>> len(recorder), recorder.to_episode().units["x"].shape
    (2, (2, 6))
    """

    def __init__(self, spec: Any, *, step_mul: int = 8, metadata: Mapping[str, Any] | None = None) -> None:
        if isinstance(spec, (str, os.PathLike)):
            from smac_hard_gym.maps import load_map

            spec = load_map(spec)
        self.spec = spec
        self.step_mul = int(step_mul)
        self.metadata: dict[str, Any] = dict(metadata or {})
        self.clear()

    def __len__(self) -> int:
        return len(self._loop)

    def clear(self) -> None:
        """Forget every captured frame (keep the map and metadata)."""
        self._utype: np.ndarray | None = None
        self._side: np.ndarray | None = None
        self._units: dict[str, list[np.ndarray]] = {name: [] for name in UNIT_FIELDS}
        self._loop: list[int] = []
        self._step: list[int] = []
        self._rewards: list[np.ndarray | None] = []
        self._actions: list[dict[str, np.ndarray]] = []
        self._opponents: list[str | None] = []

    def capture(self, state: Any, battle: int = 0, step: int | None = None, rewards: Any = None,
                actions: Any = None, opponent: str | None = None) -> None:
        """Append battle ``battle`` of ``state`` as the next frame.

        ``step`` defaults to the number of frames captured before. ``rewards`` is a number or a fixed-length
        vector (e.g. per side). ``actions`` is an array for this battle (SMAC actions per agent), a batched
        :class:`~smac_hard_gym.engine.state.Commands` (its row ``battle`` is kept), or a mapping of names to either.
        """
        n_battles = np.shape(state.x)[0]
        if not isinstance(battle, (int, np.integer)) or not 0 <= battle < n_battles:
            raise EpisodeError(f"battle must be an int in 0..{n_battles - 1}, got {battle!r}")
        utype, side = np.asarray(state.utype[battle]), np.asarray(state.side[battle])
        if self._utype is None:
            self._utype, self._side = utype.astype(np.int32), side.astype(np.int8)
        elif utype.shape != self._utype.shape or np.any(utype != self._utype) or np.any(side != self._side):
            raise EpisodeError("the units changed between captures (another map or battle?); "
                               "use one recorder per episode or call clear() first")
        reward = None if rewards is None else np.atleast_1d(np.asarray(rewards, dtype=np.float32)).ravel()
        first = next((r for r in self._rewards if r is not None), None)
        if reward is not None and first is not None and reward.shape != first.shape:
            raise EpisodeError(f"rewards must keep one length per episode: {first.size} before, now {reward.size}")
        for name, dtype in UNIT_FIELDS.items():
            self._units[name].append(np.array(getattr(state, name)[battle], dtype=dtype))
        self._loop.append(int(np.asarray(state.loop)[battle]))
        self._step.append(len(self._step) if step is None else int(step))
        self._rewards.append(reward)
        self._actions.append(_action_streams(actions, int(battle)))
        self._opponents.append(None if opponent is None else str(opponent))

    def arrays(self) -> dict[str, np.ndarray]:
        """The file's arrays (see the module docstring)."""
        if not len(self):
            raise EpisodeError("nothing captured: call capture() at least once before saving")
        names = sorted({o for o in self._opponents if o is not None})
        actions = _stack_padded(self._actions)
        meta = {
            "format": FORMAT, "version": FORMAT_VERSION, "map": self.spec.name,
            "size": [int(v) for v in self.spec.size], "step_mul": self.step_mul,
            "unit_names": [UNITS[t].name for t in self._utype], "opponents": names, "actions": sorted(actions),
            "metadata": self.metadata,
        }
        out = {
            "meta": np.frombuffer(json.dumps(meta, default=_json_value).encode(), dtype=np.uint8),
            "side": self._side, "pathable": np.asarray(self.spec.pathable, dtype=bool),
            "cliff": np.asarray(self.spec.cliff, dtype=np.float32),
            "loop": np.array(self._loop, dtype=np.int64), "step": np.array(self._step, dtype=np.int32),
            "opponent": np.array([names.index(o) if o is not None else -1 for o in self._opponents], np.int16),
        }
        out.update({name: np.stack(values) for name, values in self._units.items()})
        rewards = _stack_padded([{"rewards": r} if r is not None else {} for r in self._rewards])
        out.update(rewards)
        out.update(actions)
        return out

    def to_episode(self) -> Episode:
        """The captured frames as an :class:`Episode`, exactly as :func:`load_episode` would read them back."""
        return _episode_from_arrays(self.arrays(), "<recorder>")

    def save(self, path: str | os.PathLike) -> Path:
        """Write the episode to ``path`` (``.npz`` is appended when missing); returns the path written."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        if not path.parent.exists():
            raise FileNotFoundError(f"folder {str(path.parent)!r} for episode file {path.name!r} does not exist")
        arrays = self.arrays()
        # A temporary file in the same folder, moved over ``path`` once complete: a kill mid-write leaves the old
        # file (or none), never half an archive.
        with atomic_write(path, "wb") as handle:
            np.savez_compressed(handle, **arrays)
        return path


def _json_value(value: Any) -> Any:
    """Metadata values JSON cannot store natively: NumPy scalars and arrays become numbers and lists."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    raise EpisodeError(f"metadata value {value!r} of type {type(value).__name__} cannot be stored; "
                       f"use numbers, strings, lists or dicts")


def _action_streams(actions: Any, battle: int, prefix: str = "") -> dict[str, np.ndarray]:
    """Named per-frame arrays from whatever the caller passed as actions."""
    if actions is None:
        return {}
    if isinstance(actions, Commands):
        return {f"{prefix}commands.{name}": np.array(getattr(actions, name)[battle], dtype=dtype)
                for name, dtype in _COMMAND_FIELDS.items()}
    if isinstance(actions, Mapping):
        out: dict[str, np.ndarray] = {}
        for key, value in actions.items():
            if isinstance(value, Commands):
                out.update(_action_streams(value, battle, f"{prefix}{key}."))
            else:
                out[f"{prefix}actions.{key}"] = np.asarray(value)
        return out
    return {f"{prefix}actions": np.asarray(actions)}


def _fill_value(dtype: np.dtype) -> Any:
    return {"f": np.nan, "b": False}.get(dtype.kind, -1)


def _stack_padded(frames: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Stack each named stream over frames; frames without it get -1 / NaN / False."""
    keys = sorted({k for f in frames for k in f})
    out = {}
    for key in keys:
        first = next(f[key] for f in frames if key in f)
        dtype = np.result_type(*(f[key].dtype for f in frames if key in f))
        if dtype.kind == "u":
            dtype = np.dtype(np.int64)  # room for the -1 "none"
        if dtype.kind not in "biuf":
            raise EpisodeError(f"{key} must be numeric or bool, got dtype {dtype}")
        stacked = np.full((len(frames), *first.shape), _fill_value(dtype), dtype=dtype)
        for t, f in enumerate(frames):
            if key in f:
                if f[key].shape != first.shape:
                    raise EpisodeError(f"{key} must keep one shape per episode: {first.shape} then "
                                       f"{f[key].shape} at frame {t}")
                stacked[t] = f[key]
        out[key] = stacked
    return out


MAX_STAT = 1e6  # health, shield and energy above this are not a battle's (a unit's maximum is in the hundreds)
EDGE = 1.0  # positions may lie this far outside the map (the engine keeps units on it)


def _check_meta(meta: dict[str, Any], source: str) -> None:
    """The ``meta`` entry's fields have the types and ranges a recording writes."""
    def bad(key: str, expected: str) -> EpisodeError:
        return EpisodeError(f"{source}: malformed 'meta' entry ({key} is {meta.get(key)!r}, expected {expected})")

    if not isinstance(meta.get("map"), str):
        raise bad("map", "a map name")
    size = meta.get("size")
    if not (isinstance(size, list) and len(size) == 2 and all(type(v) is int and 0 < v <= 4096 for v in size)):
        raise bad("size", "two positive ints")
    if type(meta.get("step_mul")) is not int or not 0 < meta["step_mul"] <= 10_000:
        raise bad("step_mul", "a positive int")
    for key in ("unit_names", "opponents", "actions"):
        value = meta.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise bad(key, "a list of strings")
    if not isinstance(meta.get("metadata", {}), dict):
        raise bad("metadata", "an object")


def _check_array(arrays: Mapping[str, np.ndarray], name: str, shape: tuple[int, ...] | None, kinds: str,
                 source: str) -> np.ndarray:
    """``arrays[name]`` checked to be an array of ``shape`` (when given; ``-1`` matches any length) whose dtype kind
    is in ``kinds``."""
    value = arrays[name]
    if not isinstance(value, np.ndarray):
        raise EpisodeError(f"{source}: {name} is not an array")
    if value.dtype.kind not in kinds:
        names = {"b": "bool", "i": "int", "u": "unsigned int", "f": "float"}
        raise EpisodeError(f"{source}: {name} has dtype {value.dtype}, expected "
                           f"{' or '.join(names[k] for k in kinds)}")
    if shape is not None and (value.ndim != len(shape)
                              or any(want not in (-1, got) for want, got in zip(shape, value.shape, strict=True))):
        raise EpisodeError(f"{source}: {name} has shape {value.shape}, expected "
                           f"{tuple('any' if v == -1 else v for v in shape)}")
    return value


def _check_range(value: np.ndarray, name: str, low: float, high: float, source: str) -> None:
    """Every element of ``value`` is a number in ``low..high`` (NaN and infinities are not)."""
    with np.errstate(invalid="ignore"):
        bad = ~((value >= low) & (value <= high))
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise EpisodeError(f"{source}: {name}{list(index)} is {value[index].item()!r}, out of range "
                           f"({low:g}..{high:g})")


def _check_arrays(arrays: Mapping[str, np.ndarray], meta: dict[str, Any], n_units: int, source: str) -> None:
    """Every entry has the shape, type and physical range a recording writes (a recording with positions of 1e300
    or negative health is as malformed as a truncated one)."""
    size = tuple(meta["size"])
    n_frames = len(_check_array(arrays, "loop", (-1,), "iu", source))
    if n_frames == 0:
        raise EpisodeError(f"{source}: the episode has no frames")
    _check_range(arrays["loop"], "loop", 0, 2**62, source)
    _check_range(_check_array(arrays, "step", (n_frames,), "iu", source), "step", 0, 2**62, source)
    _check_range(_check_array(arrays, "side", (n_units,), "biu", source), "side", RED, BLUE, source)
    _check_range(_check_array(arrays, "opponent", (n_frames,), "iu", source), "opponent", -1,
                 len(meta["opponents"]) - 1, source)
    _check_range(_check_array(arrays, "pathable", size, "biu", source), "pathable", 0, 1, source)
    _check_range(_check_array(arrays, "cliff", size, "iuf", source), "cliff", -1e3, 1e3, source)
    frame = (n_frames, n_units)
    for name in ("x", "y"):
        axis_size = size[0] if name == "x" else size[1]
        _check_range(_check_array(arrays, name, frame, "iuf", source), name, -EDGE, axis_size + EDGE, source)
    for name in ("health", "shield", "energy"):
        _check_range(_check_array(arrays, name, frame, "iuf", source), name, 0, MAX_STAT, source)
    for name in ("alive", "burst"):
        _check_range(_check_array(arrays, name, frame, "biu", source), name, 0, 1, source)
    _check_range(_check_array(arrays, "fired_at", frame, "iu", source), "fired_at", -1, n_units - 1, source)
    if "rewards" in arrays:
        rewards = _check_array(arrays, "rewards", (n_frames, -1), "iuf", source)
        if np.isinf(rewards).any():
            raise EpisodeError(f"{source}: rewards holds an infinite value")
    for key in meta.get("actions", []):
        value = _check_array(arrays, key, None, "biuf", source)
        if value.ndim == 0 or value.shape[0] != n_frames:
            raise EpisodeError(f"{source}: {key} has shape {value.shape}, expected {n_frames} frames first")


def _episode_from_arrays(arrays: Mapping[str, np.ndarray], source: str) -> Episode:
    if "meta" not in arrays:
        raise EpisodeError(f"{source}: not an episode file (no 'meta' entry)")
    try:
        meta = json.loads(bytes(np.asarray(arrays["meta"], dtype=np.uint8)).decode())
    except (UnicodeDecodeError, ValueError, TypeError, OverflowError, RecursionError) as err:
        raise EpisodeError(f"{source}: unreadable 'meta' entry ({err})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise EpisodeError(f"{source}: not an episode file (format is not {FORMAT!r})")
    if meta.get("version") != FORMAT_VERSION:
        raise EpisodeError(f"{source}: episode format version {meta.get('version')!r}; this install reads "
                           f"version {FORMAT_VERSION}")
    _check_meta(meta, source)
    required = ["side", "pathable", "cliff", "loop", "step", "opponent", *UNIT_FIELDS]
    missing = [k for k in required if k not in arrays]
    if missing:
        raise EpisodeError(f"{source}: missing entries {', '.join(missing)}")
    try:
        utype = np.array([unit_index(n) for n in meta["unit_names"]], dtype=np.int32)
    except KeyError as err:
        raise EpisodeError(f"{source}: {err.args[0]}") from None
    missing = [k for k in meta.get("actions", []) if k not in arrays]
    if missing:
        raise EpisodeError(f"{source}: missing action entries {', '.join(missing)}")
    _check_arrays(arrays, meta, len(utype), source)
    side = np.asarray(arrays["side"], dtype=np.int8)
    terrain = MapTerrain(meta["map"], tuple(meta["size"]), np.asarray(arrays["pathable"], dtype=bool),
                         np.asarray(arrays["cliff"], dtype=np.float64))
    actions = {k: np.asarray(arrays[k]) for k in meta.get("actions", [])}
    return Episode(
        terrain=terrain, step_mul=int(meta["step_mul"]), unit_names=tuple(meta["unit_names"]), utype=utype,
        side=side, loop=np.asarray(arrays["loop"], dtype=np.int64), step=np.asarray(arrays["step"], dtype=np.int64),
        units={name: np.asarray(arrays[name], dtype=dtype) for name, dtype in UNIT_FIELDS.items()},
        rewards=np.asarray(arrays["rewards"]) if "rewards" in arrays else None,
        opponent=np.asarray(arrays["opponent"], dtype=np.int64), opponents=tuple(meta["opponents"]),
        actions=actions,
        metadata=dict(meta.get("metadata", {})),
    )


def load_episode(path: str | os.PathLike) -> Episode:
    """Read an episode file written by :meth:`EpisodeRecorder.save`."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"episode file {str(path)!r} does not exist")
    if path.stat().st_size == 0:
        raise EpisodeError(f"{path}: not an episode file (the file is empty)")
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as err:  # truncated, random bytes, a pickle: whatever numpy raises on it
        raise EpisodeError(f"{path}: not an episode file ({_reason(err)})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise EpisodeError(f"{path}: not an episode file (a single array, not an .npz archive)")
    try:
        with data:
            arrays = {k: data[k] for k in data.files}
    except Exception as err:  # a damaged member: bad CRC, truncated deflate stream, an object array
        raise EpisodeError(f"{path}: not an episode file ({_reason(err)})") from None
    try:
        return _episode_from_arrays(arrays, str(path))
    except EpisodeError:
        raise
    except Exception as err:  # anything the checks above did not foresee is still a malformed file
        raise EpisodeError(f"{path}: malformed episode file ({_reason(err)})") from None


def _reason(err: BaseException) -> str:
    """One line saying what went wrong."""
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__
