"""Location of the shipped data tables in ``resources/``."""

from __future__ import annotations

import json
import os
from functools import lru_cache
from pathlib import Path
from typing import Any

#: ``resources/`` at the repository root; ``NPSIM_RESOURCES`` overrides it.
RESOURCES_DIR = Path(os.environ.get("NPSIM_RESOURCES", Path(__file__).resolve().parent.parent / "resources"))


def resource_path(name: str) -> Path:
    """Absolute path of a file in ``resources/`` (raises if it is missing)."""
    path = RESOURCES_DIR / name
    if not path.exists():
        raise FileNotFoundError(
            f"NPSim resource {path} is missing; reinstall the project with 'pip install -e .' "
            "from a full checkout or set NPSIM_RESOURCES to the resources folder")
    return path


@lru_cache(maxsize=None)
def load_json_resource(name: str) -> Any:
    """Parsed JSON resource (cached; treat the result as read-only)."""
    with open(resource_path(name), encoding="utf-8") as fh:
        return json.load(fh)
