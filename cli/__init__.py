"""The ``csgs`` command-line front end (installed as the ``csgs_cli`` package)."""
