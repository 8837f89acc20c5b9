"""A results document as the published figure (matplotlib, optional)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from smac_hard_gym.bench.document import select_rows, subproc_scaling


def plot_report(doc: dict[str, Any], path: str | os.PathLike) -> bool:
    """A PNG: steps/s against N per map (ours solid, SMAX dashed) and subprocess scaling, each when measured.
    False without matplotlib (an optional dependency: the ``[dev]`` and ``[render]`` extras) or with nothing to
    draw."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    panels = [draw for draw, rows in ((_plot_native, select_rows(doc, "native")), (_plot_scaling, subproc_scaling(doc)))
              if rows]
    if not panels:
        return False
    fig, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels) + 0.5, 5), squeeze=False)
    for draw, ax in zip(panels, axes[0], strict=True):
        draw(doc, ax, plt.rcParams["axes.prop_cycle"].by_key()["color"])
    m = doc["machine"]
    fig.suptitle(f"smac-hard-gym {m.get('smac_hard_gym')} on {m['cpu']} ({m['cores']} cores), {m['date']}",
                 fontsize=9)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _plot_native(doc: dict[str, Any], ax: Any, colours: list[str]) -> None:
    for i, name in enumerate(dict.fromkeys(r["map"] for r in select_rows(doc, "native"))):
        colour = colours[i % len(colours)]
        rows = sorted(select_rows(doc, "native", map=name), key=lambda r: r["num_envs"])
        ax.plot([r["num_envs"] for r in rows], [r["steps_per_second"] for r in rows], "o-", color=colour, label=name)
        smax = sorted(select_rows(doc, "smax", map=name, mode="scan"), key=lambda r: r["num_envs"])
        if smax:
            ax.plot([r["num_envs"] for r in smax], [r["steps_per_second"] for r in smax], "s--", color=colour,
                    alpha=0.6, label=f"{name} SMAX")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("battles stepped together (num_envs)")
    ax.set_ylabel("env steps / s")
    ax.set_title("NativeVectorEnv (solid) vs SMAX jit+scan (dashed)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)


def _plot_scaling(doc: dict[str, Any], ax: Any, colours: list[str]) -> None:
    workers = sorted({r["workers"] for r in select_rows(doc, "subproc")})
    for i, s in enumerate(subproc_scaling(doc)):
        ws = [w for w in workers if f"ratio_{w}" in s]
        ax.plot(ws, [s[f"ratio_{w}"] for w in ws], "o-", color=colours[i % len(colours)],
                label=f"{s['map']}, K={s['k']} per worker")
    cores = doc["machine"]["cores"] or 1
    ax.plot(workers, [min(w, cores) for w in workers], ":", color="grey", label=f"ideal on {cores} cores")
    ax.axhline(1.7, color="red", lw=0.8, ls="--", label="target 1.7x at 2 workers")
    ax.set_xticks(workers)
    ax.set_xlabel("worker processes")
    ax.set_ylabel("env steps/s over one worker")
    ax.set_title("SubprocVectorEnv scaling")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
