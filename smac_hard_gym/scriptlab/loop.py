"""The lab's rounds: plan, code, check, judge, critique; stop once both sides' win rates settle.

Each round ``k`` (folder ``out/round_k``):

1. the **planner** plans both sides from the environment prompt, the previous round's table and the critic's advice;
2. each **coder** writes its side's script from the plan, the API reference, library examples, its previous script,
   the problems its last script had and the critic's advice; the reply is checked (:mod:`.checks`) and, if it
   passes, smoke-tested in the sandbox;
3. the side's script (the new one, or the last one that passed) is **judged** (:mod:`.judging`): red against blue,
   and each against the map's library scripts, ``>= episodes`` seeded episodes per pairing;
4. the **critic** reads the table and advises the planner and the coders (skipped after the last round).

A side's score is its win rate over every game its script played in the round. The loop stops when both sides had
a new script that passed in this round and the previous one and neither score moved by ``tolerance`` or more, or
after ``rounds`` rounds. The kept scripts are the last that passed (``out/red.py``, ``out/blue.py``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from smac_hard_gym.maps import MapSpec, load_map
from smac_hard_gym.opponents import ProcessIsolatedScript, ScriptError
from smac_hard_gym.scriptlab import checks, judging, prompts, report
from smac_hard_gym.scriptlab.client import ChatClient, LLMError
from smac_hard_gym.scriptlab.judging import PairingResult

__all__ = ["LabConfig", "RoundRecord", "LabResult", "run_lab"]

SIDES = prompts.SIDES


@dataclass
class LabConfig:
    """What the lab runs: the map, the rounds, where it writes, how it judges (``episodes`` per pairing)."""

    map_name: str
    out: Path
    rounds: int = 5
    episodes: int = 64
    tolerance: float = 0.05
    seed: int = 0
    time_limit: float = 2.0  # seconds per script call in the sandbox
    smoke_episodes: int = 2
    smoke_steps: int = 40
    solutions: bool = True  # also judge a blue script against the map's known-solution controllers
    library: tuple[str, ...] | None = None  # override the library opponents (default: the map's pool and smac)
    progress: bool = True  # print one line per step

    def check(self) -> None:
        if self.rounds < 1:
            raise ValueError(f"--rounds must be >= 1, got {self.rounds}")
        if self.episodes < 1:
            raise ValueError(f"--episodes must be >= 1, got {self.episodes}")
        if not 0 <= self.tolerance <= 1:
            raise ValueError(f"--tolerance must be in [0, 1], got {self.tolerance}")
        if self.time_limit <= 0:
            raise ValueError(f"--time-limit must be > 0, got {self.time_limit}")


@dataclass
class RoundRecord:
    """One round: the plan, each side's check, the judged table, scores, advice, tokens and times."""

    number: int
    plan: str = ""
    checks: dict[str, checks.Check] = field(default_factory=dict)
    scripts: dict[str, str] = field(default_factory=dict)  # side -> path of the script that played
    rows: list[PairingResult] = field(default_factory=list)
    scores: dict[str, float | None] = field(default_factory=dict)
    advice: dict[str, str] = field(default_factory=dict)
    prompt_tokens: int = 0
    completion_tokens: int = 0
    llm_seconds: float = 0.0
    check_seconds: float = 0.0
    judge_seconds: float = 0.0

    def fresh(self, side: str) -> bool:
        """Whether ``side`` played a script written and passed in this round."""
        check = self.checks.get(side)
        return check is not None and check.ok


@dataclass
class LabResult:
    """The whole run: its rounds, whether it settled, and the kept scripts."""

    config: LabConfig
    rounds: list[RoundRecord]
    settled: bool
    kept: dict[str, Path]
    error: str = ""  # why the run stopped early (the server failed), else ""


