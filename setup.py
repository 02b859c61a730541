"""Package discovery only (metadata lives in pyproject.toml).

The command-line front end lives in the top-level ``cli/`` folder but installs as ``csgs_cli``
so that nothing installs a module with the generic name ``cli``.
"""

from setuptools import find_packages, setup

library = find_packages(include=["csgs_codec", "csgs_codec.*"])
front_end = ["csgs_cli" + name[len("cli"):] for name in find_packages(include=["cli", "cli.*"])]

setup(packages=library + front_end, package_dir={"csgs_cli": "cli"})
