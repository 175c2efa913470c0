"""The documentation site (mkdocs.yml, docs/): it builds strictly, every broken link or anchor and every docstring
that does not parse a failure, and docs/cli.md documents every subcommand and long option of `planar-lcp`."""

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CLI_PAGE = ROOT / "docs" / "cli.md"


def test_the_site_builds_strictly_without_a_warning(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("material", reason="the Material theme (mkdocs-material) is not installed")
    pytest.importorskip("mkdocstrings_handlers.python", reason="mkdocstrings' Python handler is not installed")
    # the packages documented by docs/api.md are read from this tree (mkdocs.yml: paths [.]); the theme's banner
    # about its own future is not a warning of the build
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, timeout=600, env=env)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-5000:]
    assert "WARNING" not in out, out[-5000:]
    assert (tmp_path / "site" / "index.html").is_file()
    assert (tmp_path / "site" / "cli" / "index.html").is_file()


def subcommands(parser, prefix=()):
    """(the words of each subcommand, e.g. ("study", "falling-rod"), its parser), depth first."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield prefix + (name,), sub
                yield from subcommands(sub, prefix + (name,))


def section_of(text, words):
    """The body of docs/cli.md's heading `## WORDS` (or deeper), up to the next heading."""
    m = re.search(rf"^#+ {re.escape(' '.join(words))}\n(.*?)(?=^#+ |\Z)", text, re.M | re.S)
    return m.group(1) if m else None


def test_the_cli_page_documents_every_subcommand_and_long_option():
    """Each subcommand, as the installed parser builds it (entry-point commands included), has its section in
    docs/cli.md, and the section names each of its long options and positionals."""
    from planar_lcp.cli import build_parser
    text = CLI_PAGE.read_text()
    missing = []
    found = list(subcommands(build_parser()))
    assert {"simulate", "plan", "replay"} <= {words[0] for words, _ in found}
    for words, sub in found:
        body = section_of(text, words)
        if body is None:
            missing.append(f"no section '{' '.join(words)}'")
            continue
        if f"planar-lcp {' '.join(words)}" not in body:
            missing.append(f"{' '.join(words)}: no synopsis")
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            for option in action.option_strings:
                if option.startswith("--") and not re.search(rf"{re.escape(option)}(?![\w-])", body):
                    missing.append(f"{' '.join(words)}: {option}")
            if not action.option_strings and not isinstance(action, argparse._SubParsersAction):
                # as the usage line shows it: its metavar, else its choices, else its name
                name = action.metavar or ("{" + ",".join(map(str, action.choices)) + "}" if action.choices
                                          else action.dest)
                if name not in body:
                    missing.append(f"{' '.join(words)}: {name}")
    assert not missing, missing
    top = build_parser()
    assert all(o in text for a in top._actions for o in a.option_strings if o.startswith("--") and o != "--help")
