"""RayVectorEnv: the same episodes as SubprocVectorEnv for the same seeds, an actor killed mid-run is rebuilt and its
battles flagged, and close() leaves no actor. Runs on a local Ray started here (2 CPUs); skipped without ray."""

import functools
import signal
import time

import numpy as np
import pytest
from fuzz_harness import SEED, VectorApi, fuzz_remote
from gymnasium.vector import AutoresetMode
from test_vector_env import assert_same

ray = pytest.importorskip("ray", reason="ray is not installed (pip install 'smac-hard-gym[ray]')")

from smac_hard_gym.envs.subproc import RESTART_KEY, WorkerError, make_subproc_env  # noqa: E402
from smac_hard_gym.envs.vector import NativeVectorEnv  # noqa: E402
from smac_hard_gym.wrappers.ray_vec import RayVectorEnv, make_ray_vec  # noqa: E402

pytestmark = pytest.mark.long  # a local Ray and its actors: 127 s for the module at load 8 on 2 cores

TEST_DEADLINE = 240  # seconds any one test may take on a loaded 2-core machine
HANG_BOUND = 150  # seconds: a hung actor's replacement (timeout=3 s) must come well before its 600 s sleep ends


@pytest.fixture(scope="module", autouse=True)
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(autouse=True)
def deadline():
    """Fail a test that runs past TEST_DEADLINE instead of hanging the suite."""
    def expire(signum, frame):
        raise TimeoutError(f"test ran past its {TEST_DEADLINE} s deadline")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(TEST_DEADLINE)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def _gone(names):
    """True when Ray finds none of the named actors."""
    for name in names:
        try:
            ray.get_actor(name)
            return False
        except ValueError:
            pass
    return True


def _kill_and_wait(actor, timeout=60.0):
    """Kill an actor and wait until Ray reports it dead: ``ray.kill`` only asks, and a call sent at once can still be
    answered by the dying actor (the race that made the step after the kill succeed now and then)."""
    ray.kill(actor)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            ray.get(actor.pid.remote(), timeout=max(0.1, min(5.0, deadline - time.monotonic())))
        except ray.exceptions.RayActorError:
            return
        except ray.exceptions.GetTimeoutError:
            continue  # a probe that hangs (actor neither alive nor reported dead yet): probe again until the deadline
        time.sleep(0.05)
    raise TimeoutError(f"the killed actor still answered after {timeout:g} s")


def _legal_actions(env, rng, n, agents, n_actions):
    masks = env.action_masks().reshape(n, agents, n_actions)
    return np.array([[rng.choice(np.flatnonzero(m)) for m in row] for row in masks])


@pytest.mark.parametrize("mode", [AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP])
def test_same_seeds_give_the_episodes_of_the_subprocess_env(mode):
    kwargs = {"opponent": "default", "invalid_action": "noop", "max_episode_steps": 12}
    ray_env = make_ray_vec("3m", 2, 3, autoreset_mode=mode, **kwargs)
    sub_env = make_subproc_env("3m", 2, 3, autoreset_mode=mode, **kwargs)
    try:
        assert ray_env.single_observation_space == sub_env.single_observation_space
        assert ray_env.single_action_space == sub_env.single_action_space
        assert ray_env.metadata["autoreset_mode"] is mode
        for got, want in zip(ray_env.reset(seed=5), sub_env.reset(seed=5), strict=True):
            assert_same(got, want)
        rng = np.random.default_rng(0)
        ended = 0
        for _ in range(50):
            np.testing.assert_array_equal(ray_env.action_masks(), sub_env.action_masks())
            actions = _legal_actions(sub_env, rng, 6, 3, 9)
            got, want = ray_env.step(actions), sub_env.step(actions)
            for name, x, y in zip("obs reward terminated truncated infos".split(), got, want, strict=True):
                assert_same(x, y, name)
            ended += int((got[2] | got[3]).sum())
        assert ended >= 6  # episodes of at most 12 steps: autoreset was exercised
    finally:
        ray_env.close()
        sub_env.close()


