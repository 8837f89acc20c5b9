"""Replay an EPyMARL (QMIX) checkpoint on smac-hard-gym's engine and measure how the enemy's marines get to fire.

Plays ``--episodes`` games of the run's map with ``smac_hard_gym.StarCraft2Env`` (the run's sacred ``env_args``;
SMAC's opponent, the default) and one of two learner policies:

- ``qmix`` (default): the checkpoint's ``agent.th`` loaded into EPyMARL's own agent class (``config.json``'s
  ``agent``, e.g. ``RNNAgent``), imported from the EPyMARL checkout ``--epymarl``. Inputs are built as EPyMARL's
  ``BasicMAC._build_inputs`` does (obs, then the last actions one-hot if ``obs_last_action``, then a one-hot agent
  id if ``obs_agent_id``); actions as its ``EpsilonGreedyActionSelector`` picks them: the best available action, or
  with probability ``--eps`` (default 0: greedy, as EPyMARL's test episodes) a uniformly random available one.
- ``focus_lowest``: a fixed script, the control that measures the engine without a learned policy: each learner
  marine attacks the available enemy with the least health (ties: the lowest index), else moves east.

Episode ``k`` starts with ``env.reset(seed=seed0 + k)``. The measurement reads the engine's state of battle 0
(positions, health, targets, whom each unit shot) before and after every env step (``read_units``; internal
access, see ``smac_hard_gym/engine/state.py``). Reach is a marine's on a marine, centre to centre:
5 + 0.375 + 0.375 = 5.75. The "fight" starts with the first env step in which any unit fires. Reported:

- win rate, draws (both sides dead after the same env step, which SMAC counts as neither side's win), mean episode
  length, the env step of the learner's first shot (mean over the episodes with one), learner survivors, learner
  HP left and enemy HP left at the end;
- the opening, the first 6 fight steps: enemy shots per episode (in all and per enemy slot), and the share of alive
  enemies with no learner within reach at the start of each of those steps (mean over the steps);
- enemy marine-steps (alive through a step; an episode's last step is left out): the share whose target is out of
  reach at the step's start, and the share that is so and also moves less than 0.28 (a quarter of a step's walk)
  during the step ("stalled");
- focus fire: in each step with learner shots, the share of them on the enemy that dies next (ties: the lowest
  slot); mean over those steps.

It needs the venv EPyMARL runs in (torch; see ``install.sh``); ``--policy focus_lowest`` needs no torch. To replay a
run on the engine it trained on, use the Python that has that smac-hard-gym installed (a fixed commit, as
``run_reference.py`` advises) and run this file (not ``-m``), so that the repository's own ``smac_hard_gym`` is not
on ``sys.path``; the results name the ``smac_hard_gym`` folder that was imported. ``--json PATH`` writes the results
to PATH; with ``--key A/B`` they go under that key of PATH's object (other keys kept) and the table shows every
replay in the file. ``benchmarks/results/qmix_5m_vs_6m_replay.json`` was made from the repository root with::

    export NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
    PY="nice -n 10 <epymarl-venv>/bin/python benchmarks/epymarl/replay_checkpoint.py"
    ARGS="--run-dir <runs>/qmix/5m_vs_6m/seed0 --episodes 100"      # run_reference.py's --out folder
    OUT=benchmarks/results/qmix_5m_vs_6m_replay.json
    $PY $ARGS --json $OUT --key engine_run/qmix
    $PY $ARGS --policy focus_lowest --json $OUT --key engine_run/focus_lowest
    # the same installed package with engine/kernels.py of commit 0ef79cf (branch experiment/go-round: walkers
    # slide round units that do not give way): copy <epymarl-venv>'s site-packages/smac_hard_gym to
    # <goround>/smac_hard_gym, then `git show 0ef79cf:smac_hard_gym/engine/kernels.py >
    # <goround>/smac_hard_gym/engine/kernels.py`
    PYTHONPATH=<goround> $PY $ARGS --json $OUT --key go_round/qmix
    PYTHONPATH=<goround> $PY $ARGS --policy focus_lowest --json $OUT --key go_round/focus_lowest
    # the engine with steering (docs/engine_rules.md C11): this repository at commit f8a37e9, installed with
    # `<epymarl-venv>/bin/python -m pip install --no-deps --target <steering> .`
    PYTHONPATH=<steering> $PY $ARGS --epymarl <epymarl-dir> --json $OUT --key steering/qmix
    PYTHONPATH=<steering> $PY $ARGS --policy focus_lowest --json $OUT --key steering/focus_lowest
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import types
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

import smac_hard_gym
from smac_hard_gym import StarCraft2Env

DEFAULT_EPYMARL = Path.home() / ".cache" / "smac-hard-gym" / "epymarl"
REACH = 5.0 + 0.375 + 0.375  # marine weapon range + both radii
STALL = 0.25 * 2.25 / 2  # a quarter of the distance a marine walks in one env step (8 loops)
OPENING = 6  # fight steps
ATTACK, EAST = 6, 4  # SMAC action ids: attack enemy j is 6 + j


class Units(NamedTuple):
    """Battle 0 of the engine's state, by unit slot (the learner's units first, then the enemy's)."""

    x: np.ndarray
    y: np.ndarray
    health: np.ndarray
    alive: np.ndarray
    target: np.ndarray  # unit the weapon is engaging, -1 if none
    fired_at: np.ndarray  # unit shot during the latest env step, -1 if none


