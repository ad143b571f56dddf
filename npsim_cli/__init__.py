"""The ``npsim`` command line: argument parsing only; every command calls :mod:`npsim_core.chain`
(or, for ``gui``/``annotate``, opens :mod:`npsim_gui`)."""
