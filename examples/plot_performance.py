"""The figures of docs/performance.md, drawn from the JSON that `planar-lcp bench all --json FILE` writes:

    python examples/plot_performance.py docs/figures/performance/bench.json docs/figures/performance
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
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
        n = np.array([r["bodies"] for r in rs])
        us = np.array([r["us_per_step"] for r in rs])
        ax.loglog(n, us, "o-", label=f"{label}: p = {fits[kind]:.2f}")
    ax.set_xlabel("bodies")
    ax.set_ylabel("µs per step")
    ax.set_title("Scaling (cost ~ n^p fitted over n >= 4)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "scaling.png", dpi=120)
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
    plot_step(d["step"]["rows"], out)
    plot_scaling(d["scaling"]["rows"], d["scaling"]["fits"], out)
    plot_lcp(d["lcp"]["rows"], out)
    print(f"wrote {out}/step.png, scaling.png, lcp.png")


if __name__ == "__main__":
    main(*sys.argv[1:3])