def test_dict_observations_stacked_frames_and_reset_masks_match_too():
    kwargs = {"opponent": "base", "obs_mode": "dict", "max_episode_steps": 8, "frame_stack": 3}
    ray_env = make_ray_vec("2s3z", 2, 2, autoreset_mode="Disabled", **kwargs)
    sub_env = make_subproc_env("2s3z", 2, 2, autoreset_mode="Disabled", **kwargs)
    try:
        one_frame = NativeVectorEnv("2s3z", 1, obs_mode="dict").single_observation_space["obs"].shape
        assert ray_env.single_observation_space["obs"].shape == (one_frame[0], 3 * one_frame[1])
        for got, want in zip(ray_env.reset(seed=1), sub_env.reset(seed=1), strict=True):
            assert_same(got, want)
        for _ in range(8):
            actions = np.ones((4, 5), dtype=np.int64)
            for x, y in zip(ray_env.step(actions), sub_env.step(actions), strict=True):
                assert_same(x, y)
        mask = np.array([False, True, True, False])
        for got, want in zip(ray_env.reset(seed=9, options={"reset_mask": mask}),
                             sub_env.reset(seed=9, options={"reset_mask": mask}), strict=True):
            assert_same(got, want)
    finally:
        ray_env.close()
        sub_env.close()


@pytest.mark.parametrize("mode", [AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP])
def test_killing_an_actor_mid_run_rebuilds_it_with_its_battles_flagged(mode):
    # Behaviour only, no wall-clock bound: the step after the kill must come back (the module's deadline catches a
    # hang) with the rebuilt actor's battles flagged; how long the rebuild takes depends on the machine's load.
    env = make_ray_vec("3m", 2, 2, autoreset_mode=mode, on_worker_error="restart", opponent="base")
    try:
        env.reset(seed=0)
        rng = np.random.default_rng(1)
        for _ in range(3):
            env.step(_legal_actions(env, rng, 4, 3, 9))
        kept, killed = env.actor_names
        _kill_and_wait(env.actors[1])
        obs, reward, terminated, truncated, infos = env.step(_legal_actions(env, rng, 4, 3, 9))
        assert infos[RESTART_KEY].tolist() == [False, False, True, True]
        assert infos[f"_{RESTART_KEY}"].tolist() == [False, False, True, True]
        assert truncated[2:].all() and env.restarts == 1
        assert env.actor_names[0] == kept and env.actor_names[1] != killed
        assert killed not in env.actor_names and _gone([killed]) and not _gone([env.actor_names[1]])
        if mode == AutoresetMode.SAME_STEP:
            assert infos["_final_obs"][2:].all()
        for _ in range(5):  # the rebuilt actor plays on
            obs, reward, terminated, truncated, infos = env.step(_legal_actions(env, rng, 4, 3, 9))
            assert RESTART_KEY not in infos
        assert obs.shape == (4, env.single_observation_space.shape[0])
    finally:
        env.close()


def test_killing_an_actor_with_raise_closes_everything_and_names_it():
    env = make_ray_vec("3m", 2, 1, autoreset_mode="SameStep", opponent="base")
    names = env.actor_names
    env.reset(seed=0)
    _kill_and_wait(env.actors[0])
    with pytest.raises(WorkerError, match=r"worker 0 \(battles 0..0\): died during step"):
        env.step(np.ones((2, 3), dtype=np.int64))
    assert env.closed and _gone(names)


def test_close_leaves_no_actor():
    env = make_ray_vec("3m", 2, 2, autoreset_mode="SameStep")
    names = env.actor_names
    assert len(names) == 2 and not _gone(names[:1]) and not _gone(names[1:])
    env.reset(seed=0)
    env.close()
    assert _gone(names)
    env.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()


def test_env_errors_reach_the_parent_and_bad_factories_are_reported():
    env = RayVectorEnv([functools.partial(NativeVectorEnv, "3m", num_envs=2, autoreset_mode="SameStep",
                                          invalid_action="raise")], autoreset_mode="SameStep")
    try:
        env.reset(seed=0)
        with pytest.raises(Exception, match="not available"):
            env.step(np.full((2, 3), 8, dtype=np.int64))
        env.step(np.ones((2, 3), dtype=np.int64))  # the env goes on
    finally:
        env.close()
    with pytest.raises(WorkerError, match="unknown map"):
        RayVectorEnv([functools.partial(NativeVectorEnv, "no_such_map", num_envs=2)])
    with pytest.raises(ValueError, match="unknown map"):
        make_ray_vec("no_such_map", 1, 1)
    with pytest.raises(ValueError, match="3 actors reserving 1 CPU each need 3 CPUs but the Ray cluster has 2"):
        make_ray_vec("3m", 3, 1)


def test_malformed_actions_are_rejected_before_any_actor_steps():
    rng = np.random.default_rng([SEED, 300])
    native = VectorApi("3m", opponent="default")
    env = make_ray_vec("3m", 2, 1, invalid_action="raise", autoreset_mode="SameStep", opponent="default")
    try:
        fuzz_remote(env, native, rng, rounds=40)
    finally:
        env.close()
        native.close()


