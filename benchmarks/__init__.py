"""Speed-against-error benchmarks: ``npsim bench TARGET`` or ``python -m benchmarks.TARGET``.

Each module has ``main(argv) -> int``; its options are shown by ``--help``.
"""

import pkgutil

__all__ = ["available"]


def available() -> list[str]:
    """Names of the benchmark modules."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
