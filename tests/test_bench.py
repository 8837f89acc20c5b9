"""The benchmark suite: its policy, its target arithmetic, and a smoke run of the CLI with tiny sizes.

No timing assertions: speed figures live in benchmarks/, not in tests.
"""

import json

import numpy as np
import pytest

from smac_hard_gym.bench import RandomLegalPolicy, must_reach
from smac_hard_gym.cli import main


def test_random_legal_policy_is_legal_and_uniform():
    # Two battles, two agents, five actions; agent masks with 1, 2 and 5 legal actions.
    masks = np.zeros((2, 2, 5), dtype=bool)
    masks[0, 0, [0]] = True
    masks[0, 1, [1, 3]] = True
    masks[1, 0, :] = True
    masks[1, 1, [2, 4]] = True
    policy = RandomLegalPolicy(2, 2, 5, seed=1)
    counts = np.zeros((2, 2, 5))
    draws = 4000
    for _ in range(draws):
        actions = policy(masks.reshape(2, 10))
        assert masks[np.arange(2)[:, None], np.arange(2)[None, :], actions].all()
        np.put_along_axis(counts, actions[..., None], np.take_along_axis(counts, actions[..., None], 2) + 1, 2)
    assert counts[0, 0, 0] == draws
    # Uniform among the legal ones: each of k legal actions near draws / k (binomial sd < 32 here; 5 sd slack).
    for b, a, legal in ((0, 1, [1, 3]), (1, 0, [0, 1, 2, 3, 4]), (1, 1, [2, 4])):
        expected = draws / len(legal)
        assert np.all(np.abs(counts[b, a, legal] - expected) < 160), counts[b, a]


def _doc(native=None, smax=None, sc2=None, loop=None, subproc=(), memory=()):
    rows = []
    for name, value in (native or {}).items():
        rows.append({"section": "native", "map": name, "num_envs": 4096, "steps_per_second": value,
                     "peak_bytes_per_env": 20_000.0, "runs": [value]})
    for name, value in (smax or {}).items():
        rows.append({"section": "smax", "map": name, "num_envs": 1024, "mode": "scan", "steps_per_second": value,
                     "runs": [value]})
    if sc2 is not None:
        rows.append({"section": "starcraft2", "map": "3m", "num_envs": 1, "opponent": "base",
                     "steps_per_second": sc2, "runs": [sc2]})
    if loop is not None:
        rows.append({"section": "smax", "map": "3m", "num_envs": 1, "mode": "loop", "steps_per_second": loop,
                     "runs": [loop]})
    for name, k, workers, value in subproc:
        rows.append({"section": "subproc", "map": name, "num_envs": k * workers, "workers": workers,
                     "steps_per_second": value, "runs": [value], "extra": {"envs_per_worker": k}})
    return {"results": rows, "memory": list(memory)}


def test_must_reach_ratios_and_verdicts():
    doc = _doc(native={"3m": 50_000.0, "8m": 40_000.0}, smax={"3m": 10_000.0, "8m": 10_000.0}, sc2=3_000.0,
               loop=2_000.0,
               # 3m K=16 is the light configuration; 27m K=256 (0.256 s a step for one worker) is env-dominated.
               subproc=[("3m", 16, 1, 8_000.0), ("3m", 16, 2, 4_000.0),
                        ("27m_vs_30m", 256, 1, 1_000.0), ("27m_vs_30m", 256, 2, 1_800.0)],
               memory=[{"map": "3m", "num_envs": 4096, "rss_bytes_per_env": 60 * 1024}])
    targets = {t["target"]: t for t in must_reach(doc)}
    t3m = targets["native best batch >= 5x SMAX best batch, 3m"]
    assert (t3m["value"], t3m["hit"]) == (5.0, True)
    t8m = targets["native best batch >= 5x SMAX best batch, 8m"]
    assert t8m["value"] == 4.0 and not t8m["hit"] and t8m["margin"] == pytest.approx(0.8)
    single = targets["StarCraft2Env 3m B=1 >= 2x SMAX single-env Python loop"]
    assert single["value"] == 1.5 and not single["hit"]
    workers = targets["subprocess 2 workers >= 1.7x 1 worker (env-dominated)"]
    assert workers["value"] == pytest.approx(1.8) and workers["hit"] and "27m_vs_30m" in workers["detail"]
    memory = targets["peak memory, 3m x 4096 <= 100 KB per battle"]
    assert memory["value"] == pytest.approx(60.0) and memory["hit"]  # RSS 60 KB beats the traced 19.5 KB
    assert "native best batch >= 5x SMAX best batch, 27m_vs_30m" not in targets  # no figures, no verdict


