"""The docs name what exists: paths, modules, functions and scenes in docs/*.md and README.md are checked against the
tree, so a rename that leaves a page behind fails here (docs/architecture.md, README "Layout")."""

import importlib
import re
import subprocess
from pathlib import Path

import pytest

from planar_lcp import list_scenes

ROOT = Path(__file__).resolve().parents[2]
#: what a run leaves in a checkout that is not the repository's (README: the demo writes ./planar_lcp_demo/), for a
#: tree that is not a git checkout
NOT_THE_REPOSITORYS = {".git", ".venv", "venv", "build", "dist", "__pycache__", ".pytest_cache", ".hypothesis",
                       "planar_lcp_demo", "out"}


def repository_files():
    """The repository's files (paths relative to ROOT): what git tracks plus new files it does not ignore, so that
    what a command writes into the checkout (the demo's folder, a virtualenv) is not the repository's; outside a git
    checkout every file but those under NOT_THE_REPOSITORYS."""
    try:
        out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                             capture_output=True, check=True)
        files = [Path(p) for p in out.stdout.decode().split("\0") if p]
    except (OSError, subprocess.CalledProcessError):
        files = [p.relative_to(ROOT) for p in ROOT.rglob("*") if p.is_file()]
        files = [p for p in files if not (set(p.parts) & NOT_THE_REPOSITORYS or p.parts[0].endswith(".egg-info"))]
    return [p for p in files if (ROOT / p).is_file()]         # a tracked file deleted in the working tree is gone


FILES = repository_files()
PAGES = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
SOURCES = [ROOT / p for p in FILES if p.suffix == ".py"] + sorted((ROOT / "scenes").glob("*.toml"))
SOURCE_TEXT = "\n".join(p.read_text() for p in SOURCES)
WORDS = set(re.findall(r"\w+", SOURCE_TEXT))
SCENES = sorted(name for name, _ in list_scenes())
PYPROJECT = (ROOT / "pyproject.toml").read_text()
#: names the docs use that no source defines: a corpus instance (../shared/data/lcp), a column of OMPL's benchmark
#: database
#: the benchmark database's columns are planners/bench.py's RUN_FIELDS with spaces as underscores
#: (ompl_benchmark_statistics makes them)
#: the Gymnasium environment ids planners/__init__.py registers (docs/gym.md): they look like paths
GYM_IDS = {"planar_lcp/PushT-v0", "planar_lcp/Task-v0"}
NOT_IN_THE_SOURCES = {"murty_ex2_11", "simulated_steps_per_second", "simulated_steps", "graph_motions"}