def test_make_ray_vec_is_a_lazy_export():
    import smac_hard_gym

    assert smac_hard_gym.make_ray_vec is make_ray_vec
    assert smac_hard_gym.RayVectorEnv is RayVectorEnv


def test_train_on_ray_actors(tmp_path, capsys):
    pytest.importorskip("sb3_contrib", reason="training needs the [train] extra")
    import json

    from smac_hard_gym.cli import main

    out = tmp_path / "run"
    code = main(["train", "--ray", "--ray-actors", "2", "--map", "3m", "--timesteps", "256", "--num-envs", "4",
                 "--n-steps", "32", "--batch-size", "64", "--epochs", "1", "--eval-every", "256",
                 "--eval-episodes", "2", "--out", str(out), "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "training battles on Ray: RayVectorEnv(num_envs=4, actors=[2, 2]" in printed
    config = json.loads((out / "config.json").read_text())
    assert config["ray"] is True and config["ray_actors"] == 2
    assert json.loads((out / "summary.json").read_text())["timesteps"] == 256
    assert not [name for name in ray.util.list_named_actors() if name.startswith("smac-hard-gym-actor")]


def test_league_and_ray_together_are_a_clear_error():
    from smac_hard_gym.cli import main
    from smac_hard_gym.training import TrainConfig

    with pytest.raises(SystemExit, match="--league and --ray cannot be combined: the league lives in the learner"):
        main(["train", "--league", "--ray", "--map", "3m"])
    with pytest.raises(ValueError, match="ray_actors must be a positive int dividing num_envs"):
        TrainConfig(num_envs=6, ray=True, ray_actors=4)


def test_bench_ray_section_writes_ray_and_subproc_rows_and_payload_sizes(tmp_path):
    import json

    from smac_hard_gym.cli import main

    path = tmp_path / "ray.json"
    assert main(["bench", "vector", "--sections", "ray", "--ray-maps", "3m", "--ray-envs-per-actor", "2",
                 "--seconds", "0.05", "--repeats", "2", "--json", str(path)]) == 0
    doc = json.loads(path.read_text())
    rows = {(r["mode"], r["workers"]): r for r in doc["results"] if r["section"] == "ray"}
    assert set(rows) == {("ray", 1), ("subproc", 1), ("ray", 2), ("subproc", 2)}
    assert all(len(r["runs"]) == 2 and r["steps_per_second"] > 0 for r in rows.values())
    payload = doc["ray_payload"][0]["bytes_per_step_per_actor"]
    assert payload["observations"] == 2 * 90 * 4 and payload["actions"] == 2 * 3 * 8
    assert "Ray actors vs subprocess workers" in path.with_suffix(".md").read_text()


def test_a_hung_actor_is_replaced_after_the_timeout(tmp_path):
    import cloudpickle
    import test_subproc

    hang = tmp_path / "hang"
    factories = [functools.partial(test_subproc.TickEnv, 1.0),
                 functools.partial(test_subproc.TickEnv, 2.0, hang_file=str(hang))]
    cloudpickle.register_pickle_by_value(test_subproc)  # the actors cannot import the tests
    try:
        env = RayVectorEnv(factories, autoreset_mode="NextStep", timeout=3.0, on_worker_error="restart")
    finally:
        cloudpickle.unregister_pickle_by_value(test_subproc)
    try:
        env.reset()
        env.step(np.zeros(2, dtype=np.int64))  # warm: from now on `timeout` applies
        hung = env.actor_names[1]
        hang.touch()
        start = time.monotonic()
        obs, reward, terminated, truncated, infos = env.step(np.zeros(2, dtype=np.int64))
        # The hung step sleeps 600 s: coming back at all means the 3 s timeout fired. The bound only tells that apart
        # from waiting the sleep out, with room for a loaded machine (a quiet one needs about 4 s).
        assert time.monotonic() - start < HANG_BOUND
        assert infos[RESTART_KEY].tolist() == [False, True] and truncated.tolist() == [False, True]
        assert env.restarts == 1 and env.actor_names[1] != hung and _gone([hung])
        obs, *_ = env.step(np.zeros(2, dtype=np.int64))  # NEXT_STEP: the rebuilt actor starts a new episode
        assert obs.tolist() == [[3, 1], [0, 2]]
    finally:
        env.close()
