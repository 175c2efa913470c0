"""`planar-lcp study ...`: Stewart & Trinkle's numerical experiments (their section 4), reproduced and compared.

- `study falling-rod`: section 4.1, Figures 2-5, events and the Table 1 measures (see docs/falling-rod.md)
- `study four-disks`: section 4.2 in elevation, Figure 6's impulse cascade and Table 1 (see docs/four-disks.md)

Matplotlib, scipy and tqdm are imported only when a study runs.
"""

import math
import sys


def restitution_value(text):
    """An argparse type for `--restitution E`: a number in [0, 1] (one line naming the range and the value)."""
    import argparse

    try:
        e = float(text)
    except ValueError:
        e = math.nan
    if not 0.0 <= e <= 1.0:          # also NaN and not a number at all
        raise argparse.ArgumentTypeError(f"must be a number in [0, 1], got {text!r}")
    return e


def _add_study(sub, name, module_name, help, description):
    """The parser of `study NAME`: the study in module `module_name` of this package, with the options every study
    takes."""
    from planar_lcp.cli_support import add_command
    p = add_command(sub, name, _runner(module_name), help=help, description=description)
    p.add_argument("--out", required=True, metavar="DIR", help="directory for the figures and tables (created)")
    p.add_argument("--quick", action="store_true",
                   help="two step sizes (0.0025, 0.00125) against a reference at h = 0.000625, instead of the "
                        "paper's 0.02 ... 0.0025 against h = 0.00125")
    return p


def _runner(module_name):
    def run(args):
        import importlib

        from planar_lcp.cli_support import InputError, prepare_output_dir
        try:
            prepare_output_dir(args.out, "--out")
        except InputError as e:
            print(f"planar-lcp study: error: {e}", file=sys.stderr)
            return 2
        module = importlib.import_module(f"{__package__}.{module_name}")
        from planar_lcp.studies.common import print_phase_table_and_files
        restitution = getattr(args, "restitution", None)
        kwargs = {} if restitution is None else dict(restitution=restitution)
        print(module.TITLE + (" --quick" if args.quick else "")
              + ("" if restitution is None else f" --restitution {restitution:g}"))
        res = module.run(args.out, quick=args.quick, **kwargs)
        module.print_summary(res)
        print_phase_table_and_files(res, args.out)
        return 0
    return run


def register(subparsers):
    """Add the `study` command and its sub-commands to the `planar-lcp` parser."""
    from planar_lcp.cli_support import add_command
    s = add_command(subparsers, "study", help="Stewart & Trinkle's experiments: falling rod, four-disk cascade",
                    description="Reproduce Stewart & Trinkle's section 4 experiments: figures, event tables and the "
                                "Table 1 error measures over step sizes.")
    sub = s.add_subparsers(dest="study", required=True, metavar="STUDY")

    fr = _add_study(sub, "falling-rod", "falling_rod",
                    "section 4.1: the spinning rod dropped on a table (Figures 2-5)",
                    "Falling rod over h = 0.02 ... 0.00125: strobe, velocity plots, events, convergence table, and "
                    "Stewart & Trinkle's friction moment arm.")
    fr.add_argument("--restitution", type=restitution_value, metavar="E",
                    help="Newton's coefficient of restitution in [0, 1] of the rod-table contact, for every run of "
                         "the study (default: the scene's; 0: Stewart & Trinkle's inelastic contact, "
                         "docs/falling-rod.md)")
    _add_study(sub, "four-disks", "four_disks", "section 4.2 in elevation: a thrown disk hits a row of three (Figure 6)",
               "Four disks over h = 0.02 ... 0.00125: trajectories, the impulses of the first disk-disk step, "
               "velocities, convergence table.")
    return s