def section(text, title):
    m = re.search(rf"^##+ {re.escape(title)}\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    assert m, f"no section {title!r}"
    return m.group(1)


def ids(pages):
    return [p.name for p in pages]


@pytest.mark.parametrize("page", PAGES, ids=ids(PAGES))
def test_paths_named_in_the_docs_exist(page):
    text = page.read_text()
    missing = []
    for m in re.finditer(r"(?<![\w/.])((?:planar_lcp|planners|tests|examples|scenes|docs|engine|spec|studies|benchmarks|bridges|parallel"
                         r"|kernels)/[\w/.-]*\w)", text):
        path = m.group(1).split("::")[0]
        if path in ("scenes/x.toml", "scenes/NAME.toml"):       # placeholders in examples
            continue
        if path in GYM_IDS:                                      # environment ids, not paths
            continue
        if not ((ROOT / path).exists() or (ROOT / "planar_lcp" / path).exists()):
            missing.append(path)
    assert not missing, f"{page.name} names paths that do not exist: {sorted(set(missing))}"


@pytest.mark.parametrize("page", PAGES, ids=ids(PAGES))
def test_links_between_pages_resolve(page):
    text = page.read_text()
    bad = [t for t in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
           if not t.startswith("http") and not (page.parent / t).exists()]
    assert not bad, f"{page.name}: broken links {bad}"


@pytest.mark.parametrize("page", PAGES, ids=ids(PAGES))
def test_modules_and_names_in_the_docs_exist(page):
    """`planar_lcp.a.b.name` imports; a `name_with_underscores` or `Name.attr` in backticks is defined somewhere in the
    sources (a function, a constant, a stats key, a test)."""
    text = page.read_text()
    bad = []
    for dotted in sorted(set(re.findall(r"\bplanar_lcp(?:\.\w+)+", text))):
        if f'"{dotted}"' in PYPROJECT:                       # the entry-point group planar_lcp.commands
            continue
        if f'FORMAT = "{dotted}"' in SOURCE_TEXT:            # a file format's name, e.g. planar_lcp.push_model
            continue
        parts = dotted.split(".")
        for k in range(len(parts), 0, -1):
            try:
                obj = importlib.import_module(".".join(parts[:k]))
                break
            except ImportError:
                continue
        for attr in parts[k:]:
            if not hasattr(obj, attr):
                bad.append(dotted)
                break
            obj = getattr(obj, attr)
    for token in re.findall(r"`([^`\n]+)`", text):
        if not re.fullmatch(r"[A-Za-z_][\w.]*(\(.*\))?", token) or token.startswith("planar_lcp"):
            continue
        for name in re.findall(r"[A-Za-z_]\w*", token.split("(")[0]):
            looks_like_code = "_" in name.strip("_") or re.fullmatch(r"[A-Z][a-z]+[A-Z]\w*", name)
            if looks_like_code and name not in WORDS | NOT_IN_THE_SOURCES:
                bad.append(token)
    assert not bad, f"{page.name} names what the code does not define: {sorted(set(bad))}"


@pytest.mark.parametrize("page", PAGES, ids=ids(PAGES))
def test_example_scripts_named_in_the_docs_exist(page):
    missing = [s for s in re.findall(r"python (examples/[\w/]+\.py)", page.read_text()) if not (ROOT / s).is_file()]
    assert not missing, f"{page.name}: {missing}"


def test_the_readme_and_scene_format_list_every_shipped_scene():
    readme = (ROOT / "README.md").read_text()
    m = re.search(r"Shipped scenes \(`scenes/\*\.toml`(.*?)Scenes are found", readme, re.S)
    assert m, "README has no 'Shipped scenes' sentence"
    assert sorted(re.findall(r"`(\w+)`", m.group(1))) == SCENES
    table = section((ROOT / "docs" / "scene-format.md").read_text(), "Shipped scenes")
    assert sorted(re.findall(r"^\| `(\w+)` \|", table, re.M)) == SCENES


def test_the_readme_layout_names_every_module_and_folder():
    layout = section((ROOT / "README.md").read_text(), "Layout")
    block = re.search(r"```\n(.*?)```", layout, re.S).group(1)
    named = set(re.findall(r"[\w.]+/?", block))
    for p in FILES:
        if p.parts[0] not in ("planar_lcp", "planners"):
            continue
        for folder in p.parts[1:-1]:
            assert folder + "/" in named, f"README Layout does not name the folder {folder}/ of {p}"
        if p.suffix == ".py" and not (p.name == "__init__.py" and p.parent.name != "planar_lcp"):
            assert p.name in named, f"README Layout does not name {p}"
    for top in sorted({p.parts[0] for p in FILES if len(p.parts) > 1}):
        if top.startswith(".") and top != ".ci":
            continue
        assert (top + "/") in named or f"{top}/run" in block, f"README Layout does not name {top}/"
    for name in sorted(n for n in named if n.endswith(".py") or n.endswith("/")):
        assert list(ROOT.rglob(name.rstrip("/"))), f"README Layout names {name}, which does not exist"


#: pages whose Python examples run elsewhere, with more checks: docs/planning.md's needs its task file
#: (tests/planning/test_task_planning.py), docs/gym.md's (tests/environments/test_gym.py), docs/closed_loop.md's first
#: (tests/environments/test_pusht_policy.py)
PY_BLOCKS_ELSEWHERE = {"planning.md", "gym.md", "closed_loop.md"}
#: a block that must not run as pasted (it needs a file a command writes, or a data set) is preceded by this comment,
#: with the reason: `<!-- not run: needs plan.json, which planar-lcp plan writes -->`
NOT_RUN = re.compile(r"<!-- not run: [^>]+-->\n*$")


def python_blocks(page):
    """The ```python blocks of a page, each with its index, less those marked as not run."""
    text = page.read_text()
    return [(i, m.group(1)) for i, m in enumerate(re.finditer(r"```python\n(.*?)```", text, re.S))
            if not NOT_RUN.search(text[:m.start()])]


#: the Python examples of README.md and of every page of docs/
PY_BLOCKS = [(p, i, b) for p in PAGES if p.name not in PY_BLOCKS_ELSEWHERE for i, b in python_blocks(p)]


@pytest.mark.parametrize("page, index, code", PY_BLOCKS, ids=[f"{p.name}-{i}" for p, i, _ in PY_BLOCKS])
def test_the_python_examples_in_the_docs_run(page, index, code, tmp_path):
    """Each example runs as a user pastes it, in an empty directory; each line whose comment shows its value
    (`r.status, r.z, ...   # ('solved', ...)`) is left as written: the run must not fail."""
    import subprocess
    import sys
    if "planners.plan(" in code or "import ompl" in code:
        pytest.importorskip("ompl")
    for module in ("gymnasium", "shapely", "h5py"):
        if re.search(rf"^\s*(import|from) {module}\b", code, re.M) or (module == "shapely" and "PushTPolicy" in code):
            pytest.importorskip(module)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=600,
                       env=dict(__import__("os").environ, MPLBACKEND="Agg"))
    assert r.returncode == 0, f"{page.name} example {index}:\n{code}\n{r.stderr[-3000:]}"


