"""Script lab: the SMAC-HARD paper's LLM script loop (section "LLM Script") on the embedded engine.

A strategy planner plans both sides, a coder per side writes a decision-tree script, the scripts play each other
and the map's library scripts, and a critic reads the results and sends refinements to the planner and the coders;
a script is kept once both sides' win rates settle. Modules, one job each:

- :mod:`~smac_hard_gym.scriptlab.client`: a chat-completions client (standard library HTTP) and the transcript;
- :mod:`~smac_hard_gym.scriptlab.prompts`: prompts built from the project's own sources (unit table, map, API
  docstrings, library scripts);
- :mod:`~smac_hard_gym.scriptlab.checks`: a reply's code extracted, parsed and smoke-tested in the sandbox;
- :mod:`~smac_hard_gym.scriptlab.judging`: seeded duels and the results table the critic reads;
- :mod:`~smac_hard_gym.scriptlab.loop`: the rounds and the stop rule;
- :mod:`~smac_hard_gym.scriptlab.report`: tables, report.md, the pool file and script listings.

Generated code only ever runs in the process sandbox (docs/script_lab.md, docs/script_isolation.md).
"""

from __future__ import annotations

from smac_hard_gym.scriptlab.client import KEY_ENV, ChatClient, LLMError
from smac_hard_gym.scriptlab.loop import LabConfig, LabResult, run_lab
from smac_hard_gym.scriptlab.report import SCRIPT_CLASS, list_scripts, load_pool

__all__ = ["KEY_ENV", "ChatClient", "LLMError", "LabConfig", "LabResult", "run_lab", "SCRIPT_CLASS", "list_scripts",
           "load_pool"]