def read_units(env: StarCraft2Env) -> Units:
    state = env._core.backend.state  # smac_hard_gym.engine.state.BattleState, arrays (battles, units)
    return Units(*(getattr(state, name)[0].copy() for name in Units._fields))


Policy = Callable[[StarCraft2Env, Units, int], np.ndarray]  # (env, state before the step, step) -> greedy actions


def focus_lowest(env: StarCraft2Env, units: Units, t: int) -> np.ndarray:
    avail = np.array(env.get_avail_actions())
    enemy_hp = units.health[env.n_agents:]
    actions = np.zeros(env.n_agents, dtype=int)
    for i, av in enumerate(avail):
        shootable = [j for j in range(env.n_enemies) if av[ATTACK + j]]
        if shootable:
            actions[i] = ATTACK + min(shootable, key=lambda j: (enemy_hp[j], j))
        else:
            actions[i] = EAST if av[EAST] else int(np.flatnonzero(av)[0])
    return actions


def qmix_policy(epymarl: Path, checkpoint: Path, cfg: dict[str, Any], env: StarCraft2Env) -> Policy:
    """EPyMARL's agent network with the checkpoint's weights; acts greedily, keeps its hidden state per episode."""
    import torch as th

    sys.path.insert(0, str(epymarl / "src"))
    from modules.agents import REGISTRY as AGENTS  # EPyMARL's agent classes

    n_agents, n_actions = env.n_agents, env.n_actions
    args = types.SimpleNamespace(**{**cfg, "n_agents": n_agents, "n_actions": n_actions})
    n_inputs = (env.get_obs_size() + (n_actions if cfg["obs_last_action"] else 0)
                + (n_agents if cfg["obs_agent_id"] else 0))
    agent = AGENTS[cfg["agent"]](n_inputs, args)
    agent.load_state_dict(th.load(checkpoint / "agent.th", map_location="cpu"))
    agent.eval()
    hidden = {"h": None}

    def act(env: StarCraft2Env, units: Units, t: int) -> np.ndarray:
        if t == 0:
            hidden["h"] = agent.init_hidden().expand(n_agents, -1)
        parts = [np.array(env.get_obs())]
        if cfg["obs_last_action"]:
            parts.append(env.last_action)
        if cfg["obs_agent_id"]:
            parts.append(np.eye(n_agents))
        with th.no_grad():
            q, hidden["h"] = agent(th.tensor(np.concatenate(parts, axis=1), dtype=th.float32), hidden["h"])
        q[th.tensor(env.get_avail_actions()) == 0] = -float("inf")
        return q.argmax(dim=1).numpy()

    return act


