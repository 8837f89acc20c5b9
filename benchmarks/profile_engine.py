"""Where the engine's step spends its time: perf samples of ``step_battles`` attributed to the kernel's phases.

Runs ``ab_speed.py``'s ``engine<N>`` measurement (``BattleEngine(map, battles)`` alone, random move and attack
orders) on one numba thread under ``perf record``, in a child process that compiles the kernels
afresh with line tables (``NUMBA_DEBUGINFO``, inlining kept as in a normal build) into a temporary numba cache. Each
sample inside the compiled ``step_battles``, or inside a helper it calls instead of inlining (numba links those into
the same library: ``_sort_by_x``, ``_acquire``, ``_steer``, ``_fire`` ...), is mapped to its source line with
``addr2line`` and counted under the kernel function whose line it is, outermost first: the phases (``_movement``,
``_separation``, ``_attacks``, ...) are inlined into the battle loop, so their lines are the loop's own, and a
called helper's samples count under its own name (not its caller's). Needs Linux ``perf`` (sampling allowed for the
user) and binutils' ``addr2line``.

    python benchmarks/profile_engine.py --map 3m --battles 4096 --steps 600

Numbers are shares of the samples in ``step_battles`` and the helpers it calls; "?" is code with no line (register
moves, loop set-up).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ab_speed import CHILD as ENGINE_MEASUREMENT  # noqa: E402  (the engine workload ab_speed.py times)

KERNELS = Path(__file__).resolve().parents[1] / "smac_hard_gym" / "engine" / "kernels.py"

# The child under perf: compile with line tables (without the noinline that debug info asks numba for, so the build
# inlines as a normal one), run ab_speed.py's engine measurement, then note where step_battles landed.
PRELUDE = r'''
import numba.core.lowering as lowering
_pre_lower = lowering.Lower.pre_lower
def pre_lower(self):
    _pre_lower(self)
    self.builder.function.attributes.discard("noinline")
lowering.Lower.pre_lower = pre_lower
'''
EPILOGUE = r'''
import json
import subprocess
from smac_hard_gym.engine import kernels
out = sys.argv[5]
functions = []
for k, cres in enumerate(kernels.step_battles.overloads.values()):
    obj = f"{out}/step_battles{k}.o"
    with open(obj, "wb") as f:
        f.write(cres.library._get_compiled_object())
    # every function of the compiled library (step_battles and the helpers it calls rather than inlines): where it
    # is in the object file (section, offset, size) and where it was loaded
    table = subprocess.run(["objdump", "-t", obj], capture_output=True, text=True, check=True).stdout
    for line in table.splitlines():
        parts = line.split()
        if len(parts) >= 6 and "F" in parts[1:-3] and int(parts[-2], 16) > 0 and "kernels" in parts[-1]:
            address = cres.library.get_pointer_to_function(parts[-1])
            if address:
                functions.append({"object": obj, "section": parts[-3], "offset": int(parts[0], 16),
                                  "size": int(parts[-2], 16), "address": address})
with open(f"{out}/functions.json", "w") as f:
    json.dump(functions, f)
'''
CHILD = PRELUDE + ENGINE_MEASUREMENT + EPILOGUE


def _kernel_functions() -> list[tuple[int, str]]:
    """(first line, name) of every function defined in kernels.py, in order."""
    lines = KERNELS.read_text().splitlines()
    return [(k + 1, m.group(1)) for k, text in enumerate(lines) if (m := re.match(r"def (\w+)", text))]


def profile(map_name: str, battles: int, steps: int, work: Path) -> dict[str, float]:
    """Shares of ``step_battles``'s perf samples by kernel function (outermost source line)."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "NUMBA_DEBUGINFO": "1", "NUMBA_CACHE_DIR": str(work / "cache"),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(KERNELS.parents[2]), os.environ.get("PYTHONPATH")]))}
    data = work / "perf.data"
    windows = max(1, steps // 50)  # ab_speed's windows of 50 steps, after its warm-up
    subprocess.run(["perf", "record", "-q", "-F", "2000", "-o", str(data), sys.executable, "-c", CHILD,
                    f"engine{battles}", map_name, str(windows), "50", str(work)], env=env, check=True,
                   stdout=subprocess.DEVNULL)
    ips = subprocess.run(["perf", "script", "-i", str(data), "-F", "ip"], capture_output=True, text=True,
                         check=True).stdout.split()
    counts = collections.Counter(int(ip, 16) for ip in ips)
    by_offset: dict[tuple[str, str, int], int] = collections.Counter()  # (object, section, offset): samples
    for fn in json.loads((work / "functions.json").read_text()):
        for address, c in counts.items():
            if 0 <= address - fn["address"] < fn["size"]:
                by_offset[(fn["object"], fn["section"], fn["offset"] + address - fn["address"])] += c
    if not by_offset:
        raise SystemExit("no samples fell in step_battles or its helpers: is perf allowed to sample "
                         "(perf_event_paranoid)?")
    starts = _kernel_functions()

    def owner(line: int) -> str:
        return [name for first, name in starts if first <= line][-1]

    shares: collections.Counter[str] = collections.Counter()
    for obj, section in {(o, s) for o, s, _ in by_offset}:
        offsets = [off for o, s, off in by_offset if (o, s) == (obj, section)]
        out = subprocess.run(["addr2line", "-a", "-i", "-e", obj, "-j", section, *map(hex, offsets)],
                             capture_output=True, text=True, check=True).stdout.splitlines()
        frames: dict[int, list[str]] = {}
        for line in out:
            if line.startswith("0x"):
                current = frames.setdefault(int(line, 16), [])
            else:
                current.append(line)
        for off in offsets:
            where = frames.get(off, ["?"])[-1]  # the outermost frame: a line of the battle loop itself
            m = re.search(r"kernels\.py:(\d+)", where)
            shares[owner(int(m.group(1))) if m else "?"] += by_offset[(obj, section, off)]
    total = sum(shares.values())
    return {name: c / total for name, c in shares.most_common()}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--map", default="3m")
    p.add_argument("--battles", type=int, default=4096)
    p.add_argument("--steps", type=int, default=600, help="env steps sampled after the warm-up (default 600)")
    p.add_argument("--json", type=Path, help="also write the shares here")
    args = p.parse_args()
    for tool in ("perf", "addr2line", "objdump"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: this profile needs Linux perf and binutils")
    with tempfile.TemporaryDirectory() as tmp:
        shares = profile(args.map, args.battles, args.steps, Path(tmp))
    for name, share in shares.items():
        print(f"{100 * share:5.1f}%  {name}")
    if args.json:
        args.json.write_text(json.dumps({"map": args.map, "battles": args.battles, "steps": args.steps,
                                         "shares": shares}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
