"""Entry point of the ``csgs`` command: argument parsing, warnings, errors and exit codes."""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import traceback
import warnings

from csgs_codec import __version__
from csgs_codec.atomic_write import sigterm_as_interrupt
from csgs_codec.errors import CsgsError, CsgsWarning, DataLossWarning, FallbackWarning
from csgs_codec.extras import missing_extra_message

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2


def _command_modules():
    from csgs_cli import commands

    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(module, "NAME") and hasattr(module, "run"):
            yield module


def _common_options(default) -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--quiet", "-q", action="store_true", default=default,
                        help="no progress bars or warnings, only results and errors")
    common.add_argument("--debug", action="store_true", default=default,
                        help="show the full traceback on errors")
    return common


def build_parser() -> argparse.ArgumentParser:
    """The full ``csgs`` argument parser with every discovered sub-command.

    ``--quiet`` and ``--debug`` work before or after the sub-command: the sub-command's copies
    default to "not given" so they never overwrite the top-level ones.
    """
    parser = argparse.ArgumentParser(
        prog="csgs",
        description="Codec for 3D Gaussian Splatting scenes with semantics.",
        parents=[_common_options(False)],
    )
    parser.add_argument("--version", action="version", version=f"csgs {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub_common = _common_options(argparse.SUPPRESS)
    for module in _command_modules():
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP,
                           parents=[sub_common])
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    parser.command_parsers = dict(sub.choices)
    return parser


def attach_dash_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with each value that starts with '-' joined to the option before it that
    takes one value (``--region -1,-1,-1,1,1,1`` becomes ``--region=-1,-1,-1,1,1,1``, and
    ``--up -z`` ``--up=-z``), so both spellings work. argparse alone takes such a value for
    an option and stops with "expected one argument". A word that is one of the command's
    own options (``-o -q``: a missing value) is left alone, and so is everything after
    ``--``."""
    words = list(argv)
    command = next((i for i, word in enumerate(words) if not word.startswith("-")), None)
    sub = None if command is None else parser.command_parsers.get(words[command])
    if sub is None:
        return words
    options = _option_strings(sub)
    one_value = {name for name, takes_one in options.items() if takes_one}
    out, i = words[:command + 1], command + 1
    while i < len(words):
        word = words[i]
        if word == "--":
            return out + words[i:]
        following = words[i + 1] if i + 1 < len(words) else None
        if (_resolve(word, options) in one_value and following is not None
                and following.startswith("-") and following != "-"
                and not _is_option(following, options)):
            out.append(f"{word}={following}")
            i += 2
            continue
        out.append(word)
        i += 1
    return out


def _option_strings(parser: argparse.ArgumentParser) -> dict[str, bool]:
    """Every option string of ``parser`` -> whether it takes exactly one value."""
    # argparse has no public list of a parser's actions; _actions is read, never changed.
    return {name: action.nargs is None
            for action in parser._actions for name in action.option_strings}


def _resolve(word: str, options: dict[str, bool]) -> str | None:
    """The option string ``word`` names: itself, or the one long option it is a unique
    prefix of (argparse's abbreviations); None for anything else."""
    if word in options:
        return word
    if word.startswith("--") and "=" not in word:
        matches = [name for name in options if name.startswith(word)]
        if len(matches) == 1:
            return matches[0]
    return None


def _is_option(word: str, options: dict[str, bool]) -> bool:
    """Whether argparse would read ``word`` as one of the options: an option string, one
    with ``=VALUE``, an abbreviation, or a short option with its value attached."""
    name = word.split("=", 1)[0]
    if word == "--" or _resolve(name, options) is not None:
        return True
    return not word.startswith("--") and len(word) > 2 and word[:2] in options


def _print_warning(message, category, filename, lineno, file=None, line=None):
    text = str(message)
    label = "warning" if issubclass(category, CsgsWarning) else category.__name__
    print(f"csgs: {label}: {text}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run ``csgs`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(attach_dash_values(parser, argv))
    if not getattr(args, "_run", None):
        # No command is a usage error: help goes where errors go, with the error's exit code.
        parser.print_help(sys.stderr)
        return EXIT_BAD_INPUT
    with warnings.catch_warnings(), sigterm_as_interrupt():
        warnings.showwarning = _print_warning
        if args.quiet:
            warnings.simplefilter("ignore")
            # Dropped data is reported even when quiet: it changes the output.
            warnings.simplefilter("always", DataLossWarning)
            # So is a fallback that changes the results (missing masks, say).
            warnings.simplefilter("always", FallbackWarning)
        else:
            warnings.simplefilter("always", CsgsWarning)
        try:
            return int(args._run(args) or EXIT_OK)
        except CsgsError as err:
            if args.debug:
                traceback.print_exc()
            print(f"csgs: error: {err}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except ModuleNotFoundError as err:
            # A core install (no extras) reaching code that needs torch, pyvista, ...
            message = missing_extra_message(err, args.command)
            if message is None:
                raise
            if args.debug:
                traceback.print_exc()
            print(f"csgs: error: {message}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except KeyboardInterrupt:
            print("csgs: interrupted", file=sys.stderr)
            return 130
        except BrokenPipeError:
            return EXIT_OK
        except OSError as err:
            # A path the system refuses (a name too long, a read-only folder, ...) that no
            # check before named: the file and the system's reason, as for any bad input.
            if err.filename is None:
                raise
            if args.debug:
                traceback.print_exc()
            print(f"csgs: error: {_path_text(err.filename)}: {err.strerror or err}",
                  file=sys.stderr)
            return EXIT_BAD_INPUT


def _path_text(name) -> str:
    """A file name from an OSError (text, bytes or a descriptor number) as text."""
    return os.fsdecode(name) if isinstance(name, (str, bytes, os.PathLike)) else str(name)


if __name__ == "__main__":
    sys.exit(main())
