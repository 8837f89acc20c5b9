"""Resumable EPyMARL reference runs (QMIX, MAPPO) against SMAC's opponent on smac-hard-gym's engine.

Runs a list of (algorithm, map, seed) jobs with EPyMARL's own ``src/main.py`` (installed by ``install.sh``, outside
this repository), at most ``--jobs`` at a time, each niced. EPyMARL gets smac-hard-gym's ``StarCraft2Env`` through
``examples/epymarl/smac_shim`` (``--env-config=sc2``); its default opponent is ``"smac"`` (SMAC's own opponent).

Layout of ``--out`` (one folder per job)::

    <out>/<algo>/<map>/seed<seed>/
        models/<unique_token>/<t_env>/   EPyMARL checkpoints (save_model=True, every --save-interval env steps)
        sacred/<n>/<id>/                 sacred FileStorageObserver of the n-th (re)start: info.json, metrics.json,
                                         config.json, run.json, cout.txt (<id> is sacred's run id, shared with the
                                         observer EPyMARL itself adds under <epymarl>/results/sacred)
        logs/<n>.log                     stdout+stderr of the n-th start
        pid                              pid of the running EPyMARL process
        engine.json                      fingerprint of the smac-hard-gym code the job started on
        done.json                        written when EPyMARL finished training (the job is then skipped)

Resume: re-run the same command. For each unfinished job the newest loadable checkpoint is passed as EPyMARL's
``checkpoint_path`` + ``load_step``; EPyMARL then restores the networks and optimiser state and sets t_env to the
checkpoint's step. It does NOT restore the replay buffer, the reward-standardisation statistics, the target
networks (they are set equal to the loaded networks) or the RNG state: a resumed run refills its buffer and is not
bit-identical to an uninterrupted one. Steps run after the last checkpoint are lost (at most --save-interval).

A job resumes only on the engine it started on: ``engine.json`` holds a sha256 over the smac-hard-gym code the job
imports (engine, unit table, SMAC layer, envs, opponents, maps). If that code has changed, the job is not resumed
(a run half on one engine and half on another measures neither); ``--restart-changed`` moves its folder aside
(``seed<n>.engine-<old fingerprint>``) and starts it again. To keep editing the code while runs go, install a fixed
commit of smac-hard-gym (not editable) in the environment that runs them.
A job whose EPyMARL process finished while no orchestrator was watching is marked done from sacred's own record
(``run.json`` status ``COMPLETED``).
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib.util
import json
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SHIM = REPO / "examples" / "epymarl" / "smac_shim"
STUBS = Path(__file__).resolve().parent / "stubs"
DEFAULT_EPYMARL = Path.home() / ".cache" / "smac-hard-gym" / "epymarl"

# the order of the reference runs: controls first, then the paper's maps
MAPS = ["3m", "8m", "2s_vs_1sc", "25m", "5m_vs_6m", "corridor", "6h_vs_8z", "3s5z_vs_3s6z", "MMM2", "27m_vs_30m"]
ALGOS = ["qmix", "mappo"]
# the files each learner's save_models writes (EPyMARL src/learners/q_learner.py, ppo_learner.py)
CKPT_FILES = {"qmix": ["agent.th", "mixer.th", "opt.th"],
              "mappo": ["agent.th", "critic.th", "agent_opt.th", "critic_opt.th"]}


# episode_bytes() of the reference maps, MB (computed from smac-hard-gym's env info), used if the env fails to import
EPISODE_MB = {"3m": 0.049, "8m": 0.509, "2s_vs_1sc": 0.116, "25m": 5.317, "5m_vs_6m": 0.144, "corridor": 2.556,
              "6h_vs_8z": 0.478, "3s5z_vs_3s6z": 1.079, "MMM2": 1.785, "27m_vs_30m": 7.867}


@dataclass(frozen=True)
class Job:
    algo: str
    map_name: str
    seed: int

    @property
    def name(self) -> str:
        return f"{self.algo}/{self.map_name}/seed{self.seed}"

    def dir(self, out: Path) -> Path:
        return out / self.algo / self.map_name / f"seed{self.seed}"


def log(msg: str) -> None:
    print(f"[{dt.datetime.now():%Y-%m-%d %H:%M:%S}] {msg}", flush=True)


def checkpoints(job_dir: Path, algo: str) -> list[tuple[int, Path]]:
    """(t_env, folder) of every complete-looking checkpoint of a job, newest last."""
    found = []
    for d in (job_dir / "models").glob("*/*"):
        if d.is_dir() and d.name.isdigit():
            files = CKPT_FILES.get(algo, ["agent.th"])
            if all((d / f).is_file() and (d / f).stat().st_size > 0 for f in files):
                found.append((int(d.name), d))
    return sorted(found, key=lambda x: (x[0], x[1].stat().st_mtime))


def loadable(ckpt: Path) -> bool:
    """A checkpoint cut short by a kill fails to load: check each file with torch.load."""
    try:
        import torch
    except ImportError:  # cannot check: trust the sizes
        return True
    try:
        for f in ckpt.iterdir():
            if f.suffix == ".th":
                torch.load(f, map_location="cpu", weights_only=False)
        return True
    except Exception as exc:  # noqa: BLE001 - any failure means "not this one"
        log(f"  checkpoint {ckpt} does not load ({exc.__class__.__name__}); trying an older one")
        return False


def latest_checkpoint(job_dir: Path, algo: str) -> tuple[int, Path] | None:
    for t, d in reversed(checkpoints(job_dir, algo)):
        if loadable(d):
            return t, d
    return None


def pid_alive(job_dir: Path) -> int | None:
    """The pid of a still-running EPyMARL process of this job (e.g. left by an orchestrator killed with -9)."""
    try:
        pid = int((job_dir / "pid").read_text().split()[0])
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except (OSError, ValueError, IndexError):
        return None
    return pid if ("main.py" in cmd and str(job_dir) in cmd) else None


def next_index(job_dir: Path) -> int:
    logs = job_dir / "logs"
    nums = [int(m.group(1)) for p in logs.glob("*.log") if (m := re.fullmatch(r"(\d+)\.log", p.name))]
    return max(nums, default=0) + 1


def command(job: Job, job_dir: Path, args: argparse.Namespace, resume: tuple[int, Path] | None,
            n: int) -> list[str]:
    cmd = [sys.executable, "src/main.py", f"--config={job.algo}", "--env-config=sc2",
           "-F", str(job_dir / "sacred" / str(n)), "with",
           f"env_args.map_name={job.map_name}", f"seed={job.seed}", f"t_max={args.t_max}",
           "save_model=True", f"save_model_interval={args.save_interval}",
           f"local_results_path={json.dumps(str(job_dir))}"]
    if resume is not None:
        t, ckpt = resume
        # a quoted value: sacred would otherwise try to parse the folder name (it holds a date and spaces)
        cmd += [f"checkpoint_path={json.dumps(str(ckpt.parent))}", f"load_step={t}"]
    if (size := buffer_size(job, args)) is not None:
        cmd.append(f"buffer_size={size}")
    if job.algo == "qmix" and args.qmix_envs > 1:
        # qmix.yaml's episode runner steps 1 env and trains after every episode; the parallel runner steps
        # batch_size_run envs and trains once per batch of episodes (pymarl2, the paper's QMIX, uses 8)
        cmd += ["runner=parallel", f"batch_size_run={args.qmix_envs}"]
    cmd += args.set
    return cmd


def episode_bytes(map_name: str) -> int:
    """Bytes one episode takes in EPyMARL's ReplayBuffer (th.zeros, preallocated for episode_limit + 1 steps):
    state, reward, terminated, filled, and per agent obs, action (int64), avail_actions (int32), actions_onehot."""
    try:
        from smac_hard_gym import StarCraft2Env

        info = StarCraft2Env(map_name=map_name).get_env_info()
    except Exception as exc:  # noqa: BLE001 - a broken import must not stop the other jobs
        if map_name in EPISODE_MB:
            log(f"  cannot size {map_name}'s buffer from the env ({exc.__class__.__name__}); using the table")
            return int(EPISODE_MB[map_name] * 1e6)
        raise
    a, n = info["n_agents"], info["n_actions"]
    per_step = info["state_shape"] * 4 + 4 + 1 + 8 + a * (info["obs_shape"] * 4 + 8 + 4 * n + 4 * n)
    return per_step * (info["episode_limit"] + 1)


def buffer_size(job: Job, args: argparse.Namespace) -> int | None:
    """QMIX's buffer (qmix.yaml: 5000 episodes) capped to --buffer-gb; None when the default fits."""
    if job.algo != "qmix" or args.buffer_gb <= 0:
        return None
    fits = int(args.buffer_gb * 1e9 // episode_bytes(job.map_name))
    return fits if fits < 5000 else None


def job_env() -> dict[str, str]:
    env = dict(os.environ)
    paths = [str(SHIM)]
    if importlib.util.find_spec("smaclite") is None:
        paths.append(str(STUBS))  # EPyMARL imports smaclite at start-up; sc2 never uses it
    if env.get("PYTHONPATH"):
        paths.append(env["PYTHONPATH"])
    env["PYTHONPATH"] = os.pathsep.join(paths)
    # two jobs share the cores: one thread each for numba's parallel kernels and torch's intra-op pool
    env.setdefault("NUMBA_NUM_THREADS", "1")
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("MKL_NUM_THREADS", "1")
    return env


def provenance(epymarl: Path) -> str:
    """The code a start runs: smac-hard-gym's and EPyMARL's commits (a resumed job may run newer code)."""
    def rev(path: Path) -> str:
        try:
            head = subprocess.run(["git", "-C", str(path), "rev-parse", "HEAD"], capture_output=True, text=True,
                                  check=True).stdout.strip()
            dirty = subprocess.run(["git", "-C", str(path), "status", "--porcelain", "--untracked-files=no"],
                                   capture_output=True, text=True, check=True).stdout.strip()
            return head + (" (with uncommitted changes)" if dirty else "")
        except (OSError, subprocess.CalledProcessError):
            return "unknown"
    return f"smac-hard-gym {rev(REPO)}; EPyMARL {rev(epymarl)}"


# what decides a reference run's games: the engine, the unit table, the SMAC layer, the envs, the opponents, the maps
_FINGERPRINT_PACKAGES = ("smac_hard_gym.engine", "smac_hard_gym.smac", "smac_hard_gym.envs",
                         "smac_hard_gym.opponents", "smac_hard_gym.maps")
_FINGERPRINT_MODULES = ("smac_hard_gym.backend",)


def engine_fingerprint(cwd: Path) -> str:
    """sha256 (first 16 hex digits) over the source and map files of the smac-hard-gym the jobs import.

    Computed in a child with the jobs' environment and working folder (``cwd``, the EPyMARL checkout), so it
    describes the code EPyMARL will import, not the code this script happens to see."""
    probe = (
        "import hashlib, importlib, pathlib\n"
        f"packages, modules = {_FINGERPRINT_PACKAGES!r}, {_FINGERPRINT_MODULES!r}\n"
        "files = set()\n"
        "for name in packages:\n"
        "    for root in importlib.import_module(name).__path__:\n"
        "        files |= {p for p in pathlib.Path(root).rglob('*') if p.suffix in ('.py', '.json')}\n"
        "files |= {pathlib.Path(importlib.import_module(name).__file__) for name in modules}\n"
        "h = hashlib.sha256()\n"
        "for p in sorted(files, key=lambda p: (p.name, str(p))):\n"
        "    if '__pycache__' not in p.parts:\n"
        "        h.update(p.name.encode()); h.update(p.read_bytes())\n"
        "print(h.hexdigest()[:16])\n")
    out = subprocess.run([sys.executable, "-c", probe], env=job_env(), cwd=cwd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"cannot import smac-hard-gym as the jobs would:\n{out.stderr[-2000:]}")
    return out.stdout.strip()


def started_on(job_dir: Path) -> str | None:
    """The engine fingerprint a job started on (None: not recorded, e.g. a job from before fingerprints)."""
    try:
        return json.loads((job_dir / "engine.json").read_text())["fingerprint"]
    except (OSError, ValueError, KeyError):
        return None


def sacred_completed(job_dir: Path) -> bool:
    """sacred recorded a completed run in the job's newest start (EPyMARL reached t_max and exited cleanly)."""
    runs = sorted(job_dir.glob("sacred/*/*/run.json"), key=lambda p: (int(p.parts[-3]), p.stat().st_mtime))
    if not runs:
        return False
    try:
        return json.loads(runs[-1].read_text()).get("status") == "COMPLETED"
    except (OSError, ValueError):
        return False


def mark_done(job: Job, job_dir: Path, t_max: int, how: str) -> None:
    ckpts = checkpoints(job_dir, job.algo)
    (job_dir / "done.json").write_text(json.dumps(
        {"finished": dt.datetime.now().isoformat(timespec="seconds"), "t_max": t_max, "how": how,
         "last_checkpoint_t_env": ckpts[-1][0] if ckpts else None}, indent=1) + "\n")


def _nice() -> None:
    os.nice(max(0, 19 - os.nice(0)))


class Pool:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.running: dict[Job, subprocess.Popen] = {}
        self.files: dict[Job, object] = {}
        self.failed: set[Job] = set()
        self.adopted: dict[Job, int] = {}  # jobs still running from an earlier launch: pid

    def busy(self) -> int:
        return len(self.running) + len(self.adopted)

    def finished(self, job: Job, rc: int | None) -> None:
        job_dir = job.dir(self.args.out)
        text = (job_dir / "logs" / f"{next_index(job_dir) - 1}.log").read_text(errors="replace")
        if rc in (0, None) and "Finished Training" in text:
            mark_done(job, job_dir, self.args.t_max, "log: Finished Training")
            log(f"done  {job.name}")
        else:
            log(f"FAILED {job.name} (exit {rc}); see its log. It is retried on the next launch.")
            self.failed.add(job)

    def start(self, job: Job) -> None:
        job_dir = job.dir(self.args.out)
        (job_dir / "logs").mkdir(parents=True, exist_ok=True)
        resume = latest_checkpoint(job_dir, job.algo)
        if resume is None:  # a fresh start records its engine (a job from before fingerprints resumes unrecorded)
            (job_dir / "engine.json").write_text(json.dumps({"fingerprint": self.args.fingerprint}) + "\n")
        n = next_index(job_dir)
        cmd = command(job, job_dir, self.args, resume, n)
        logf = open(job_dir / "logs" / f"{n}.log", "w")  # noqa: SIM115 - closed when the job ends
        logf.write("# " + " ".join(cmd) + "\n# " + provenance(self.args.epymarl) + "\n")
        logf.flush()
        what = f"resume from t_env={resume[0]} ({resume[1]})" if resume else "fresh start"
        log(f"start {job.name}: {what}; log {job_dir / 'logs' / f'{n}.log'}")
        proc = subprocess.Popen(cmd, cwd=self.args.epymarl, env=job_env(), stdout=logf, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, preexec_fn=_nice, start_new_session=True)
        (job_dir / "pid").write_text(f"{proc.pid}\n")
        self.running[job], self.files[job] = proc, logf

    def reap(self) -> None:
        for job, proc in list(self.running.items()):
            rc = proc.poll()
            if rc is None:
                continue
            self.files.pop(job).close()
            del self.running[job]
            self.finished(job, rc)
        for job, _pid in list(self.adopted.items()):
            if pid_alive(job.dir(self.args.out)) is None:  # not our child: no exit code, judge by its log
                del self.adopted[job]
                self.finished(job, None)

    def stop_all(self, *_: object) -> None:
        for job, proc in self.running.items():
            log(f"stopping {job.name} (pid {proc.pid})")
            try:
                os.killpg(proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        deadline = time.time() + 30
        for proc in self.running.values():
            try:
                proc.wait(timeout=max(1, deadline - time.time()))
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
        sys.exit(1)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--epymarl", type=Path, default=DEFAULT_EPYMARL, help="EPyMARL checkout (install.sh --dest)")
    p.add_argument("--out", type=Path, required=True, help="results folder (outside the repository)")
    p.add_argument("--algos", default="qmix,mappo", help="comma list, run in this order (default qmix,mappo)")
    p.add_argument("--maps", default=",".join(MAPS), help="comma list, run in this order")
    p.add_argument("--seeds", default="0", help="comma list of seeds (default 0)")
    p.add_argument("--jobs", type=int, default=2, help="at most this many runs at a time (default 2)")
    p.add_argument("--t-max", type=int, default=2_050_000, help="EPyMARL t_max (default 2050000)")
    p.add_argument("--save-interval", type=int, default=100_000, help="save_model_interval (default 100000)")
    p.add_argument("--qmix-envs", type=int, default=2,
                   help="QMIX: runner=parallel with this many envs (default 2; 1 = qmix.yaml's episode runner)")
    p.add_argument("--buffer-gb", type=float, default=4.0,
                   help="QMIX: cap the replay buffer (5000 episodes, allocated up front) to this many GB; "
                        "0 = no cap (default 4: 25m, corridor, 3s5z_vs_3s6z, MMM2, 27m_vs_30m get fewer episodes)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="extra sacred config update passed to every job (repeatable), e.g. test_interval=10000")
    p.add_argument("--poll", type=float, default=20.0, help="seconds between checks (default 20)")
    p.add_argument("--restart-changed", action="store_true",
                   help="start again (old folder moved aside) the jobs begun on a different smac-hard-gym engine")
    p.add_argument("--dry-run", action="store_true", help="print each job's state and command, start nothing")
    args = p.parse_args(argv)
    args.out = args.out.expanduser().resolve()
    args.epymarl = args.epymarl.expanduser().resolve()
    if not (args.epymarl / "src" / "main.py").is_file():
        p.error(f"no EPyMARL at {args.epymarl}: run benchmarks/epymarl/install.sh first")
    missing = [m for m in ("sacred", "einops", "yaml", "torch") if importlib.util.find_spec(m) is None]
    if missing:
        p.error(f"{', '.join(missing)} not installed in this venv: run benchmarks/epymarl/install.sh first")
    # all maps of the first algorithm and seed first (QMIX seed 0 on every map, then MAPPO)
    jobs = [Job(a, m, int(s)) for a in args.algos.split(",") for s in args.seeds.split(",")
            for m in args.maps.split(",")]

    args.fingerprint = engine_fingerprint(args.epymarl)
    log(f"smac-hard-gym engine fingerprint {args.fingerprint}")
    pending, adopted = [], {}
    for job in jobs:
        d = job.dir(args.out)
        pid = pid_alive(d)
        if not pid and not (d / "done.json").is_file() and sacred_completed(d):
            mark_done(job, d, args.t_max, "sacred run.json: COMPLETED")
        done = (d / "done.json").is_file()
        ck = checkpoints(d, job.algo)
        began = started_on(d)
        if ck and not done and not pid and began not in (None, args.fingerprint):
            if args.restart_changed and not args.dry_run:
                d.rename(d.with_name(f"{d.name}.engine-{began}"))
                ck = []
            else:
                log(f"{job.name:32s} begun on engine {began}, now {args.fingerprint}: not resumed "
                    f"(--restart-changed starts it again)")
                continue
        state = ("done" if done else f"running (pid {pid}, left by an earlier launch)" if pid else
                 f"resume at t_env={ck[-1][0]}" if ck else "new")
        log(f"{job.name:32s} {state}")
        if state == "new" or state.startswith("resume"):
            pending.append(job)
        elif pid:
            adopted[job] = pid  # left running by a launch whose orchestrator died: wait for it, counts as a slot
        if args.dry_run and state != "done" and not pid:
            print("   ", " ".join(command(job, d, args, ck[-1] if ck else None, next_index(d))))
    if args.dry_run:
        return 0
    args.out.mkdir(parents=True, exist_ok=True)

    pool = Pool(args)
    pool.adopted.update(adopted)
    signal.signal(signal.SIGTERM, pool.stop_all)
    signal.signal(signal.SIGINT, pool.stop_all)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    while pending or pool.busy():
        while pending and pool.busy() < args.jobs:
            pool.start(pending.pop(0))
        time.sleep(args.poll)
        pool.reap()
    log(f"all jobs ended; failed: {sorted(j.name for j in pool.failed) or 'none'}")
    return 1 if pool.failed else 0


if __name__ == "__main__":
    sys.exit(main())
