"""One module per sub-command (``register(subparsers)``); see :mod:`npsim_cli.main`."""