def play(env: StarCraft2Env, policy: Policy, seed: int, eps: float, rng: np.random.Generator) -> dict[str, Any]:
    """One episode; its outcome and the raw counts of the metrics."""
    n = env.n_agents
    enemies = range(n, n + env.n_enemies)
    env.reset(seed=seed)
    before = read_units(env)
    out: dict[str, Any] = {"steps": 0, "opening_shots": np.zeros(env.n_enemies), "no_reach": [],
                           "enemy_steps": 0, "out_of_reach": 0, "stalled": 0}
    fight_start, death_step, learner_shots = None, {}, []
    done, info = False, {}
    while not done:
        actions = policy(env, before, out["steps"])
        for i, av in enumerate(env.get_avail_actions()):
            if eps > 0 and rng.random() < eps:
                actions[i] = rng.choice(np.flatnonzero(av))
        _, done, info = env.step([int(a) for a in actions])
        after, t = read_units(env), out["steps"]
        out["steps"] += 1
        if fight_start is None and (after.fired_at >= 0).any():
            fight_start = t
        if fight_start is not None and t < fight_start + OPENING:
            out["opening_shots"] += after.fired_at[n:] >= 0
            alive_l, alive_e = np.flatnonzero(before.alive[:n]), np.flatnonzero(before.alive[n:]) + n
            if len(alive_l) and len(alive_e):
                d = np.hypot(before.x[alive_e, None] - before.x[alive_l], before.y[alive_e, None] - before.y[alive_l])
                out["no_reach"].append(float((d.min(axis=1) > REACH).mean()))
        for j in enemies:
            if not (before.alive[j] and after.alive[j]) or done:
                continue
            out["enemy_steps"] += 1
            k = before.target[j]
            if k >= 0 and np.hypot(before.x[j] - before.x[k], before.y[j] - before.y[k]) > REACH:
                out["out_of_reach"] += 1
                out["stalled"] += int(np.hypot(after.x[j] - before.x[j], after.y[j] - before.y[j]) < STALL)
        for j in enemies:
            if before.alive[j] and not after.alive[j]:
                death_step[j] = t
        shots = after.fired_at[:n]
        if (shots >= 0).any():
            learner_shots.append((t, shots[shots >= 0]))
        before = after
    focus = []
    for t, shots in learner_shots:
        later = [(s, j) for j, s in death_step.items() if s >= t]
        if later:
            focus.append(float((shots == min(later)[1]).mean()))
    alive_hp = before.health * before.alive
    out |= {"won": bool(info.get("battle_won", False)), "survivors": int(before.alive[:n].sum()),
            "learner_hp": float(alive_hp[:n].sum()), "enemy_hp": float(alive_hp[n:].sum()), "focus": focus,
            "draw": not before.alive.any(),  # both sides dead after the same env step: neither won (SMAC)
            "first_shot": learner_shots[0][0] if learner_shots else None}
    return out


def trace(env: StarCraft2Env, policy: Policy, seed: int) -> None:
    """Play one greedy episode and print every env step: the learner's actions, then each unit's position, health,
    order (the engine's ``ORDER_*`` code), target and the unit it shot during the step (slots as in ``Units``)."""
    env.reset(seed=seed)
    units = read_units(env)
    done, t, info = False, 0, {}
    while not done:
        actions = policy(env, units, t)
        _, done, info = env.step([int(a) for a in actions])
        units, order = read_units(env), env._core.backend.state.order[0]
        cells = [f"{k}: dead" if not units.alive[k] else
                 f"{k}: ({units.x[k]:.1f}, {units.y[k]:.1f}) hp {units.health[k]:.0f} order {order[k]} "
                 f"target {units.target[k]} shot {units.fired_at[k]}" for k in range(len(units.x))]
        print(f"step {t} actions {' '.join(map(str, actions))} | " + " | ".join(cells))
        t += 1
    print(f"won: {bool(info.get('battle_won', False))}")


