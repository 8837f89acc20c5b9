"""``smac-hard-gym train``: MaskablePPO on the native vector env (or on Ray actors with ``--ray [ADDRESS]``), with a
masked win-rate evaluation on a schedule.

Writes ``model.zip``, ``config.json``, ``curve.csv``, ``curve.png`` and ``summary.json`` into ``--out``, and a
checkpoint every ``--checkpoint-every`` steps that ``--resume`` carries the run on from. Needs the
``[train]`` extra: ``pip install -e ".[train]"``.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from smac_hard_gym.training.checkpoints import RESUMABLE_OPTIONS
from smac_hard_gym.training.config import POLICIES, POLICY_DEFAULTS, REWARDS
from smac_hard_gym.training.mappo_settings import CLIP_FOR_EPOCHS, MAPPO_DEFAULT, MEASURED, RATIOS

HELP = "train MaskablePPO on a map against an opponent pool and report the win rate"
# the options `train --resume` takes besides --out: the settings a resume may change, as the command line spells them
# (the rest are the run's own, from its config.json)
RESUME_OPTIONS = tuple("no-progress" if name == "progress" else name.replace("_", "-")
                       for name in RESUMABLE_OPTIONS if name != "out")


def _policy_defaults() -> str:
    """POLICY_DEFAULTS as help text: "joint: obs-mode joint, ...; shared: ..."."""
    def value(v: object) -> str:
        return "the rollout in MAPPO's minibatches for the map" if v is None else str(v)

    flags = {"n_epochs": "epochs"}  # the config's field names that the CLI spells otherwise
    clips = ", ".join(f"{clip} with {epochs}" for epochs, clip in CLIP_FOR_EPOCHS.items())
    measured_steps = sorted({m["n_steps"] for m in MEASURED.values() if "n_steps" in m})
    per_map = {"shared": f"; n-steps {MAPPO_DEFAULT['n_steps']} (MAPPO's 8 threads x 400 over 64 battles; "
                         f"{', '.join(map(str, measured_steps))} where measured), epochs and "
                         f"frame-stack as MAPPO's launch script for the map has them (one frame where "
                         f"measured to do as well), clip-range with --ratio joint by "
                         f"epochs: {clips}, or as measured for the map, with --ratio unit MAPPO's for the map "
                         f"(smac_hard_gym/training/mappo_settings.py)"}
    return "; ".join(f"{policy}: " + ", ".join(f"{flags.get(key, key).replace('_', '-')} {value(v)}"
                                               for key, v in table.items()) + per_map.get(policy, "")
                     for policy, table in POLICY_DEFAULTS.items())


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--map", default="3m", help="map name (see `smac-hard-gym maps`; default 3m)")
    parser.add_argument("--opponent", default="default",
                        help="'default' (the map's SMAC-HARD pool), 'blackbox', a script name, a saved model "
                             "(path/to/model.zip, played from its own side's features; loading it runs the pickled "
                             "code inside, as stable-baselines3 loads models: only name files you trust), or these "
                             "joined by commas "
                             "(see `smac-hard-gym scripts --map M`)")
    parser.add_argument("--timesteps", type=int, default=50_000, help="env steps to train (default 50000)")
    parser.add_argument("--num-envs", type=int, default=64, help="battles stepped together (default 64)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="", help="output directory (default runs/<map>-<opponent>-s<seed>)")
    parser.add_argument("--eval-every", type=int, default=0,
                        help="env steps between evaluations (default: a tenth of --timesteps)")
    parser.add_argument("--eval-episodes", type=int, default=32, help="episodes per evaluation (default 32)")
    parser.add_argument("--policy", default="shared", choices=POLICIES,
                        help="shared (default): one 64x64 actor shared by the units (with unit ids, last actions, "
                             "stacked frames and its unit's state row), a critic on the global state sized by "
                             "--net-arch, value normalisation (MAPPO; wrappers/sb3_shared.py); joint: one MLP over all "
                             "units (the first sweep's policy; docs/training_results.md compares them). The options "
                             f"below marked 'the policy's' default to {_policy_defaults()}")
    parser.add_argument("--ratio", default="joint", choices=RATIOS,
                        help="what PPO's clip applies to: joint: the whole action's probability ratio, as "
                             "MaskablePPO has it (default); unit: each unit's ratio, MAPPO's loss, with MAPPO's clip "
                             "for the map (--policy shared only; wrappers/sb3_unit_ppo.py)")
    parser.add_argument("--obs-mode", default=None, choices=("joint", "joint+state", "dict"),
                        help="observation (default: the policy's)")
    parser.add_argument("--frame-stack", type=int, default=None, metavar="K",
                        help="each unit's observation is its last K SMAC observations (default: the policy's)")
    parser.add_argument("--actor-state", action=argparse.BooleanOptionalAction, default=None,
                        help="whether the shared actor also reads its unit's own row of SMAC's global state (weapon "
                             "cooldown or energy, health, shield, type, position from the map's centre), which the "
                             "joint+state observation carries; MAPPO's actors do not see it (default: on for --policy "
                             "shared with --obs-mode joint+state, off otherwise)")
    parser.add_argument("--n-steps", type=int, default=None,
                        help="rollout length per env: num-envs x n-steps samples per update (default: the policy's)")
    parser.add_argument("--batch-size", type=int, default=None,
                        help="PPO minibatch size (default: the policy's)")
    parser.add_argument("--epochs", type=int, default=None, help="PPO epochs per update (default: the policy's)")
    parser.add_argument("--clip-range", type=float, default=None, help="PPO clip range (default: the policy's)")
    parser.add_argument("--lr", type=float, default=5e-4, help="learning rate (default 5e-4)")
    parser.add_argument("--ent-coef", type=float, default=0.01, help="entropy coefficient (default 0.01)")
    parser.add_argument("--ent-coef-final", type=float, default=None, metavar="COEF",
                        help="let the entropy coefficient fall linearly from --ent-coef at the first update to COEF "
                             "at the last (default: --ent-coef throughout)")
    parser.add_argument("--max-grad-norm", type=float, default=0.5, metavar="NORM",
                        help="clip the gradient's global norm to NORM before each optimiser step (default 0.5, "
                             "SB3's; MAPPO clips the actor's and the critic's at 10 each)")
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--reward", default="positive", choices=REWARDS,
                        help="the training battles' reward: positive (SMAC's default: damage dealt and kills), "
                             "signed (SMAC's reward_only_positive=False: damage taken and deaths count against, "
                             "regenerated shields for, at half weight) or abs (SMAC v1's abs(damage + kills), which "
                             "also pays for enemy regeneration and healing, as in the SMAC-HARD paper's runs); test "
                             "evaluations use the default")
    parser.add_argument("--net-arch", default="128,128", help="hidden layer sizes (default 128,128)")
    parser.add_argument("--torch-threads", type=int, default=1, help="torch threads (default 1)")
    parser.add_argument("--env-threads", type=int, default=1, help="engine (numba) threads (default 1)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--league", action="store_true",
                        help="self-play league: snapshots of the learner join --opponent's scripts as opponents")
    parser.add_argument("--league-every", type=int, default=0, metavar="STEPS",
                        help="env steps between league snapshots (default: a fifth of --timesteps)")
    parser.add_argument("--league-weighting", default="uniform", choices=("uniform", "prioritized"),
                        help="how league members are drawn: equally, or more often the less the learner beats them")
    parser.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                        help="step the training battles in Ray actors: a local Ray, or the cluster at ADDRESS "
                             "('auto', 'head:6379', 'ray://head:10001'); needs the [ray] extra; not with --league")
    parser.add_argument("--ray-actors", type=int, default=2,
                        help="Ray actors, each with num-envs / ray-actors battles (default 2)")
    parser.add_argument("--tensorboard", default="", metavar="DIR",
                        help="also log to TensorBoard in DIR (needs the tensorboard package)")
    parser.add_argument("--checkpoint-every", type=int, default=100_000, metavar="STEPS",
                        help="write checkpoint.zip and checkpoint.json into --out every STEPS env steps and at the "
                             "end, what --resume carries on from (default 100000; 0: at the end only; none in a "
                             "league run)")
    parser.add_argument("--resume", action="store_true",
                        help="carry on the run in --out from its checkpoint, with the run's own settings (its "
                             "config.json), to its --timesteps or to the --timesteps given (more than the checkpoint "
                             f"has); with it only {', '.join('--' + o for o in RESUME_OPTIONS)} may be given")
    # what each option is when not given, so that --resume can tell which were
    parser.set_defaults(option_defaults=vars(parser.parse_args([])))


def run(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from smac_hard_gym.training import train

    config = _resumed_config(args) if args.resume else _new_config(args)
    print("config:")
    for key, value in asdict(config).items():
        print(f"  {key:<16} {value}")
    print(f"  {'eval_interval':<16} {config.eval_interval}")
    missing = _kernels_to_compile(config)
    if missing is None or missing:
        from smac_hard_gym.kernel_cache import compiling_notice

        print(compiling_notice(missing), flush=True)
    try:
        summary = train(config, resume=args.resume)
    except ValueError as err:  # a checkpoint that cannot be carried on
        if not args.resume:
            raise
        raise SystemExit(f"smac-hard-gym train --resume: {err}") from None
    if summary["interrupted"]:
        if summary["final_win_rate"] is None:
            measured = "no test win rate measured since training began (the first evaluation comes at " \
                       f"{config.eval_interval} steps)"
        else:
            measured = f"last test win rate {summary['final_win_rate']:.3f} at {summary['final_win_rate_at']} steps"
        print(f"\ninterrupted after {summary['timesteps']} steps ({measured}): model, curve and summary saved in "
              f"{config.out}")
        return 130
    print()
    print(f"win rate (masked, deterministic, {summary['eval_episodes']} episodes) after {summary['timesteps']} "
          f"steps: {summary['final_win_rate']:.3f} (best {summary['best_win_rate']:.3f})")
    for name, rate in summary["final_per_opponent"].items():
        print(f"  vs {name:<20} {rate:.3f}")
    if summary["final_train_episodes"]:
        print(f"training episodes won (sampled actions, last {summary['final_train_episodes']} episodes): "
              f"{summary['final_train_win_rate']:.3f}")
    if "league" in summary:
        print(f"league ({summary['league']['weighting']} weighting), win rate against each member "
              f"({summary['eval_episodes']} episodes each):")
        for name, row in summary["league"]["members"].items():
            print(f"  vs {name:<22} {row['win_rate']:.3f}   drawn with p={row['prob']:.2f}, "
                  f"{row['train_games']} training games")
    reached = summary["first_timesteps_at_0.8"]
    print(f"first evaluation at >= 0.8: {reached if reached is not None else 'not reached'}")
    print(f"time inside the env (step + masks): {summary['env_s']:.1f} s of {summary['train_wall_s']:.1f} s "
          f"training wall time ({summary['env_fraction']:.1%})")
    print("files: " + json.dumps({k: v for k, v in summary["files"].items() if v}))
    return 0


def _new_config(args: argparse.Namespace) -> Any:
    """The :class:`TrainConfig` of a new run from the command line's options."""
    from smac_hard_gym.maps import list_maps
    from smac_hard_gym.training import TrainConfig

    if args.map not in list_maps():
        raise SystemExit(f"unknown map {args.map!r}; maps: {', '.join(list_maps())}")
    try:
        net_arch = [int(n) for n in args.net_arch.split(",")]
    except ValueError:
        raise SystemExit(f"--net-arch must be comma-separated ints, got {args.net_arch!r}") from None
    try:
        config = TrainConfig(
            map_name=args.map, opponent=args.opponent, timesteps=args.timesteps, num_envs=args.num_envs,
            seed=args.seed, out=args.out, eval_every=args.eval_every, eval_episodes=args.eval_episodes,
            obs_mode=args.obs_mode, frame_stack=args.frame_stack, actor_state=args.actor_state,
            clip_range=args.clip_range,
            policy=args.policy, ratio=args.ratio, n_steps=args.n_steps, batch_size=args.batch_size,
            n_epochs=args.epochs,
            learning_rate=args.lr, gamma=args.gamma, ent_coef=args.ent_coef, ent_coef_final=args.ent_coef_final,
            max_grad_norm=args.max_grad_norm,
            reward=args.reward, net_arch=net_arch,
            torch_threads=args.torch_threads, env_threads=args.env_threads, progress=not args.no_progress,
            tensorboard=args.tensorboard, league=args.league, league_every=args.league_every,
            league_weighting=args.league_weighting, ray=args.ray is not None,
            ray_address=None if args.ray in (None, "local") else args.ray, ray_actors=args.ray_actors,
            checkpoint_every=args.checkpoint_every)
        if config.ray:
            import ray  # noqa: F401  (a clear error now rather than after the model is built)
        from smac_hard_gym.opponents import make_opponent, opponent_from_text

        make_opponent(args.map, opponent_from_text(args.opponent))
    except ModuleNotFoundError as err:
        hint = "; pip install 'smac-hard-gym[ray]'" if err.name == "ray" else ""
        raise SystemExit(f"smac-hard-gym train: {err}{hint}") from None
    except (TypeError, ValueError, FileNotFoundError, ImportError) as err:
        raise SystemExit(f"smac-hard-gym train: {err}") from None
    return config


