"""README.md's examples work as written, and the pages it points to are current.

The Python quick start runs against the bundled sample in a temporary folder; the quick
start's ``csgs`` lines all parse, and the fast ones (info, decode) run on the file the Python
snippet wrote. The command synopsis names only options the commands have. docs/results.md
must be what benchmarks/results_md.py writes, and README.md stays short.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks import results_md
from csgs_cli.main import attach_dash_values, build_parser, main
from csgs_codec import GaussianScene, read_ply

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
SAMPLE = REPO / "samples" / "donut.ply"
SAMPLE_GAUSSIANS = 45_624
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.MULTILINE | re.DOTALL)
#: Commands the tests run rather than only parse (seconds at most on the sample).
FAST_COMMANDS = ("info", "decode")


def fenced(language: str) -> list[str]:
    """The bodies of README.md's code blocks fenced as ``language``."""
    text = README.read_text(encoding="utf-8")
    return [body for kind, body in FENCE.findall(text) if kind == language]


def shell_commands(blocks: int | None = None) -> list[list[str]]:
    """Every ``csgs ...`` line of the README's sh blocks (the first ``blocks`` of them when
    given), as argv without 'csgs'."""
    commands = []
    for block in fenced("sh")[:blocks]:
        for line in block.splitlines():
            words = shlex.split(line, comments=True)
            if words and words[0] == "csgs":
                commands.append(words[1:])
    return commands


class InFolder:
    """Run in ``folder`` and come back (contextlib.chdir is Python 3.11+)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def __enter__(self):
        self.previous = Path.cwd()
        os.chdir(self.folder)

    def __exit__(self, *exc):
        os.chdir(self.previous)


@pytest.fixture(scope="module")
def quick_start(tmp_path_factory):
    """A folder holding samples/donut.ply after the README's Python quick start ran in it,
    and the names the snippet defined."""
    folder = tmp_path_factory.mktemp("readme")
    (folder / "samples").mkdir()
    shutil.copyfile(SAMPLE, folder / "samples" / "donut.ply")
    snippet = fenced("python")[0]
    names: dict = {"__name__": "readme_quick_start"}
    with InFolder(folder):
        exec(compile(snippet, "README.md (Python quick start)", "exec"), names)
    return folder, names


def test_the_readme_is_short():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 180, f"README.md has {len(lines)} lines"


def test_the_python_quick_start_runs_on_the_sample(quick_start):
    folder, names = quick_start
    decoded = names["decoded"]
    assert isinstance(decoded, GaussianScene) and len(decoded) == SAMPLE_GAUSSIANS
    assert (folder / "donut.csgs").read_bytes() == names["data"]
    assert (folder / "donut.glb").stat().st_size > 0
    report = names["report"]
    assert report.scene is not None and len(report.scene) == SAMPLE_GAUSSIANS
    assert report.tiles == [0] and report.bytes_read == report.file_bytes


def test_every_python_block_compiles():
    blocks = fenced("python")
    assert blocks, "README.md has no Python block"
    for number, block in enumerate(blocks):
        compile(block, f"README.md (Python block {number})", "exec")


def test_every_quick_start_command_parses():
    commands = shell_commands()
    assert {argv[0] for argv in commands} >= {"encode", "info", "decode", "view"}, commands
    parser = build_parser()
    for argv in commands:
        args = parser.parse_args(attach_dash_values(parser, argv))
        assert args.command == argv[0]


def test_the_fast_quick_start_commands_run(quick_start, capsys):
    folder, _ = quick_start
    ran = []
    with InFolder(folder):
        for argv in shell_commands(blocks=2):  # make demo/test, then the sample's commands
            if argv[0] in FAST_COMMANDS:
                assert main(argv) == 0, argv
                ran.append(argv[0])
    assert set(ran) == set(FAST_COMMANDS)
    assert "Gaussians" in capsys.readouterr().out
    decoded = read_ply(folder / "donut.ply")
    assert len(decoded) == SAMPLE_GAUSSIANS


def synopsis_entries() -> list[tuple[str, str]]:
    """(command, text) of each ``csgs COMMAND`` entry of the README's text blocks, with the
    indented lines that continue it."""
    entries: list[tuple[str, str]] = []
    for block in fenced("text"):
        for line in block.splitlines():
            if line.startswith("csgs "):
                entries.append((line.split()[1], line))
            elif line.startswith(" ") and entries and entries[-1][1].startswith("csgs "):
                entries[-1] = (entries[-1][0], entries[-1][1] + " " + line.strip())
    return entries


def test_the_synopsis_names_only_options_the_commands_have():
    parser = build_parser()
    entries = synopsis_entries()
    assert {command for command, _ in entries} == set(parser.command_parsers), entries
    for command, text in entries:
        help_text = parser.command_parsers[command].format_help()
        for option in re.findall(r"(?<![\w-])--[a-z][a-z-]*", text):
            pattern = rf"(?<![\w-]){re.escape(option)}(?![\w-])"
            assert re.search(pattern, help_text), f"csgs {command} has no {option}"


def test_the_results_page_is_current():
    done = subprocess.run([sys.executable, str(REPO / "benchmarks" / "results_md.py"),
                           "--check"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr


def test_the_results_page_lists_unknown_kinds_and_reports_staleness(tmp_path, monkeypatch):
    results = tmp_path / "results"
    results.mkdir()
    document = {"schema": "csgs-bench/1", "benchmark": "novel", "machine": {"cpus": 3},
                "setting": "x", "results": [{"scene": "a", "seconds": 1.23456, "nested": {}},
                                            {"scene": "b", "count": 7}]}
    (results / "novel_2026-01-02.json").write_text(json.dumps(document))
    (results / "novel_2026-01-01.json").write_text(json.dumps(document))
    page = tmp_path / "results.md"
    page.write_text("old\n" + results_md.NOTES_HEADING + "\n\nkept by hand\n")
    monkeypatch.setattr(results_md, "RESULTS", results)
    monkeypatch.setattr(results_md, "OUTPUT", page)
    monkeypatch.setattr(results_md, "REPO", tmp_path)
    assert results_md.main(["--check"]) == 1
    assert results_md.main([]) == 0
    text = page.read_text()
    assert "### novel_2026-01-02.json" in text and "Machine: 3 CPUs." in text
    assert "| scene | seconds | count |" in text and "| a | 1.235 | - |" in text
    assert "Other files: novel_2026-01-01.json." in text
    assert text.endswith(results_md.NOTES_HEADING + "\n\nkept by hand\n")
    assert results_md.main(["--check"]) == 0
