"""Joint MLP against the unit-shared MAPPO-style policy (wrappers/sb3_shared.py) and its ablations, for a long run.

Trains MaskablePPO with each variant on the given maps and seeds for the given steps (each at ``smac-hard-gym
train``'s defaults for its policy, ``smac_hard_gym.training.config.POLICY_DEFAULTS``, unless the variant says
otherwise), then plays a deterministic test evaluation against the opponent "smac" (SC2's built-in AI script) on the
test battles ``smac-hard-gym eval`` plays, and writes ``study.json`` (one row per run) and ``study.md`` (per map and
variant: mean final test win rate over seeds, its spread, and training steps/s) to ``--out``.

Variants (``--variants``, comma-separated):

- ``joint``: the joint MLP (MaskableJointPolicy, obs_mode "joint", 128x128 actor and critic, the first sweep's PPO);
- ``shared``: ``train --policy shared``: SharedUnitPolicy on the "joint+state" view, shared 64x64 actor on
  [frames, unit id, last action], 128x128 critic on the global state, running value normalisation, MAPPO's PPO
  settings for the map (64 x 50 steps; epochs, minibatches and memory (4 frames or 1) from MAPPO's launch script
  for the map, the clip measured for those epochs: ``smac_hard_gym.training.mappo_settings``);
- ``shared-no-id``: without the one-hot unit id;
- ``shared-no-last-action``: without the last-action input;
- ``shared-no-state``: decentralised critic (shared per-unit critic on [obs, id], averaged over living units);
- ``shared-no-vnorm``: without value normalisation;
- ``shared-popart``: PopArt (value normalisation that rescales the value head to keep its outputs);
- ``shared-1-frame``: one frame (no memory);
- ``shared-sb3-ppo``: the joint MLP's PPO settings (64 x 32 steps, minibatches of 512, 10 epochs, clip 0.2);
- ``shared-4-frames``: four frames on every map (27m_vs_30m's default is one);
- ``shared-shuffled-buffer``: ``shared-4-frames`` with sb3-contrib's own whole-rollout minibatch (the rollout
  gathered in a new random order for every epoch) instead of ours (built once per update); for ``--speed``;
- ``shared-15-epochs``: 4 frames, 15 epochs and clip 0.05 on every map (the shared policy's defaults before they
  followed MAPPO's settings for the map).

``--probe``: no training; scripted learner-side policies on 2s_vs_1sc against "smac", written in the learner's own
observations and actions (what PPO sees and can do), to measure which behaviours the map rewards (win rate, return,
discounted return, episode length, and how often the crawler changes target while both stalkers live), on the test
battles:

- ``attack``: attack the crawler when the action is legal (centre distance 6), else walk north towards it;
- ``attack-eps0.1``, ``attack-eps0.3``: the same with a random legal action instead, with probability 0.1 or 0.3;
- ``swap``: a single tank swap: a unit whose health + shields fell to 25 or less while its ally still has 140 or
  more walks south while it sees the crawler (it leaves the crawler's range, 7 + radii = 8.75 centre to centre,
  and the crawler turns on the ally), then comes back;
- ``regen``: shield cycling with health kept in reserve: once a unit's health is 45 or less (and its ally's too, or
  the ally is dead) and its shields are gone, it walks south out of sight of the crawler and stops there until its
  shields have regenerated (10 game seconds after the last hit, then 2 per game second), then comes back; plus the
  swap above. Rewards for this and the others are SMAC's default (damage dealt, kills, the win).

``--speed``: no evaluation; instead ``--rounds`` interleaved rounds of ``--timesteps`` steps per variant after one
untimed warm-up rollout (as ``smac-hard-gym bench train``), reporting each round's steps/s and the median. Either
way the engine's kernels and torch are warmed up first (one untimed rollout per policy kind and obs mode), so the
first variant does not pay for compilation. Training steps/s counts rollouts and updates together (evaluation
apart), like ``train``'s and ``bench train``'s.

    nice -n 10 python benchmarks/shared_policy_study.py --maps 3m --seeds 0 --timesteps 20000
    nice -n 10 python benchmarks/shared_policy_study.py --probe --eval-episodes 256
    nice -n 10 python benchmarks/shared_policy_study.py --maps 27m_vs_30m --speed --timesteps 4096 --rounds 2 \\
        --variants joint,shared
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path
from typing import Any

# policy: train --policy; config: TrainConfig fields that differ from the policy's defaults; kwargs: policy keywords
VARIANTS: dict[str, dict[str, Any]] = {
    "joint": {"policy": "joint", "config": {}, "kwargs": {}},
    "shared": {"policy": "shared", "config": {}, "kwargs": {}},
    "shared-no-id": {"policy": "shared", "config": {}, "kwargs": {"unit_ids": False}},
    "shared-no-last-action": {"policy": "shared", "config": {}, "kwargs": {"last_action": False}},
    "shared-no-state": {"policy": "shared", "config": {}, "kwargs": {"critic": "unit"}},
    "shared-no-vnorm": {"policy": "shared", "config": {}, "kwargs": {"value_norm": "none"}},
    "shared-popart": {"policy": "shared", "config": {}, "kwargs": {"value_norm": "popart"}},
    "shared-1-frame": {"policy": "shared", "config": {"frame_stack": 1}, "kwargs": {}},
    "shared-sb3-ppo": {"policy": "shared", "config": {"n_steps": 32, "batch_size": 512, "n_epochs": 10,
                                                       "clip_range": 0.2}, "kwargs": {}},
    "shared-4-frames": {"policy": "shared", "config": {"frame_stack": 4}, "kwargs": {}},
    "shared-shuffled-buffer": {"policy": "shared", "config": {"frame_stack": 4}, "kwargs": {}, "buffer": "sb3"},
    "shared-15-epochs": {"policy": "shared", "config": {"n_epochs": 15, "clip_range": 0.05, "frame_stack": 4},
                         "kwargs": {}},
}
DEFAULT_VARIANTS = "joint,shared,shared-no-id,shared-no-state,shared-no-vnorm"


def variant_config(variant: str, map_name: str, seed: int, num_envs: int) -> Any:
    """The TrainConfig a variant trains with (its policy's defaults, then the variant's changes)."""
    from smac_hard_gym.training import TrainConfig

    spec = VARIANTS[variant]
    return TrainConfig(map_name=map_name, seed=seed, num_envs=num_envs, policy=spec["policy"], **spec["config"])


def build_model(variant: str, map_name: str, seed: int, num_envs: int, opponent: str) -> Any:
    """MaskablePPO for ``variant`` (see :func:`variant_config`), on a fresh native vector env."""
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecMonitor

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.wrappers.sb3 import SB3VecEnv
    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer
    from smac_hard_gym.wrappers.sb3_policy import MaskableJointPolicy
    from smac_hard_gym.wrappers.sb3_shared import SharedUnitPolicy, SharedUnitRolloutBuffer

    spec = VARIANTS[variant]
    config = variant_config(variant, map_name, seed, num_envs)
    venv = VecMonitor(SB3VecEnv(NativeVectorEnv(num_envs=num_envs, autoreset_mode="SameStep", opponent=opponent,
                                                **config.env_kwargs())))
    ppo = config.ppo_kwargs()
    if spec["policy"] == "joint":
        policy, buffer = MaskableJointPolicy, MaskableJointRolloutBuffer
    else:
        policy, buffer = SharedUnitPolicy, SharedUnitRolloutBuffer
        ppo["policy_kwargs"] = {**ppo["policy_kwargs"], **spec["kwargs"]}
        if spec.get("buffer") == "sb3":
            from sb3_contrib.common.maskable.buffers import MaskableRolloutBuffer

            buffer = type("ShuffledSharedBuffer", (SharedUnitRolloutBuffer,), {"get": MaskableRolloutBuffer.get})
    model = MaskablePPO(policy, venv, rollout_buffer_class=buffer, **ppo)
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def count_parameters(model: Any) -> int:
    return int(sum(p.numel() for p in model.policy.parameters()))


def test_win_rate(model: Any, variant: str, map_name: str, episodes: int, eval_envs: int) -> dict[str, Any]:
    """Deterministic masked win rate against "smac" on the test battles (``smac-hard-gym eval``'s defaults)."""
    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.training import TEST_SEED_BASE, evaluate, win_rate_spread

    env = NativeVectorEnv(num_envs=min(eval_envs, episodes), autoreset_mode="SameStep", opponent="smac",
                          **variant_config(variant, map_name, 0, 1).env_kwargs())
    try:
        result = evaluate(model, env, episodes, seed=TEST_SEED_BASE)
    finally:
        env.close()
    return {"win_rate": result.win_rate, "wins": result.wins, "episodes": result.episodes,
            "mean_return": result.mean_return, **{k: v for k, v in win_rate_spread(result.wins, result.episodes).items()
                                                  if k != "episodes"}}


def warm_up(map_name: str, variants: list[str], num_envs: int, opponent: str) -> None:
    """One untimed rollout and update per policy kind and obs mode: the engine's and torch's first calls (kernel
    compilation, allocations) stay out of every variant's steps/s."""
    kinds = {(VARIANTS[v]["policy"], tuple(sorted(VARIANTS[v]["config"].items()))): v for v in variants}
    for variant in kinds.values():
        model = build_model(variant, map_name, 0, num_envs, opponent)
        model.learn(model.n_steps * num_envs)
        model.get_env().close()


def study(args: argparse.Namespace, variants: list[str]) -> list[dict[str, Any]]:
    rows = []
    for map_name in args.maps.split(","):
        warm_up(map_name, variants, args.num_envs, args.opponent)
        for seed in [int(s) for s in args.seeds.split(",")]:
            for variant in variants:
                model = build_model(variant, map_name, seed, args.num_envs, args.opponent)
                start = time.perf_counter()
                model.learn(args.timesteps)
                wall = time.perf_counter() - start
                model.get_env().close()
                row = {"map": map_name, "seed": seed, "variant": variant, "timesteps": int(model.num_timesteps),
                       "train_s": wall, "steps_per_s": model.num_timesteps / wall,
                       "parameters": count_parameters(model), "train_opponent": args.opponent,
                       "test": test_win_rate(model, variant, map_name, args.eval_episodes, args.eval_envs)}
                rows.append(row)
                print(f"{map_name} seed {seed} {variant}: test win rate {row['test']['win_rate']:.3f} "
                      f"({row['test']['wins']}/{row['test']['episodes']}), {row['steps_per_s']:.0f} steps/s",
                      flush=True)
    return rows


def speed(args: argparse.Namespace, variants: list[str]) -> list[dict[str, Any]]:
    rows = []
    for map_name in args.maps.split(","):
        warm_up(map_name, variants, args.num_envs, args.opponent)
        models = {v: build_model(v, map_name, 0, args.num_envs, args.opponent) for v in variants}
        for model in models.values():  # warm-up: compilation and first allocations, untimed
            model.learn(model.n_steps * args.num_envs)
        runs: dict[str, list[float]] = {v: [] for v in variants}
        for _ in range(args.rounds):  # interleaved: a busy spell on a shared machine hits every variant
            for variant, model in models.items():
                before = model.num_timesteps
                start = time.perf_counter()
                model.learn(args.timesteps, reset_num_timesteps=False)
                runs[variant].append((model.num_timesteps - before) / (time.perf_counter() - start))
        base = statistics.median(runs[variants[0]])
        for variant, model in models.items():
            median = statistics.median(runs[variant])
            rows.append({"map": map_name, "variant": variant, "steps_per_s": median, "rounds": runs[variant],
                         "parameters": count_parameters(model), f"speedup_vs_{variants[0]}": median / base})
            print(f"{map_name} {variant}: {median:.0f} steps/s (rounds {[round(r) for r in runs[variant]]}), "
                  f"{count_parameters(model)} parameters, {median / base:.2f}x {variants[0]}", flush=True)
            model.get_env().close()
    return rows


PROBES = ("attack", "attack-eps0.1", "attack-eps0.3", "swap", "regen")
PROBE_MAP = "2s_vs_1sc"


def probe_actions(name: str, obs: Any, masks: Any, feature: dict[str, int], unit_obs: int, rng: Any) -> Any:
    """(N, 2) actions of probe ``name`` from the learner's joint observation and action masks (2s_vs_1sc: 2
    stalkers, 7 actions: no-op, stop, north, south, east, west, attack the crawler; the crawler is north of the
    spawns)."""
    import numpy as np

    n_battles = len(obs)
    legal = masks.reshape(n_battles, 2, 7)
    units = obs[:, :2 * unit_obs].reshape(n_battles, 2, unit_obs)

    def column(key: str) -> Any:
        return units[:, :, feature[key]]

    actions = np.where(legal[:, :, 6], 6, np.where(legal[:, :, 2], 2, 0))  # attack, else north, else no-op
    if name in ("swap", "regen"):
        health, shield = column("own_health") * 80, column("own_shield") * 80
        ally_health = column("ally_0_health") * 80
        ally = ally_health + column("ally_0_shield") * 80
        ally_alive = column("ally_0_visible") > 0
        in_sight = column("enemy_0_distance") > 0  # the crawler within sight (9): SMAC zeroes its row beyond
        run = (health + shield <= 25) & (ally >= 140) & in_sight
        if name == "regen":
            reserve = (health <= 45) & ((ally_health <= 45) | ~ally_alive)
            run |= reserve & in_sight & (shield < 1)
            wait = reserve & ~in_sight & (shield < 79)
            actions = np.where(wait & legal[:, :, 1], 1, actions)
        actions = np.where(run & legal[:, :, 3], 3, actions)
    if name.startswith("attack-eps"):
        flip = rng.random(actions.shape) < float(name.removeprefix("attack-eps"))
        actions = np.where(flip, (rng.random(legal.shape) * legal).argmax(axis=2), actions)
    return actions


def probe(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Play each probe policy for ``--eval-episodes`` episodes of 2s_vs_1sc against "smac" on the test battles."""
    import numpy as np

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.training import TEST_SEED_BASE

    rows = []
    gammas = (0.99, 0.999)
    for name in PROBES:
        env = NativeVectorEnv(PROBE_MAP, min(args.eval_envs, args.eval_episodes), autoreset_mode="SameStep",
                              opponent="smac")
        feats = env.core.features[0]
        feature = {key: i for i, key in enumerate(feats.obs_feature_names())}
        rng = np.random.default_rng(0)
        n_battles = env.num_envs
        crawler = feats.n_agents  # the crawler's unit slot follows the learner's
        obs, _ = env.reset(seed=TEST_SEED_BASE)
        ret, steps, switches = np.zeros(n_battles), np.zeros(n_battles, dtype=int), np.zeros(n_battles, dtype=int)
        disc = {g: np.zeros(n_battles) for g in gammas}
        target = env.core.state.target[:, crawler].copy()
        done: list[dict[str, float]] = []
        while len(done) < args.eval_episodes:
            obs, reward, terminated, truncated, info = env.step(
                probe_actions(name, obs, env.action_masks(), feature, feats.obs_size, rng))
            both = (obs[:, :2 * feats.obs_size].reshape(n_battles, 2, -1)[:, :, feature["own_health"]] > 0).all(1)
            for g in gammas:
                disc[g] += reward * g ** steps
            ret += reward
            steps += 1
            now = env.core.state.target[:, crawler]
            switches += (now != target) & (now >= 0) & (target >= 0) & both  # both stalkers still alive
            ended = terminated | truncated
            for b in np.flatnonzero(ended):
                done.append({"won": float(info["final_info"]["battle_won"][b]), "return": ret[b],
                             "length": float(steps[b]), "switches": float(switches[b]),
                             **{f"discounted_{g}": disc[g][b] for g in gammas}})
            for array in (ret, steps, switches, *disc.values()):
                array[ended] = 0
            target = np.where(ended, -1, now)
        env.close()
        done = done[:args.eval_episodes]
        row = {"map": PROBE_MAP, "probe": name, "episodes": len(done),
               **{key: float(np.mean([d[key] for d in done])) for key in done[0]}}
        rows.append(row)
        print(f"{name}: win rate {row['won']:.3f}, return {row['return']:.2f}, length {row['length']:.1f}, "
              f"crawler target switches {row['switches']:.2f}", flush=True)
    return rows


def probe_markdown(rows: list[dict[str, Any]]) -> str:
    lines = ["| probe | episodes | win rate | return | discounted return (gamma 0.99) | (gamma 0.999) | "
             "episode length | crawler target switches (both stalkers alive) |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['probe']} | {r['episodes']} | {r['won']:.2f} | {r['return']:.2f} | "
                     f"{r['discounted_0.99']:.2f} | {r['discounted_0.999']:.2f} | {r['length']:.1f} | "
                     f"{r['switches']:.2f} |")
    return "\n".join(lines) + "\n"


def markdown(rows: list[dict[str, Any]], speed_only: bool) -> str:
    if speed_only:
        lines = ["| map | variant | training steps/s (median) | rounds | parameters | speedup |",
                 "|---|---|---|---|---|---|"]
        for r in rows:
            key = next(k for k in r if k.startswith("speedup_vs_"))
            lines.append(f"| {r['map']} | {r['variant']} | {r['steps_per_s']:.0f} | "
                         f"{', '.join(f'{x:.0f}' for x in r['rounds'])} | {r['parameters']:,} | {r[key]:.2f}x |")
        return "\n".join(lines) + "\n"
    lines = ["| map | variant | seeds | final test win rate vs smac (mean) | per seed | training steps/s (mean) | "
             "parameters |", "|---|---|---|---|---|---|---|"]
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["map"], r["variant"]), []).append(r)
    for (map_name, variant), group in groups.items():
        rates = [g["test"]["win_rate"] for g in group]
        lines.append(f"| {map_name} | {variant} | {len(group)} | {statistics.mean(rates):.3f} | "
                     f"{', '.join(f'{x:.2f}' for x in rates)} | "
                     f"{statistics.mean(g['steps_per_s'] for g in group):.0f} | {group[0]['parameters']:,} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--maps", default="3m")
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--timesteps", type=int, default=20_000)
    parser.add_argument("--variants", default=DEFAULT_VARIANTS)
    parser.add_argument("--opponent", default="smac", help="the training opponent (tests are always vs smac)")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--eval-episodes", type=int, default=32)
    parser.add_argument("--eval-envs", type=int, default=16)
    parser.add_argument("--speed", action="store_true", help="interleaved steps/s only, no evaluation")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--probe", action="store_true",
                        help="no training: scripted learner-side policies on 2s_vs_1sc vs smac (see the docstring)")
    parser.add_argument("--out", default="runs/shared_policy_study")
    args = parser.parse_args(argv)
    variants = args.variants.split(",")
    unknown = sorted(set(variants) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variants {unknown}; known: {sorted(VARIANTS)}")

    import numba
    import torch

    from smac_hard_gym.training import distribution_checks_off

    torch.set_num_threads(1)
    numba.set_num_threads(1)
    with distribution_checks_off():
        if args.probe:
            rows = probe(args)
        else:
            rows = speed(args, variants) if args.speed else study(args, variants)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"args": vars(args), "rows": rows}
    name = "probe" if args.probe else "speed" if args.speed else "study"
    (out / f"{name}.json").write_text(json.dumps(meta, indent=1) + "\n")
    table = probe_markdown(rows) if args.probe else markdown(rows, args.speed)
    (out / f"{name}.md").write_text(table)
    print(table)


if __name__ == "__main__":
    main()