#: every `SimOptions(...)` the pages show in a code span (the README's `SimOptions(warm_start=True)` among them)
SIMOPTIONS_SPANS = sorted({m for p in PAGES for m in re.findall(r"`(SimOptions\([^`]*\))`", p.read_text())})


def test_the_simoptions_the_docs_show_run_a_simulator():
    """Each as written, without h (the scene's [sim] h): `Simulator(model, options)` steps a shipped scene."""
    import numpy as np

    import planar_lcp
    from planar_lcp.model import compile_scene
    assert "SimOptions(warm_start=True)" in SIMOPTIONS_SPANS
    model = compile_scene(planar_lcp.load_scene("box_push"))
    for span in SIMOPTIONS_SPANS:
        sim = planar_lcp.Simulator(model, eval(span, {"SimOptions": planar_lcp.SimOptions}))
        assert sim.h == model.scene.sim.h, span
        run = sim.rollout(*sim.initial_state()[:3], model.vk0[None], 5)
        assert np.all(run["status"] == 0) and np.all(np.isfinite(run["q"])), span


def test_ci_runs_the_readmes_two_commands_in_order():
    """.ci/run runs exactly the README's two commands, in order (the demo before the tests), as a user does, then the
    slow tests (with a report of their durations)."""
    first_block = re.search(r"```\n(.*?)```", (ROOT / "README.md").read_text(), re.S).group(1)
    commands = [line.strip() for line in first_block.strip().splitlines()]
    assert commands == ['python -m pip install -e ".[dev]" && planar-lcp demo', "python -m pytest"]
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    install = ci.index('python -m pip install -q -e ".[dev]" && planar-lcp demo')   # the first, quiet
    assert ci.index("python -m pytest") > install
    slow = next(i for i, line in enumerate(ci) if line.startswith("python -m pytest -m slow"))
    assert slow > ci.index("python -m pytest")