def summarise(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    def mean(key: str) -> float:
        return float(np.mean([e[key] for e in episodes]))

    def pooled(key: str) -> list[float]:
        return [v for e in episodes for v in e[key]]

    enemy_steps = sum(e["enemy_steps"] for e in episodes)
    per_slot = np.mean([e["opening_shots"] for e in episodes], axis=0)
    first_shots = [e["first_shot"] for e in episodes if e["first_shot"] is not None]
    return {
        "win_rate": mean("won"), "draw_rate": mean("draw"), "mean_length": mean("steps"),
        "first_learner_shot": float(np.mean(first_shots)) if first_shots else None,
        "learner_survivors": mean("survivors"),
        "learner_hp_left": mean("learner_hp"), "enemy_hp_left": mean("enemy_hp"),
        "opening_enemy_shots": float(per_slot.sum()), "opening_enemy_shots_per_slot": per_slot.round(2).tolist(),
        "opening_no_reach_share": float(np.mean(pooled("no_reach"))),
        "enemy_out_of_reach_share": sum(e["out_of_reach"] for e in episodes) / enemy_steps,
        "enemy_stalled_share": sum(e["stalled"] for e in episodes) / enemy_steps,
        "focus_fire_share": float(np.mean(pooled("focus"))),
    }


COLUMNS = {"win_rate": "win rate", "draw_rate": "draws", "mean_length": "mean length",
           "first_learner_shot": "first learner shot (step)", "learner_survivors": "learner survivors",
           "learner_hp_left": "learner HP left", "enemy_hp_left": "enemy HP left",
           "opening_enemy_shots": "opening enemy shots", "opening_enemy_shots_per_slot": "… per enemy slot",
           "opening_no_reach_share": "opening: enemies with no learner in reach",
           "enemy_out_of_reach_share": "enemy steps, target out of reach",
           "enemy_stalled_share": "… and stalled", "focus_fire_share": "focus fire"}


def table(rows: dict[str, dict[str, Any]]) -> str:
    def cell(v: Any) -> str:
        if v is None:
            return "–"  # not measured: a replay recorded before the column existed, or no learner shot
        return " / ".join(f"{x:.1f}" for x in v) if isinstance(v, list) else f"{v:.3g}" if v < 10 else f"{v:.1f}"

    lines = ["| replay | " + " | ".join(COLUMNS.values()) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    lines += [f"| {name} | " + " | ".join(cell(r.get(k)) for k in COLUMNS) + " |" for name, r in rows.items()]
    return "\n".join(lines)


def replays(node: dict[str, Any], name: str = "") -> Iterator[tuple[str, dict[str, Any]]]:
    """(key path, results) of every replay stored in a --json file."""
    if "win_rate" in node:
        yield name, node
        return
    for key, value in node.items():
        if isinstance(value, dict):
            yield from replays(value, f"{name}/{key}" if name else key)


def latest(paths: list[Path], key: Callable[[Path], tuple[int, ...]], what: str) -> Path:
    if not paths:
        raise SystemExit(f"no {what} found")
    return max(paths, key=key)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--run-dir", type=Path, help="a run_reference.py job folder (<out>/<algo>/<map>/seed<n>): "
                   "the newest checkpoint under models/ and the newest sacred config.json")
    p.add_argument("--checkpoint", type=Path, help="a checkpoint folder (holds agent.th); overrides --run-dir's")
    p.add_argument("--config", type=Path, help="the run's sacred config.json; overrides --run-dir's")
    p.add_argument("--epymarl", type=Path, default=DEFAULT_EPYMARL, help="EPyMARL checkout (install.sh --dest)")
    p.add_argument("--policy", choices=["qmix", "focus_lowest"], default="qmix")
    p.add_argument("--eps", type=float, default=0.0, help="probability of a random available action (default 0)")
    p.add_argument("--episodes", type=int, default=100)
    p.add_argument("--seed0", type=int, default=1000, help="episode k is reset with seed seed0 + k (default 1000)")
    p.add_argument("--json", type=Path, help="write the results here")
    p.add_argument("--key", help="store the results under this key (A/B) of --json's object, keeping the others")
    p.add_argument("--trace", type=int, metavar="SEED",
                   help="instead of measuring, play the episode reset with SEED and print every step's units")
    a = p.parse_args(argv)

    run = a.run_dir.expanduser().resolve() if a.run_dir else None
    config = a.config or (run and latest(list(run.glob("sacred/*/*/config.json")),
                                         lambda c: (int(c.parts[-3]), int(c.parts[-2])), f"config under {run}"))
    if config is None:
        p.error("give --run-dir or --config")
    cfg = json.loads(Path(config).read_text())
    env = StarCraft2Env(**{**cfg["env_args"], "seed": a.seed0})
    checkpoint = None
    if a.policy == "focus_lowest":
        policy: Policy = focus_lowest
    else:
        checkpoint = a.checkpoint or (run and latest([d for d in run.glob("models/*/*") if (d / "agent.th").is_file()],
                                                     lambda d: (int(d.name),), f"checkpoint under {run}"))
        if checkpoint is None:
            p.error("give --run-dir or --checkpoint")
        policy = qmix_policy(a.epymarl.expanduser(), Path(checkpoint), cfg, env)

    if a.trace is not None:
        trace(env, policy, a.trace)
        return 0
    rng = np.random.default_rng(a.seed0)
    results = summarise([play(env, policy, a.seed0 + k, a.eps, rng) for k in range(a.episodes)])

    pythonpath = [f"PYTHONPATH={shlex.quote(os.environ['PYTHONPATH'])}"] if os.environ.get("PYTHONPATH") else []
    results |= {
        "policy": a.policy, "eps": a.eps, "episodes": a.episodes, "seed0": a.seed0, "map": cfg["env_args"]["map_name"],
        "checkpoint": str(checkpoint) if checkpoint else None, "config": str(config),
        "smac_hard_gym": str(Path(smac_hard_gym.__file__).parent),
        "command": " ".join([*pythonpath, sys.executable, *map(shlex.quote, sys.argv)]),
    }
    rows = {a.key or a.policy: results}
    if a.json and a.key:
        data = json.loads(a.json.read_text()) if a.json.is_file() else {}
        node = data
        *outer, last = a.key.split("/")
        for name in outer:
            node = node.setdefault(name, {})
        node[last] = results
        a.json.write_text(json.dumps(data, indent=1) + "\n")
        rows = dict(replays(data))
    elif a.json:
        a.json.write_text(json.dumps(results, indent=1) + "\n")
    print(table(rows))
    print(f"smac_hard_gym from {results['smac_hard_gym']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
