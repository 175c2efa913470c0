"""The figures of docs/performance.md, drawn from the JSON that `planar-lcp bench all --json FILE` writes (step.png,
scaling.png, lcp.png) and from the large piles' `planar-lcp bench scaling --kinds tower pyramid bin --json FILE`
(scaling_piles.png): each figure whose part the JSON holds.

    python examples/measurements/plot_performance.py docs/figures/performance/bench.json docs/figures/performance
    python examples/measurements/plot_performance.py docs/figures/performance/scaling_piles.json docs/figures/performance
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402


def plot_step(rows, out):
    names = [r["scene"] for r in rows]
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.bar(x - 0.27, [r["us_per_step"] for r in rows], 0.27, label="ours (defaults)")
    ax.bar(x, [r["warm_us_per_step"] for r in rows], 0.27, label="ours (warm_start=True)")
    ax.bar(x + 0.27, [r["pymunk_us_per_step"] for r in rows], 0.27, label="pymunk (10 iterations)")
    ax.set_yscale("log")
    ax.set_xticks(x, names)
    ax.set_ylabel("µs per step")
    ax.set_title("Cost per step, same scene and h, warm JIT")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "step.png", dpi=120)
    plt.close(fig)


def plot_scaling(rows, fits, out):
    fig, ax = plt.subplots(figsize=(6, 4))
    for kind, label in (("pile", "one tower (one island)"), ("islands", "separate boxes (n islands)")):
        rs = [r for r in rows if r["kind"] == kind]
        if not rs:
            continue
        n = np.array([r["bodies"] for r in rs])
        us = np.array([r["us_per_step"] for r in rs])
        ax.loglog(n, us, "o-", label=f"{label}: p = {fits[kind]:.2f}" if fits.get(kind) is not None else label)
    ax.set_xlabel("bodies")
    ax.set_ylabel("µs per step")
    ax.set_title("Scaling (cost ~ n^p fitted over n >= 4)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "scaling.png", dpi=120)
    plt.close(fig)


def _fit_label(d, kind, path):
    p, b = d["fits"][kind][path], d["fit_bodies"][kind][path]
    if p is None:
        return f"{kind}, {path}: not fitted"
    s = d["fit_spread"][kind][path]
    return f"{kind}, {path}: p = {p:.2f} [{s['min']:.2f}-{s['max']:.2f}] over {b[0]}-{b[-1]}"


def plot_scaling_piles(d, out):
    """Cost per step against bodies, log-log: each kind with the defaults (solid) and the dense path (dashed), the
    fitted exponents in the legend. Hollow markers: most of the step's large islands fell back to dense Lemke; x: timed
    once, over the step budget (not fitted)."""
    fig, ax = plt.subplots(figsize=(9, 4.6))
    for (kind, color) in zip(d["fits"], ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")):
        rs = [r for r in d["rows"] if r["kind"] == kind]
        # dense first, so that the defaults' markers (hollow where most islands fell back) are drawn on top
        for path, pre, style, marker in (("dense", "dense_", "--", "s"), ("defaults", "", "-", "o")):
            timed = [r for r in rs if r[pre + "timing"] == "rounds"]
            if timed:
                ax.loglog([r["bodies"] for r in timed], [r[pre + "us_per_step"] for r in timed], style, color=color,
                          label=_fit_label(d, kind, path))
                for r in timed:
                    hollow = r[pre + "sparse_share"] is not None and r[pre + "sparse_share"] < 0.5
                    ax.loglog(r["bodies"], r[pre + "us_per_step"], marker, color=color,
                              markerfacecolor="white" if hollow else color)
            once = [r for r in rs if r[pre + "timing"] == "once"]
            if once:
                ax.loglog([r["bodies"] for r in once], [r[pre + "us_per_step"] for r in once], "x", color=color,
                          markersize=9 if path == "dense" else 6)
    bodies = [r["bodies"] for r in d["rows"]]
    if bodies:
        ax.set_xticks([2 ** k for k in range(12) if min(bodies) / 1.5 <= 2 ** k <= max(bodies) * 1.5])
        ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("bodies")
    ax.set_ylabel("µs per step (thread CPU time)")
    ax.set_title("Large piles, h = 1/60 s: defaults (sparse solver, solid) and dense Lemke (dashed)", fontsize=9)
    kinds = list(d["fits"])
    pairs = sorted(zip(*ax.get_legend_handles_labels()),        # each kind's defaults, then its dense path
                   key=lambda hl: (kinds.index(hl[1].split(",")[0]), ", dense" in hl[1]))
    ax.legend(*zip(*pairs) if pairs else ([], []), fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              title=("cost ~ bodies^p fitted per round,\nmedian [min-max]\nhollow: most large islands fell back\n"
                     f"x: timed once, over the {d.get('step_budget_s', 0):g} s\nper step budget, not fitted"),
              title_fontsize=7, alignment="left")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "scaling_piles.png", dpi=120)
    plt.close(fig)


def plot_lcp(rows, out):
    rs = sorted(rows, key=lambda r: r["ratio"])
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ratios = np.array([max(r["ratio"], 1e-6) for r in rs])
    colors = ["tab:red" if r["qe_status"] != "solved" else "tab:blue" for r in rs]
    ax.bar(np.arange(len(rs)), ratios, color=colors)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_yscale("log")
    ax.set_xticks([])
    ax.set_xlabel(f"{len(rs)} corpus instances, sorted (red: QuantEcon's status is not 'solved')")
    ax.set_ylabel("time ours / QuantEcon")
    ax.set_title("Lemke: ours against QuantEcon's lcp_lemke")
    fig.tight_layout()
    fig.savefig(out / "lcp.png", dpi=120)
    plt.close(fig)


def main(json_path, out_dir):
    d = json.loads(Path(json_path).read_text())
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    wrote = []
    if "step" in d:
        plot_step(d["step"]["rows"], out)
        wrote.append("step.png")
    if "scaling" in d:
        plot_scaling(d["scaling"]["rows"], d["scaling"]["fits"], out)
        wrote.append("scaling.png")
    if "scaling_piles" in d:
        plot_scaling_piles(d["scaling_piles"], out)
        wrote.append("scaling_piles.png")
    if "lcp" in d:
        plot_lcp(d["lcp"]["rows"], out)
        wrote.append("lcp.png")
    print(f"wrote {out}/{', '.join(wrote)}" if wrote else f"{json_path}: no part of bench's JSON to draw")


if __name__ == "__main__":
    main(*sys.argv[1:3])
