"""One module per ``csgs`` sub-command.

Each module defines ``NAME`` (the sub-command), ``HELP`` (one line), ``add_arguments(parser)``
and ``run(args) -> int``. :mod:`csgs_cli.main` discovers them, so adding a command never edits
a shared file. Commands parse arguments, show progress and call the library; no codec logic.
"""