@pytest.mark.long  # every section, subprocess workers included: 53 s at load 8
def test_bench_vector_cli_writes_every_section_it_is_asked_for(tmp_path, capsys):
    out = tmp_path / "run" / "bench.json"
    code = main(["bench", "vector", "--maps", "3m", "--num-envs", "2", "--sections",
                 "native,subproc,starcraft2,opponents,profile", "--workers", "1", "--envs-per-worker", "2",
                 "--subproc-maps", "3m", "--opponent-num-envs", "2", "--memory", "3m:256", "--profile", "3m:2",
                 "--seconds", "0.05", "--repeats", "2", "--json", str(out)])
    assert code == 0
    doc = json.loads(out.read_text())
    by_section = {}
    for r in doc["results"]:
        by_section.setdefault(r["section"], []).append(r)
    native = by_section["native"][0]
    assert (native["map"], native["num_envs"], len(native["runs"])) == ("3m", 2, 2)
    assert native["steps_per_second"] > 0 and native["peak_bytes_per_env"] > 0
    assert [(r["workers"], r["num_envs"]) for r in by_section["subproc"]] == [(1, 2)]
    assert sorted(r["opponent"] for r in by_section["starcraft2"]) == ["base", "default"]
    assert sorted(r["opponent"] for r in by_section["opponents"]) == ["base", "default"]
    # 256 battles: enough that their arrays grow RSS by more than a page (4 battles could fit in the heap slack)
    assert doc["memory"][0]["num_envs"] == 256 and doc["memory"][0]["rss_bytes_per_env"] > 0
    assert {p["what"] for p in doc["profiles"]} == {"native", "starcraft2"}
    profile = doc["profiles"][0]
    assert profile["share"]["engine step"] > 0 and sum(profile["share"].values()) >= 0.99
    assert {"cpu", "cores", "numba", "python", "date"} <= set(doc["machine"])
    markdown = out.with_suffix(".md").read_text()
    assert "| 3m | 2 |" in markdown and "Subprocess vector env" in markdown
    assert out.with_suffix(".png").stat().st_size > 0
    assert "| 3m | 2 |" in capsys.readouterr().out
    # The JSON alone re-renders the same tables.
    out.with_suffix(".md").unlink()
    assert main(["bench", "report", str(out)]) == 0
    assert out.with_suffix(".md").read_text() == markdown


def test_bench_report_rejects_other_json(tmp_path, capsys):
    path = tmp_path / "engine.json"
    path.write_text(json.dumps({"benchmark": "engine", "results": []}))
    assert main(["bench", "report", str(path)]) == 2
    assert "not a `bench vector` result" in capsys.readouterr().err


def test_bench_vector_rejects_bad_input(capsys):
    assert main(["bench", "vector", "--maps", "nosuchmap", "--sections", "native"]) == 2
    assert "nosuchmap" in capsys.readouterr().err
    assert main(["bench", "vector", "--sections", "native,bogus"]) == 2
    assert "bogus" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["bench", "vector", "--num-envs", "0"])
    assert "positive ints" in capsys.readouterr().err


def test_peer_without_jaxmarl_says_how_to_set_it_up(tmp_path, capsys):
    code = main(["bench", "vector", "--maps", "3m", "--sections", "native", "--peer", "smax",
                 "--peer-python", str(tmp_path / "no-python")])
    assert code == 2
    err = capsys.readouterr().err
    assert "jaxmarl" in err and "pip install" in err


def test_bench_engine_cli_writes_an_engine_result(tmp_path):
    out = tmp_path / "engine.json"
    assert main(["bench", "engine", "--map", "3m", "--batch", "2", "--steps", "2", "--repeats", "1",
                 "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["benchmark"] == "engine" and doc["results"][0]["num_envs"] == 2


@pytest.mark.long  # PPO training runs, 3 variants x 2 rounds: 26 s at load 8
def test_bench_train_interleaves_both_variants_to_the_same_weights(tmp_path, capsys):
    out = tmp_path / "train.json"
    assert main(["bench", "train", "--map", "3m", "--timesteps", "2048", "--rounds", "2", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["benchmark"] == "train" and [r["mode"] for r in doc["results"]] == ["stock", "joint", "shared"]
    for result in doc["results"]:
        assert len(result["runs"]) == 2 and result["steps_per_second"] > 0 and result["num_envs"] == 64
        # the same seed and steps, each variant on its own copy of the random streams: equal weights, a cross-check
        # that the joint policy and buffer are sb3-contrib's, not only a timing (the shared policy is another net)
        assert result["extra"]["same_weights"] is (None if result["mode"] == "shared" else True)
    assert doc["results"][0]["extra"]["speedup_vs_stock"] == 1.0
    assert doc["results"][1]["extra"]["speedup_vs_joint"] == 1.0
    assert "same weights" in capsys.readouterr().out


def test_bench_train_rejects_bad_input(capsys):
    assert main(["bench", "train", "--map", "nosuchmap"]) == 2
    assert "nosuchmap" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["bench", "train", "--rounds", "0"])
    assert "positive int" in capsys.readouterr().err