def _resumed_config(args: argparse.Namespace) -> Any:
    """The :class:`TrainConfig` of the run in ``--out`` (its config.json), with the options a resume may change."""
    from dataclasses import replace
    from pathlib import Path

    from smac_hard_gym.training.run_files import load_run_config

    allowed = {*RESUMABLE_OPTIONS, "no_progress", "resume", "option_defaults"}
    given = [name for name, default in args.option_defaults.items()
             if name not in allowed and getattr(args, name) != default]
    if given:
        raise SystemExit(f"smac-hard-gym train --resume: the run keeps its own settings, so "
                         f"--{given[0].replace('_', '-')} cannot be given (with --resume: --out, "
                         f"{', '.join('--' + o for o in RESUME_OPTIONS)})")
    if not args.out:
        raise SystemExit("smac-hard-gym train --resume: name the run's folder with --out")
    try:
        saved = load_run_config(Path(args.out) / "config.json")
    except ValueError as err:
        raise SystemExit(f"smac-hard-gym train --resume: {err}") from None
    if saved is None:
        raise SystemExit(f"smac-hard-gym train --resume: no run in {args.out!r} (no config.json)")
    changes: dict[str, Any] = {"progress": not args.no_progress, "out": args.out}  # the folder may have moved
    for name in RESUMABLE_OPTIONS:
        if name not in changes and getattr(args, name) != args.option_defaults[name]:
            changes[name] = getattr(args, name)
    try:
        return replace(saved, **changes)
    except (TypeError, ValueError) as err:
        raise SystemExit(f"smac-hard-gym train --resume: {err}") from None


def _kernels_to_compile(config: Any) -> list[str] | None:
    """The kernels this run will compile (``kernel_cache.missing_kernels``): the engine's overloads its training and
    evaluation batches step with (as ``BattleEngine`` picks them), and the feature kernels; None when unknown."""
    import numba

    from smac_hard_gym.engine.battle import PARALLEL_MIN_BATCH, SPECIALIZE_MIN_BATCH
    from smac_hard_gym.kernel_cache import missing_kernels
    from smac_hard_gym.maps import load_map

    spec = load_map(config.map_name)
    threads = min(config.env_threads, numba.config.NUMBA_NUM_THREADS)
    missing: list[str] = []
    battles = config.num_envs // config.ray_actors if config.ray else config.num_envs
    for batch in (battles, min(config.eval_envs, config.eval_episodes)):
        found = missing_kernels(spec.n_red + spec.n_blue if batch >= SPECIALIZE_MIN_BATCH else None,
                                parallel=threads > 1 and batch >= PARALLEL_MIN_BATCH)
        if found is None:
            return None
        missing += [name for name in found if name not in missing]
    return missing