class _Side:
    """A side's current script: the last that passed its checks, its code and its live sandbox."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.path: Path | None = None
        self.code = ""
        self.sandbox: ProcessIsolatedScript | None = None
        self.last_code = ""  # the latest code the coder sent (shown to it next round, passed or not)
        self.feedback = ""

    def close(self) -> None:
        if self.sandbox is not None:
            self.sandbox.close()
            self.sandbox = None


def _say(config: LabConfig, text: str) -> None:
    if config.progress:
        print(text, flush=True)


def _ask(client: ChatClient, record: RoundRecord, messages: list[dict[str, str]], role: str) -> str:
    reply = client.chat(messages, role=role, round_no=record.number)
    record.prompt_tokens += reply.prompt_tokens
    record.completion_tokens += reply.completion_tokens
    record.llm_seconds += reply.seconds
    return reply.content


def _code_round(config: LabConfig, spec: MapSpec, client: ChatClient, record: RoundRecord, side: _Side,
                plan: str, advice: str, folder: Path) -> None:
    """Ask the side's coder for a script, check it, and make it the side's script if it passes."""
    messages = prompts.coder_messages(spec, side.name, plan, side.last_code, side.feedback, advice)
    reply = _ask(client, record, messages, f"{side.name}_coder")
    start = time.perf_counter()
    check = checks.check_reply(reply, side.name, folder)
    live = checks.smoke_test(check, spec, config.time_limit, config.smoke_episodes, config.smoke_steps)
    record.check_seconds += time.perf_counter() - start
    record.checks[side.name] = check
    side.last_code = check.code
    side.feedback = check.feedback
    if live is not None:
        side.close()
        side.path, side.code, side.sandbox = check.path, check.code, live
    _say(config, f"  {side.name} script: " + ("passed" if check.ok else f"failed: {check.feedback[:160]}"))


def _pairings(config: LabConfig, spec: MapSpec, sides: dict[str, _Side]) -> list[tuple[object, object, tuple]]:
    """(red entry, blue entry, lab sides) of every pairing this round plays."""
    red, blue = sides["red"], sides["blue"]
    out: list[tuple[object, object, tuple]] = []
    if red.sandbox is not None and blue.sandbox is not None:
        out.append((red.sandbox, blue.sandbox, ("red", "blue")))
    if red.sandbox is not None:
        for name in config.library or judging.library_opponents(spec, "red"):
            if not name.startswith(judging.SOLUTION_PREFIX):
                out.append((red.sandbox, name, ("red",)))
    if blue.sandbox is not None:
        for name in config.library or judging.library_opponents(spec, "blue", config.solutions):
            out.append((name, blue.sandbox, ("blue",)))
    return out


def _judge(config: LabConfig, spec: MapSpec, sides: dict[str, _Side], record: RoundRecord,
           cache: dict[str, PairingResult]) -> None:
    """Play every pairing (a pairing of unchanged code is taken from ``cache``: same code and seeds, same result);
    a script error during judging becomes that side's feedback."""
    start = time.perf_counter()
    failed: set[str] = set()
    for red, blue, lab in _pairings(config, spec, sides):
        if failed & set(lab):  # its script already failed this round: dropped
            continue
        labels = tuple(f"lab_{s}" if isinstance(e, ProcessIsolatedScript) else None
                       for s, e in (("red", red), ("blue", blue)))
        codes = [sides[s].code if isinstance(e, ProcessIsolatedScript) else str(e)
                 for s, e in (("red", red), ("blue", blue))]
        key = judging.code_key(*codes, str(config.episodes), str(config.seed), spec.name)
        if key in cache:
            row = cache[key]
        else:
            try:
                row = judging.play_pairing(spec, red, blue, config.episodes, config.seed, labels=labels)
            except ScriptError as err:
                guilty = [s for s in lab if err.script in (sides[s].sandbox.name if sides[s].sandbox else "",)]
                row = judging.error_result(labels[0] or str(red), labels[1] or str(blue), err, lab)
                for s in guilty or lab:
                    failed.add(s)
                    sides[s].feedback = checks.cap_feedback(
                        f"the script failed while judged ({row.red} vs {row.blue}): {err.cause}")
                    if s in record.checks:
                        record.checks[s].feedback = sides[s].feedback
            else:
                cache[key] = row
        row.lab_sides = lab
        record.rows.append(row)
    for s in failed:  # a script that fails while judged is not kept; the coder gets the error next round
        sides[s].close()
        sides[s].path, sides[s].code = None, ""
    record.judge_seconds += time.perf_counter() - start
    record.scores = {s: judging.side_score(record.rows, s) for s in SIDES}


def _critique(spec: MapSpec, client: ChatClient, record: RoundRecord) -> None:
    feedback = {s: c.feedback for s, c in record.checks.items()}
    messages = prompts.critic_messages(spec, record.plan, judging.format_table(record.rows), feedback)
    text = _ask(client, record, messages, "critic")
    parts = prompts.split_sections(text, ("PLANNER", "RED CODER", "BLUE CODER"))
    record.advice = {"planner": parts["PLANNER"], "red": parts["RED CODER"], "blue": parts["BLUE CODER"]}


def _settled(previous: RoundRecord | None, record: RoundRecord, tolerance: float) -> bool:
    if previous is None:
        return False
    for side in SIDES:
        a, b = previous.scores.get(side), record.scores.get(side)
        if not (previous.fresh(side) and record.fresh(side)) or a is None or b is None or abs(a - b) >= tolerance:
            return False
    return True


def run_lab(config: LabConfig, client: ChatClient) -> LabResult:
    """Run the loop (see the module docstring) and write its files under ``config.out`` (see
    :mod:`smac_hard_gym.scriptlab.report`)."""
    config.check()
    spec = load_map(config.map_name)
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    sides = {s: _Side(s) for s in SIDES}
    records: list[RoundRecord] = []
    cache: dict[str, PairingResult] = {}
    advice: dict[str, str] = {}
    settled = False
    failure: LLMError | None = None
    try:
        for k in range(1, config.rounds + 1):
            record = RoundRecord(k)
            folder = out / f"round_{k}"
            _say(config, f"round {k}/{config.rounds} on {spec.name}: planning")
            table = judging.format_table(records[-1].rows) if records else ""
            record.plan = _ask(client, record, prompts.planner_messages(spec, table, advice.get("planner", "")),
                               "planner")
            plan = prompts.split_sections(record.plan, ("RED", "BLUE"))
            for side in SIDES:
                _code_round(config, spec, client, record, sides[side], plan[side.upper()], advice.get(side, ""),
                            folder)
            _say(config, "  judging")
            _judge(config, spec, sides, record, cache)
            record.scripts = {s: str(sides[s].path) for s in SIDES if sides[s].path is not None}
            settled = _settled(records[-1] if records else None, record, config.tolerance)
            records.append(record)
            report.write_round(folder, record)
            scores = ", ".join(f"{s} {'-' if v is None else f'{v:.2f}'}" for s, v in record.scores.items())
            _say(config, f"  scores: {scores}; judging took {record.judge_seconds:.1f} s")
            if settled or k == config.rounds:
                break
            _critique(spec, client, record)
            advice = record.advice
            report.write_round(folder, record)
    except LLMError as err:  # the server failed: keep what passed so far, write the report, then re-raise
        failure = err
    finally:
        for side in sides.values():
            side.close()
    kept = report.keep_scripts(out, spec, {s: sides[s].path for s in SIDES})
    result = LabResult(config, records, settled, kept, str(failure or ""))
    report.write_report(out, result, client)
    if failure is not None:
        raise failure
    return result
