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
import zipfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED, Commands
from smac_hard_gym.units import UNITS, unit_index

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
        np.savez_compressed(path, **self.arrays())
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


def _episode_from_arrays(arrays: Mapping[str, np.ndarray], source: str) -> Episode:
    if "meta" not in arrays:
        raise EpisodeError(f"{source}: not an episode file (no 'meta' entry)")
    try:
        meta = json.loads(bytes(np.asarray(arrays["meta"], dtype=np.uint8)).decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise EpisodeError(f"{source}: unreadable 'meta' entry ({err})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise EpisodeError(f"{source}: not an episode file (format is not {FORMAT!r})")
    if meta.get("version") != FORMAT_VERSION:
        raise EpisodeError(f"{source}: episode format version {meta.get('version')!r}; this install reads "
                           f"version {FORMAT_VERSION}")
    required = ["side", "pathable", "cliff", "loop", "step", "opponent", *UNIT_FIELDS]
    missing = [k for k in required if k not in arrays]
    if missing:
        raise EpisodeError(f"{source}: missing entries {', '.join(missing)}")
    try:
        utype = np.array([unit_index(n) for n in meta["unit_names"]], dtype=np.int32)
    except KeyError as err:
        raise EpisodeError(f"{source}: {err.args[0]}") from None
    side = np.asarray(arrays["side"], dtype=np.int8)
    n_frames, n_units = len(arrays["loop"]), len(utype)
    for name in UNIT_FIELDS:
        if arrays[name].shape != (n_frames, n_units):
            raise EpisodeError(f"{source}: {name} has shape {arrays[name].shape}, expected {(n_frames, n_units)}")
    for name in ("step", "opponent"):
        if arrays[name].shape != (n_frames,):
            raise EpisodeError(f"{source}: {name} has shape {arrays[name].shape}, expected {(n_frames,)}")
    terrain = MapTerrain(meta["map"], tuple(meta["size"]), np.asarray(arrays["pathable"], dtype=bool),
                         np.asarray(arrays["cliff"], dtype=np.float64))
    missing = [k for k in meta.get("actions", []) if k not in arrays]
    if missing:
        raise EpisodeError(f"{source}: missing action entries {', '.join(missing)}")
    actions = {k: np.asarray(arrays[k]) for k in meta.get("actions", [])}
    return Episode(
        terrain=terrain, step_mul=int(meta["step_mul"]), unit_names=tuple(meta["unit_names"]), utype=utype,
        side=side, loop=np.asarray(arrays["loop"]), step=np.asarray(arrays["step"]),
        units={name: np.asarray(arrays[name]) for name in UNIT_FIELDS},
        rewards=np.asarray(arrays["rewards"]) if "rewards" in arrays else None,
        opponent=np.asarray(arrays["opponent"]), opponents=tuple(meta["opponents"]), actions=actions,
        metadata=dict(meta.get("metadata", {})),
    )


def load_episode(path: str | os.PathLike) -> Episode:
    """Read an episode file written by :meth:`EpisodeRecorder.save`."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"episode file {str(path)!r} does not exist")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (zipfile.BadZipFile, ValueError, OSError) as err:
        raise EpisodeError(f"{path}: not an episode file ({err})") from None
    if not isinstance(arrays, dict):
        raise EpisodeError(f"{path}: not an episode file (a single array, not an .npz archive)")
    return _episode_from_arrays(arrays, str(path))


def __getattr__(name: str) -> Any:
    if name == "record_engine_episode":
        raise ImportError("record_engine_episode moved to smac_hard_gym.envs.duel (it plays on the two-player core): "
                          "from smac_hard_gym.envs.duel import record_engine_episode")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
