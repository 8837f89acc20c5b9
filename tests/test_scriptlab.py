"""The script lab without a network: a fake chat-completions server on 127.0.0.1 replays recorded replies
(tests/data/scriptlab) through the real HTTP client. Few episodes on 3m keep it short; 64 is for real use."""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from smac_hard_gym.cli import main
from smac_hard_gym.engine.units import UNITS, unit_index
from smac_hard_gym.maps import load_map
from smac_hard_gym.opponents.sandbox import SUPPORTED
from smac_hard_gym.scriptlab import (
    KEY_ENV,
    ChatClient,
    LabConfig,
    LLMError,
    checks,
    list_scripts,
    load_pool,
    prompts,
    run_lab,
)
from smac_hard_gym.scriptlab.client import Transcript

DATA = Path(__file__).parent / "data" / "scriptlab"
KEY = "sk-test-secret-0123456789"
EPISODES = 8


class _QuietServer(ThreadingHTTPServer):
    daemon_threads = True

    def handle_error(self, request, client_address):
        pass  # a client that gave up (the time-out test) breaks the pipe: printed, it would land in a later test


class FakeServer:
    """Replays recorded replies per role (the ``ROLE:`` line of the system prompt), recording every request."""

    def __init__(self, script: dict[str, list[str]] | None = None, mode: str = "replay") -> None:
        self.queues = {role: list(files) for role, files in (script or {}).items()}
        self.mode = mode
        self.requests: list[dict] = []
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):  # keep pytest's output clean
                pass

            def do_POST(self):
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                server.requests.append({"path": self.path, "headers": dict(self.headers), "body": body})
                status, data = server.answer(body)
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

        self.httpd = _QuietServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    def answer(self, body: dict) -> tuple[int, bytes]:
        if self.mode == "error":
            return 500, f"internal error; your key was {KEY}".encode()
        if self.mode == "not_json":
            return 200, b"<html>not json</html>"
        if self.mode == "slow":
            time.sleep(3)
        role = body["messages"][0]["content"].split("\n", 1)[0].removeprefix("ROLE: ").strip()
        name = self.queues[role].pop(0)
        text = (DATA / name).read_text()
        if name.endswith(".json"):  # a whole recorded response
            return 200, text.encode()
        doc = {"id": "fake", "object": "chat.completion", "model": body["model"],
               "choices": [{"index": 0, "message": {"role": "assistant", "content": text}, "finish_reason": "stop"}],
               "usage": {"prompt_tokens": len(json.dumps(body)) // 4, "completion_tokens": len(text) // 4}}
        return 200, json.dumps(doc).encode()

    def roles(self) -> list[str]:
        return [r["body"]["messages"][0]["content"].split("\n", 1)[0] for r in self.requests]

    def __enter__(self) -> FakeServer:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


def _script(name: str) -> dict[str, list[str]]:
    return json.loads((DATA / name).read_text())


# ---------------------------------------------------------------------------------------------------------------
# Prompts and checks (no server, no sandbox).


def test_prompts_come_from_the_sources():
    spec = load_map("3m")
    messages = prompts.coder_messages(spec, "blue", "attack", "", "", "")
    text = messages[1]["content"]
    assert messages[0]["content"].startswith("ROLE: blue_coder")
    marine = UNITS[unit_index("Marine")]
    assert f"| Marine | {marine.health:g} |" in text  # the unit table's numbers
    assert "3 x Marine_RL" in text and "32 x 32" in text  # the map spec
    assert "CMD_ATTACK_MOVE = 5 (attack_move)" in text  # the engine's constants
    assert "nearest_enemy(i: 'int') -> 'int': Index of the alive enemy nearest own unit i" in text  # docstrings
    assert "class FocusFire(BatchScript):" in text and "class LineAdvance" in text  # library sources
    assert f"class {prompts.SCRIPT_CLASS}(PerBattleScript)" in text


def test_sections_and_code_extraction():
    parts = prompts.split_sections("**RED:** go left\n## BLUE: go right", ("RED", "BLUE"))
    assert parts == {"RED": "go left", "BLUE": "go right"}
    assert prompts.split_sections("no sections", ("RED", "BLUE"))["BLUE"] == "no sections"
    assert checks.extract_code("text\n```python\nx = 1\n```\nmore") == "x = 1\n"
    assert checks.extract_code("no code here.") == ""
    feedback, _ = checks.parse_feedback(checks.extract_code((DATA / "syntax_red.md").read_text()))
    assert feedback.startswith("SyntaxError") and "line 8" in feedback
    feedback, code = checks.parse_feedback(checks.extract_code((DATA / "good_blue.md").read_text()))
    assert feedback == "" and code.rstrip().endswith("LabScript = NearestFire  # the name the lab loads")


# ---------------------------------------------------------------------------------------------------------------
# The client's errors: one line each, never the key.


def test_client_errors_are_one_line(monkeypatch, tmp_path):
    monkeypatch.setenv(KEY_ENV, KEY)
    messages = [{"role": "user", "content": "hi"}]
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(LLMError, match="cannot reach http://127.0.0.1"):
        ChatClient(f"http://127.0.0.1:{port}/v1", "m", retries=0).chat(messages)
    for mode, pattern, kwargs in (("error", "HTTP 500", {}), ("not_json", "is not JSON", {}),
                                  ("slow", "no reply from .* within 0.5 s", {"timeout": 0.5})):
        with FakeServer(mode=mode) as server:
            with pytest.raises(LLMError, match=pattern) as err:
                ChatClient(server.url, "m", retries=0, **kwargs).chat(messages)
        assert "\n" not in str(err.value) and KEY not in str(err.value)
    with pytest.raises(ValueError, match="http"):
        ChatClient("ftp://x", "m")
    assert ChatClient("https://example.org/v1", "m").scrub(KEY) == "***"
    monkeypatch.delenv(KEY_ENV)
    monkeypatch.setenv("OPENAI_API_KEY", KEY)  # an OpenAI key goes to OpenAI only
    assert ChatClient("https://example.org/v1", "m").scrub(KEY) == KEY
    assert ChatClient("https://api.openai.com/v1", "m").scrub(KEY) == "***"


def test_cli_reports_an_unreachable_server_in_one_line(tmp_path, capsys):
    code = main(["scriptlab", "--map", "3m", "--endpoint", "http://127.0.0.1:9/v1", "--rounds", "1",
                 "--out", str(tmp_path / "lab"), "--timeout", "5", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("smac-hard-gym scriptlab: error: cannot reach") and "\n" not in err
    assert "Stopped early: cannot reach" in (tmp_path / "lab" / "report.md").read_text()


# ---------------------------------------------------------------------------------------------------------------
# Whole loops through the real HTTP client and the sandbox.


@pytest.mark.skipif(not SUPPORTED, reason="the process sandbox needs a POSIX system")
def test_a_good_loop_settles_and_its_scripts_are_usable(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(KEY_ENV, KEY)
    out = tmp_path / "lab"
    with FakeServer(_script("settle.json")) as server:
        code = main(["scriptlab", "--map", "3m", "--rounds", "4", "--episodes", str(EPISODES), "--out", str(out),
                     "--endpoint", server.url, "--model", "recorded-model", "--quiet"])
    assert code == 0, capsys.readouterr().err
    assert "2 round(s), settled" in capsys.readouterr().out
    # Two rounds of planner, red coder, blue coder; the critic only between them.
    assert server.roles() == ["ROLE: planner", "ROLE: red_coder", "ROLE: blue_coder", "ROLE: critic",
                              "ROLE: planner", "ROLE: red_coder", "ROLE: blue_coder"]
    assert all(r["path"] == "/v1/chat/completions" and r["headers"]["Authorization"] == f"Bearer {KEY}"
               and r["body"]["model"] == "recorded-model" for r in server.requests)
    # Round 2's prompts carry round 1's results and the critic's advice.
    assert "| lab_red | lab_blue | 8 |" in server.requests[4]["body"]["messages"][1]["content"]
    assert "shared target" in server.requests[6]["body"]["messages"][1]["content"]
    transcript = (out / "transcript.jsonl").read_text()
    assert len(transcript.splitlines()) == 7 and KEY not in transcript
    assert json.loads(transcript.splitlines()[0])["prompt_tokens"] == 812  # the recorded response's usage
    table = json.loads((out / "round_1" / "table.json").read_text())
    pairs = {(p["red"], p["blue"]) for p in table["pairings"]}
    assert pairs == {("lab_red", "lab_blue"), ("lab_red", "line_front"), ("lab_red", "base"), ("lab_red", "smac"),
                     ("line_front", "lab_blue"), ("base", "lab_blue"), ("smac", "lab_blue")}
    assert all(p["episodes"] == EPISODES and p["error"] == "" for p in table["pairings"])
    assert (out / "round_2" / "table.csv").read_text().startswith("red,blue,episodes")
    assert "Both sides' win rates settled" in (out / "report.md").read_text()
    # The kept scripts: listed without being run, and usable at once, alone or in the pool.
    listed = {Path(s["file"]).relative_to(out).as_posix(): s for s in list_scripts(out)}
    assert listed["blue.py"]["reference"] == f"{out / 'blue.py'}:LabScript" and listed["blue.py"]["name"] == "lab_blue"
    assert {"red.py", "round_1/red.py", "round_2/blue.py"} <= set(listed)
    assert main(["scripts", "--path", str(out)]) == 0
    assert "every unit attacks its nearest enemy" in capsys.readouterr().out
    opponent, probs = load_pool(out / "pool.json")
    assert opponent == [f"{out / 'blue.py'}:LabScript", "line_front", "base"] and abs(sum(probs) - 1) < 1e-9
    from smac_hard_gym.envs.duel import run_duel

    result = run_duel("3m", red="nearest", blue=opponent, blue_probs=probs, episodes=6, seed=1)
    assert "nearest vs lab_blue" in result.by_script
    assert main(["duel", "--map", "3m", "--red", f"{out / 'red.py'}:LabScript",
                 "--blue", f"{out / 'blue.py'}:LabScript", "--episodes", "4"]) == 0
    # train takes the kept script as its opponent (a few updates: the check is that it plays, not what is learned)
    pytest.importorskip("sb3_contrib", reason="training needs the [train] extra")
    run = tmp_path / "run"
    assert main(["train", "--map", "3m", "--opponent", f"{out / 'blue.py'}:LabScript", "--timesteps", "512",
                 "--num-envs", "4", "--n-steps", "64", "--batch-size", "128", "--epochs", "1", "--eval-every", "512",
                 "--eval-episodes", "2", "--no-progress", "--out", str(run)]) == 0
    assert json.loads((run / "summary.json").read_text())["timesteps"] >= 512


@pytest.mark.skipif(not SUPPORTED, reason="the process sandbox needs a POSIX system")
def test_broken_hanging_and_hostile_scripts_become_feedback(tmp_path):
    import smac_hard_gym.opponents.guard as guard
    import smac_hard_gym.scriptlab.judging as judging

    check_commands, play_pairing = guard.check_commands, judging.play_pairing
    out = tmp_path / "lab"
    with FakeServer(_script("repair.json")) as server:
        client = ChatClient(server.url, "m", retries=0, transcript=Transcript(out / "transcript.jsonl"))
        config = LabConfig("3m", out, rounds=3, episodes=EPISODES, time_limit=1.0, progress=False)
        result = run_lab(config, client)
    r1, r2, r3 = result.rounds
    # Round 1: red does not parse, blue hangs; neither plays, the lab goes on.
    assert r1.checks["red"].feedback.startswith("SyntaxError: expected ':' at line 8") or \
        r1.checks["red"].feedback.startswith("SyntaxError: invalid syntax at line 8")
    assert "timed out after 1 s" in r1.checks["blue"].feedback
    assert r1.rows == [] and r1.scores == {"red": None, "blue": None}
    # The feedback reaches each coder's next prompt, with its previous code.
    red_prompt = server.requests[5]["body"]["messages"][1]["content"]
    assert "SyntaxError" in red_prompt and "def act_battle(self, battle)\n" in red_prompt
    assert "timed out" in server.requests[6]["body"]["messages"][1]["content"]
    # Round 2: red repaired and judged; blue's escape attempt ends its own process only.
    assert r2.checks["red"].ok and r2.scores["red"] is not None
    assert "exited with code 0" in r2.checks["blue"].feedback
    assert guard.check_commands is check_commands and judging.play_pairing is play_pairing  # host untouched
    # Round 3: both pass; only one round with two fresh scripts, so no settling: stopped at the limit.
    assert r3.checks["red"].ok and r3.checks["blue"].ok and not result.settled
    assert {("lab_red", "lab_blue")} <= {(r.red, r.blue) for r in r3.rows}
    assert set(result.kept) == {"red", "blue"}
    assert (out / "blue.py").read_text() == (out / "round_3" / "blue.py").read_text()
    # Every round's scripts are on disk as the coders sent them, broken ones included.
    assert "def act_battle(self, battle)\n" in (out / "round_1" / "red.py").read_text()
