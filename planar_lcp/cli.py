"""The `planar-lcp` command."""

import argparse
import sys


def _cmd_demo(args):
    import numpy as np

    from .lcp import lemke
    from .lcp_corpus import find_corpus_dir, load_corpus

    print("planar-lcp demo: Lemke's algorithm (lexicographic) on LCPs written by other projects")
    insts = load_corpus()
    if not insts:
        print("(the corpus ../shared/data/lcp is absent; solving built-in examples instead)")
        examples = [("murty_2x2", np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0])),
                    ("kostreva_cycling", np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 2.0], [2.0, 0.0, 1.0]]),
                     -np.ones(3))]
    else:
        print(f"corpus: {find_corpus_dir()}")
        wanted = ("siconos_lcp_deudeu", "kostreva_ex1_cycling", "drake_testPSD_artificial_tie", "dart_12d",
                  "siconos_lcp_tobenna", "murty_ex2_9_ray")
        examples = [(i.id, i.M, i.q) for i in insts if i.id in wanted]
    for name, M, q in examples:
        r = lemke(M, q)
        z = np.array2string(r.z[:6], precision=4, suppress_small=True)
        more = " ..." if len(r.z) > 6 else ""
        print(f"  {name:32s} n={len(q):3d}  {r.status:16s} pivots={r.pivots:4d}  residual={r.residual:.1e}  "
              f"z={z}{more}")
    return 0


def _cmd_bench(args):
    from .bench import run_bench
    run_bench(args.what, json_path=args.json)
    return 0


def build_parser():
    p = argparse.ArgumentParser(prog="planar-lcp", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("demo", help="the main job: a short tour of what the toolkit does")
    d.set_defaults(func=_cmd_demo)

    b = sub.add_parser("bench", help="benchmarks against peers measured in the same run")
    b.add_argument("what", choices=["lcp", "all"], help="lcp: our Lemke vs QuantEcon's lcp_lemke on the corpus")
    b.add_argument("--json", metavar="FILE", help="also write the measurements as JSON")
    b.set_defaults(func=_cmd_bench)
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
