"""Choosing the Mitsuba variant safely (docs/stack.md §2).

``llvm_ad_rgb`` is several times faster than ``scalar_rgb`` but, with an LLVM
that Dr.Jit cannot use (e.g. LLVM 15/16 here), the *first render aborts the
whole process* -- no Python exception. So the choice is made by rendering a tiny
scene in a **subprocess**; the answer is cached in
``~/.cache/npsim/mitsuba_variant.json`` keyed by the Mitsuba version and the
LLVM library found, so the probe runs once per machine set-up.

``NPSIM_MITSUBA_VARIANT=scalar_rgb|llvm_ad_rgb`` overrides the choice.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

from ..errors import NpsimInputError

SUPPORTED = ("llvm_ad_rgb", "scalar_rgb")
ENV_VAR = "NPSIM_MITSUBA_VARIANT"
CACHE_FILE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "npsim" / "mitsuba_variant.json"

_PROBE = r"""
import numpy as np, mitsuba as mi
mi.set_variant("llvm_ad_rgb")
m = mi.Mesh("probe", vertex_count=3, face_count=1, has_vertex_normals=False, has_vertex_texcoords=True)
p = mi.traverse(m)
FT, UT = type(p["vertex_positions"]), type(p["faces"])
p["vertex_positions"] = FT(np.array([[-1, -1, 3], [1, -1, 3], [0, 1, 3]], np.float32).ravel())
p["faces"] = UT(np.array([0, 1, 2], np.uint32))
p["vertex_texcoords"] = FT(np.zeros(6, np.float32))
p.update()
s = mi.load_dict({"type": "scene", "m": m, "e": {"type": "constant"}, "integrator": {"type": "path"},
                  "sensor": {"type": "perspective", "fov": 60,
                             "film": {"type": "hdrfilm", "width": 8, "height": 8}}})
img = np.array(mi.render(s, spp=4))
assert np.isfinite(img).all() and img.mean() > 0
print("NPSIM_PROBE_OK")
"""

_lock = threading.Lock()


@dataclass(frozen=True)
class VariantChoice:
    """The Mitsuba variant to use and why (``reason`` is for logs / the GUI status line)."""

    name: str
    reason: str


def _llvm_library() -> str:
    """The LLVM shared library Dr.Jit would find (its env var, else the newest system one)."""
    env = os.environ.get("DRJIT_LIBLLVM_PATH")
    if env:
        return env
    cands = []
    for pat in ("/usr/lib/*/libLLVM*.so*", "/usr/lib/libLLVM*.so*", "/usr/lib/llvm-*/lib/libLLVM*.so*",
                "/usr/local/lib/libLLVM*.so*"):
        cands.extend(glob.glob(pat))
    return ",".join(sorted(set(cands))) or "none"


def _mitsuba_version() -> str:
    try:
        from importlib.metadata import version

        return version("mitsuba")
    except Exception:  # pragma: no cover - metadata missing in odd installs
        return "unknown"


def probe_llvm(timeout: float = 180.0) -> tuple[bool, str]:
    """Render a tiny scene with ``llvm_ad_rgb`` in a subprocess; (works, detail)."""
    try:
        res = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False, f"probe timed out after {timeout:.0f} s"
    if res.returncode == 0 and "NPSIM_PROBE_OK" in res.stdout:
        return True, "probe render succeeded"
    tail = (res.stderr or res.stdout).strip().splitlines()[-1:] or ["no output"]
    return False, f"probe failed (exit {res.returncode}): {tail[0][:200]}"


def choose_variant(*, refresh: bool = False, use_cache: bool = True) -> VariantChoice:
    """Pick ``llvm_ad_rgb`` if a subprocess probe renders with it, else ``scalar_rgb``.

    Never touches Mitsuba in the calling process. ``NPSIM_MITSUBA_VARIANT``
    overrides; the probe result is cached per (Mitsuba version, LLVM library).
    """
    forced = os.environ.get(ENV_VAR, "").strip()
    if forced:
        if forced not in SUPPORTED:
            raise NpsimInputError(f"{ENV_VAR}={forced!r}: use one of {', '.join(SUPPORTED)}")
        return VariantChoice(forced, f"{ENV_VAR} set")
    libs = _llvm_library()
    key = (f"mitsuba {_mitsuba_version()} | llvm {hashlib.sha1(libs.encode()).hexdigest()[:12]} "
           f"({libs.count(',') + 1 if libs != 'none' else 0} libs) | python {sys.executable}")
    with _lock:
        if use_cache and not refresh and CACHE_FILE.exists():
            try:
                doc = json.loads(CACHE_FILE.read_text())
                if doc.get("key") == key and doc.get("variant") in SUPPORTED:
                    return VariantChoice(doc["variant"], f"cached probe ({doc.get('detail', '')})")
            except (OSError, json.JSONDecodeError):
                pass
        ok, detail = probe_llvm()
        name = "llvm_ad_rgb" if ok else "scalar_rgb"
        if use_cache:
            try:
                CACHE_FILE.parent.mkdir(parents=True, exist_ok=True)
                tmp = CACHE_FILE.with_suffix(f".tmp{os.getpid()}")
                tmp.write_text(json.dumps({"key": key, "variant": name, "detail": detail}))
                os.replace(tmp, CACHE_FILE)
            except OSError:
                pass  # a read-only home only costs a probe next time
        return VariantChoice(name, detail)


def resolve_variant(name: str | None = None) -> VariantChoice:
    """``name`` if given (validated), else :func:`choose_variant`."""
    if name:
        if name not in SUPPORTED:
            raise NpsimInputError(f"Mitsuba variant {name!r} is not supported; use one of {', '.join(SUPPORTED)}")
        return VariantChoice(name, "requested")
    return choose_variant()


def set_variant(name: str | None = None):
    """Activate the variant in this process (``name`` or the probed choice) and return ``mitsuba``."""
    import mitsuba as mi

    choice = resolve_variant(name)
    if mi.variant() != choice.name:
        mi.set_variant(choice.name)
    return mi
