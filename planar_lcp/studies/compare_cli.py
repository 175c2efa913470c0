"""`planar-lcp compare SCENE --out DIR`: the command over `planar_lcp.studies.compare` (which says what it writes)."""

import math
import sys
from pathlib import Path

PROG = "planar-lcp compare"
#: Flags that override a setting, in the order the report's command line lists them: (flag, argparse dest).
OVERRIDES = (("--h", "h"), ("--t-end", "t_end"), ("--restitution", "restitution"), ("--iterations", "iterations"),
             ("--collision-slop", "collision_slop"))


def _error(message, status=2):
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return status


def _command_line(args):
    """The command as the user could type it again (report.md quotes it)."""
    parts = [f"{PROG} {args.scene} --out {args.out}"]
    parts += [f"{flag} {getattr(args, dest)}" for flag, dest in OVERRIDES if getattr(args, dest) is not None]
    if args.no_gif:
        parts.append("--no-gif")
    return " ".join(parts)


def _cmd_compare(args):
    from planar_lcp.cli_support import SIMULATE_FLAGS, InputError, prepare_output_dir
    from planar_lcp.studies.compare import fmt, run_compare
    from planar_lcp.sim import SimulationError
    from planar_lcp.spec.scene import SceneError, load_scene, restitution_setting, sim_settings

    try:
        import pymunk  # noqa: F401
    except ImportError:
        return _error("pymunk is not installed (pip install pymunk)")
    try:
        scene = load_scene(args.scene)
        sim_settings(scene, {"h": args.h, "t_end": args.t_end}, SIMULATE_FLAGS)  # before any work, named by flag
        scene = restitution_setting(scene, args.restitution, "--restitution")    # the scene of BOTH simulators
        prepare_output_dir(args.out, "--out")
    except (InputError, SceneError) as e:
        return _error(e)
    try:
        res = run_compare(scene, Path(args.out), h=args.h, t_end=args.t_end, iterations=args.iterations,
                          collision_slop=args.collision_slop, gif=not args.no_gif, command=_command_line(args))
    except SimulationError as e:
        print(f"{PROG}: planar_lcp simulation failed: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        return _error(f"cannot write {e.filename or ''}: {e.strerror or e}", 1)
    except SceneError as e:
        return _error(e)
    except ValueError as e:
        return _error(f"{scene.source}: {e}")
    for r in res["rows"]:
        print(f"{r['simulator']:<10s} {r['body']:<8s} first contact {fmt(r['first_contact_t_s'])} s  "
              f"max pen {fmt(r['max_penetration_m'])} m  drift {fmt(r['drift_xy_m'])} m  "
              f"final ({r['final_x_m']:.4f}, {r['final_y_m']:.4f}, {r['final_theta_rad']:.4f})  "
              f"{r['us_per_step']:.1f} us/step")
    for p in res["files"]:
        print(f"wrote {p}")
    return 0


def register(subparsers):
    from planar_lcp.cli_support import SCENE_OPERAND, add_command, finite_number

    c = add_command(
        subparsers, "compare", _cmd_compare, SCENE_OPERAND,
        help="run a scene in planar_lcp and in pymunk with the same time step; plots, GIF, report",
        description="Run a scene (a shipped name or a .toml path) in planar_lcp and in pymunk (Chipmunk2D) with the "
                    "same time step; write overlaid trajectories, frames, a side-by-side GIF and report.md/.csv.")
    c.add_argument("--out", required=True, metavar="DIR", help="directory for the files (created if missing)")
    helps = {"--h": ("H", float, 0, True, "time step [s] (default: the scene's)"),
             "--t-end": ("T", float, 0, True, "duration [s] (default: the scene's)"),
             # any finite number here: restitution_setting checks [0, 1] and names the flag
             "--restitution": ("E", float, -math.inf, True, "coefficient of restitution in [0, 1] of every contact "
                               "pair without a world.restitution_pairs entry, in both simulators (default: the "
                               "scene's world.restitution)"),
             "--iterations": ("N", int, 1, False, "pymunk solver iterations per step (default 10, pymunk's)"),
             "--collision-slop": ("M", float, 0, False, "pymunk allowed overlap [m] (default 1e-4)")}
    for flag, _dest in OVERRIDES:
        metavar, kind, minimum, strict, text = helps[flag]
        c.add_argument(flag, type=finite_number(kind, minimum, strict), metavar=metavar, help=text)
    c.add_argument("--no-gif", action="store_true", help="skip the side-by-side GIF")
    return c
