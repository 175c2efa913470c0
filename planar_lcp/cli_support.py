"""What the commands share, here and in the rooms that add commands (planar_lcp.benchmarks, planar_lcp.studies,
planners): the optional packages and their extras, the argument checks that make bad input one line with exit
status 2, the output checks made before any work, a long run's progress bar, and how an interrupt is recognised.

Nothing here imports the commands, so a command's module may import it without importing `planar_lcp.cli`.
"""

import argparse
import importlib.util
import math
import os


#: Optional packages -> the extra of pyproject.toml ([project.optional-dependencies]) that installs each.
OPTIONAL_PACKAGES = {"matplotlib": "plot", "shapely": "plot", "osqp": "osqp", "scipy": "osqp", "pymunk": "compare",
                     "ompl": "plan", "distributed": "plan", "tqdm": "studies", "quantecon": "bench", "h5py": "pushdata"}


class MissingPackage(Exception):
    """An optional package a command needs is not installed: `main` prints one line naming it and its extra, exit
    status 2."""

    def __init__(self, package):
        self.package = package
        extra = OPTIONAL_PACKAGES[package]
        super().__init__(f"{package} is not installed; it comes with the extra '{extra}': pip install "
                         f"\"planar-lcp[{extra}]\" (in a checkout: pip install -e \".[{extra}]\"; the extra 'dev' "
                         "installs every extra)")


def require(*packages):
    """Before any work: raise MissingPackage for the first of `packages` (keys of OPTIONAL_PACKAGES) not installed."""
    for name in packages:
        if importlib.util.find_spec(name) is None:
            raise MissingPackage(name)


def missing_optional(e):
    """The optional package whose absence raised `e` (a ModuleNotFoundError or MissingPackage), else None."""
    if isinstance(e, MissingPackage):
        return e.package
    if isinstance(e, ModuleNotFoundError):
        top = (e.name or "").split(".")[0]
        if top in OPTIONAL_PACKAGES:
            return top
    return None


class InputError(Exception):
    """Bad user input found after parsing: one line on stderr, exit status 2."""


def finite_number(kind, minimum, strict, maximum=None, why=""):
    """An argparse type: a finite number of `kind` (float or int) that is > (strict) or >= `minimum`, and at most
    `maximum` when given (`why` follows the bound in the message)."""
    def conv(text):
        try:
            x = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {'an integer' if kind is int else 'a number'}, "
                                             f"got {text!r}") from None
        if kind is float and not math.isfinite(x):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
        if (strict and not x > minimum) or (not strict and not x >= minimum):
            raise argparse.ArgumentTypeError(f"must be {'>' if strict else '>='} {minimum}, got {text!r}")
        if maximum is not None and not x <= maximum:
            raise argparse.ArgumentTypeError(f"must be <= {maximum:{'d' if kind is int else 'g'}}{why}, got {text!r}")
        return x
    conv.__name__ = kind.__name__
    return conv


def one_line_errors(parser):
    """Argument errors of this subcommand as one line on stderr (no usage block), exit status 2."""
    def error(message):
        parser.exit(2, f"{parser.prog}: error: {message}\n")
    parser.error = error
    return parser


#: the positional argument of the commands that run a scene (simulate, compare): add_command's `operand`
SCENE_OPERAND = ("scene", dict(metavar="SCENE", help="a shipped scene name or a path to a .toml scene file"))


def add_command(subparsers, name, func=None, operand=None, **kwargs):
    """A subcommand's parser (`subparsers.add_parser(name, **kwargs)`) with its argument errors in one line
    (one_line_errors), given `func` the function the command runs (args.func), given `operand` (name, add_argument's
    keywords) its first positional argument. args.command_parser is the parser of the (innermost) command given,
    which reports arguments no parser took."""
    parser = one_line_errors(subparsers.add_parser(name, **kwargs))
    parser.set_defaults(command_parser=parser)
    if func is not None:
        parser.set_defaults(func=func)
    if operand is not None:
        parser.add_argument(operand[0], **operand[1])
    return parser


def check_output_file(path, option, suffixes):
    """Before any work: `path` has one of `suffixes` and can be written (its directory exists and is writable, and
    it is not a directory). Raises InputError naming the option."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in suffixes:
        raise InputError(f"{option} {path}: the file name must end in {' or '.join(suffixes)}, got "
                          f"{suffix or 'no extension'!r}")
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        raise InputError(f"{option} {path}: the directory {d} does not exist")
    if os.path.isdir(path):
        raise InputError(f"{option} {path}: must be a file name, got a directory")
    existed = os.path.exists(path)
    try:
        with open(path, "ab"):   # opened to append: an existing file is left as it is
            pass
    except OSError as e:
        raise InputError(f"{option} {path}: must be a writable file, got: {e.strerror or e}") from None
    if not existed:
        os.remove(path)


def prepare_output_dir(path, option):
    """Before any work: create the output directory `path` if missing (as every command writing a directory does)
    and check that it is a writable directory. Raises InputError naming the option."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise InputError(f"{option} {path}: must be a directory, got an existing file")
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as e:
        raise InputError(f"{option} {path}: cannot create the directory: {e.strerror or e}") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise InputError(f"{option} {path}: must be a writable directory, got no write permission")


#: How `simulate()`'s messages name the settings this command sets by flags.
SIMULATE_FLAGS = {"h": "--h", "t_end": "--t-end", "solver": "--solver", "formulation": "--formulation",
                  "fixed_point_iterations": "--fixed-point-iterations", "friction_directions": "--friction-directions",
                  "support_model": "--support-model", "limit_surface_twists": "--limit-surface-twists",
                  "limit_surface_resolution": "--limit-surface-resolution", "restitution": "--restitution",
                  "on_failure": "--on-failure record"}


#: A long run's progress bar shows only after this many seconds (a shorter run prints nothing)
PROGRESS_DELAY_S = 2.0


class ProgressBar:
    """A tqdm bar on stderr as `Simulator.progress` (progress(done, total)), shown on a terminal only once a run has
    taken PROGRESS_DELAY_S and cleared at its end; none when tqdm is not installed (it comes with the plan and studies
    extras, and the core's commands do not need it)."""

    def __init__(self, desc, unit="step"):
        try:
            from tqdm import tqdm
        except ImportError:
            tqdm = None
        self._tqdm, self.desc, self.unit, self.bar = tqdm, desc, unit, None

    def __call__(self, done, total):
        if self._tqdm is None:
            return
        if self.bar is None:
            # disable=None: only on a terminal (a log or a pipe gets no bar frames)
            self.bar = self._tqdm(total=total, desc=self.desc, unit=self.unit, delay=PROGRESS_DELAY_S, leave=False,
                                  disable=None)
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def raised_while_interrupted(e):
    """Whether an exception was raised while a KeyboardInterrupt was being handled (its __context__ chain)."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__context__
    return False
