"""A coder's reply checked before it plays: the code block extracted, parsed with :mod:`ast`, written to a file and
smoke-tested in the process sandbox.

The host never imports or runs generated code: :func:`check_reply` only parses it, and the smoke duel loads the
file in a :class:`~smac_hard_gym.opponents.ProcessIsolatedScript` child (killed at its time limit). Every problem
(no code, a syntax error, no ``LabScript`` class, an import error, an exception, a time-out, an invalid command, a
child that exits or crashes) comes back as :attr:`Check.feedback`, text for the coder's next round.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

from smac_hard_gym.files import write_text
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents import ProcessIsolatedScript, ScriptError
from smac_hard_gym.scriptlab.prompts import SCRIPT_CLASS

__all__ = ["Check", "extract_code", "parse_feedback", "check_reply", "sandboxed", "smoke_test", "cap_feedback"]

_FENCE = re.compile(r"```[ \t]*([A-Za-z0-9_+-]*)[^\n]*\n(.*?)```", re.DOTALL)
_MAX_CODE = 100_000  # characters of code accepted from one reply
_FEEDBACK_CAP = 1_500  # characters of one error message passed back to the coder


@dataclass
class Check:
    """One side's script of one round: where it was written, its code, and what was wrong (empty: it passed)."""

    side: str
    path: Path | None
    code: str
    feedback: str = ""

    @property
    def ok(self) -> bool:
        return not self.feedback

    @property
    def reference(self) -> str:
        """The script as an opponent reference (``path:LabScript``)."""
        return f"{self.path}:{SCRIPT_CLASS}"


def extract_code(reply: str) -> str:
    """The code of a reply: its longest fenced block labelled python (or unlabelled), else the whole reply when it
    parses as Python; "" when there is none."""
    blocks = [(lang.lower(), body) for lang, body in _FENCE.findall(reply)]
    python = [b for lang, b in blocks if lang in ("python", "py", "python3")] or [b for lang, b in blocks if not lang]
    if python:
        return max(python, key=len).strip("\n") + "\n"
    text = reply.strip()
    if text and not blocks:
        try:
            ast.parse(text)
            return text + "\n"
        except SyntaxError:
            pass
    return ""


def cap_feedback(text: str) -> str:
    return text if len(text) <= _FEEDBACK_CAP else text[:_FEEDBACK_CAP] + " ...(truncated)"


def parse_feedback(code: str) -> tuple[str, str]:
    """(feedback, code): the code's problems found by parsing it ("" when none), and the code with an alias line
    ``LabScript = X`` appended when it defines exactly one class under another name."""
    if not code.strip():
        return "the reply had no ```python code block; answer with exactly one.", code
    if len(code) > _MAX_CODE:
        return f"the code is {len(code)} characters long, over the limit of {_MAX_CODE}.", code
    try:
        tree = ast.parse(code)
    except SyntaxError as err:
        line = (err.text or "").rstrip("\n")
        return (f"SyntaxError: {err.msg} at line {err.lineno}, column {err.offset}" +
                (f": {line.strip()!r}" if line.strip() else "") + "."), code
    classes = [n.name for n in tree.body if isinstance(n, ast.ClassDef)]
    if SCRIPT_CLASS in classes:
        return "", code
    if len(classes) == 1:  # a coder that named its class otherwise: keep the script, add the name we load
        return "", code.rstrip("\n") + f"\n\n{SCRIPT_CLASS} = {classes[0]}  # the name the lab loads\n"
    return (f"the module must define a class named {SCRIPT_CLASS} (a PerBattleScript subclass); it defines "
            f"{classes or 'no class'}."), code


def sandboxed(path: Path, time_limit: float) -> ProcessIsolatedScript:
    """The script in ``path`` loaded in a child process only (raises ScriptError or ValueError if it fails to
    load there)."""
    return ProcessIsolatedScript(f"{path}:{SCRIPT_CLASS}", time_limit=time_limit)


def check_reply(reply: str, side: str, folder: Path) -> Check:
    """Extract and parse the code of a coder's reply and write it to ``folder/<side>.py`` (written even when it
    does not parse, so the round's folder shows what the coder sent)."""
    code = extract_code(reply)
    feedback, code = parse_feedback(code)
    path = None
    if code.strip():
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{side}.py"
        write_text(path, code)
    return Check(side, path, code, feedback)


def smoke_test(check: Check, spec: MapSpec, time_limit: float, episodes: int = 2,
               max_steps: int = 40) -> ProcessIsolatedScript | None:
    """Load the checked script in the sandbox and play a short duel against SMAC's behaviour; on failure record
    the cause in ``check.feedback`` and return None, else return the live sandboxed script (reused for judging)."""
    from smac_hard_gym.scriptlab.judging import LIBRARY_PARTNER, play_pairing

    if not check.ok or check.path is None:
        return None
    script = None
    try:
        script = sandboxed(check.path, time_limit)
        red, blue = (script, "smac") if check.side == "red" else (LIBRARY_PARTNER, script)
        play_pairing(spec, red, blue, episodes=episodes, seed=0, max_steps=max_steps)
    except (ScriptError, ValueError, TypeError, RuntimeError) as err:  # load errors are ValueErrors
        cause = err.cause if isinstance(err, ScriptError) else f"{type(err).__name__}: {err}"
        check.feedback = cap_feedback(f"the smoke test (a short duel in the sandbox) failed: {cause}")
        if script is not None:
            script.close()
        return None
    return script
