"""Every ``uniros``, ``uniros-sim`` and ``uniros-fake-robot`` command line in the docs parses.

The command lines of bash blocks (README.md and docs/*.md) are split as the shell would and given to
the program's own argument parser: a renamed option or subcommand fails here, not in a reader's
terminal. (Cheap commands also run: bash blocks marked ``docs-test: run``.)
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex

import pytest
from docs_snippets import Block, all_blocks, shell_lines

from multiros.sim.program import _parser as sim_parser
from uniros.cli import build_parser
from uniros.fake_robot import build_parser as fake_robot_parser

PROGRAMS = {"uniros": build_parser, "uniros-sim": sim_parser, "uniros-fake-robot": fake_robot_parser}
_ASSIGNMENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*=")


def command_lines(block: Block) -> list[list[str]]:
    """argv lists of the block's commands that start one of PROGRAMS (env assignments, & and ; dropped)."""
    found = []
    for words in shell_lines(block):
        for part in " ".join(shlex.quote(w) for w in words).replace(" '&&' ", " ; ").split(" ; "):
            argv = [w for w in shlex.split(part) if w not in ("&", ";")]
            while argv and _ASSIGNMENT.match(argv[0]):
                argv.pop(0)
            if argv and argv[0].rsplit("/", 1)[-1] in PROGRAMS:
                found.append([argv[0].rsplit("/", 1)[-1], *argv[1:]])
    return found


def _lines() -> list[tuple[str, list[str]]]:
    return [(b.where, argv) for b in all_blocks() if b.lang == "bash" for argv in command_lines(b)]


def test_docs_show_the_programs():
    programs = {argv[0] for _, argv in _lines()}
    assert programs == set(PROGRAMS), programs


@pytest.mark.parametrize(("where", "argv"), _lines(), ids=lambda v: v if isinstance(v, str) else " ".join(v)[:60])
def test_command_line_parses(where, argv):
    parser: argparse.ArgumentParser = PROGRAMS[argv[0]]()
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            parser.parse_args(argv[1:])
    except SystemExit as exc:
        if exc.code not in (0, None):
            pytest.fail(f"{where}: `{shlex.join(argv)}` does not parse: {err.getvalue().strip()}")
