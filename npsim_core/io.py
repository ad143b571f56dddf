"""File formats: atomic writes, images, depth and normal maps.

Every reader validates and raises :class:`NpsimInputError` naming the file and
the fix; every writer writes to a temporary file in the target folder and
renames it into place, so a crash never leaves a half-written file.
"""

from __future__ import annotations

import json
import os
import tempfile
import zlib
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import cv2
import numpy as np

from .errors import NpsimInputError

PathLike = str | os.PathLike

# mkstemp creates 0600 files; finished files get the usual 0666 & ~umask instead (read once at import,
# since reading the umask means setting it).
_UMASK = os.umask(0o022)
os.umask(_UMASK)


# --------------------------------------------------------------------------- atomic writing
@contextmanager
def atomic_path(path: PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    On any exception the temporary file is removed and ``path`` is untouched.
    ``suffix`` defaults to ``path``'s suffix (encoders pick the format from it).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # The temp name keeps the real suffix so encoders (np.save, cv2) pick the right format.
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.tmp-", suffix=suffix if suffix is not None else path.suffix,
                               dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as fh:
            os.fsync(fh.fileno())
        try:  # keep the mode of a file being replaced; new files get the umask's mode
            mode = path.stat().st_mode & 0o7777
        except FileNotFoundError:
            mode = 0o666 & ~_UMASK
        os.chmod(tmp_path, mode)
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def staging_prefix(name: str) -> str:
    """Prefix of the staging folder an export of frame ``name`` writes into before it commits
    (:mod:`npsim_core.chain.export`): ``.<name>.partial-<pid>-``, so a leftover can be told from a
    staging folder in use (:func:`remove_stale_staging`)."""
    return f".{name}.partial-{os.getpid()}-"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def remove_stale_staging(folder: PathLike, depth: int = 0) -> list[tuple[Path, int]]:
    """Remove the export staging folders (``.*.partial-*``) a killed run left in ``folder`` (and its
    sub-folders down to ``depth`` levels): those whose process (the pid in the name) is gone, and
    those of older versions without a pid. Returns (path, bytes) of each removed folder, for the
    caller to say so (1.5 GB were left by a killed 'npsim mesh').

    A staging folder of a live process on this machine is left alone; on a cluster whose nodes
    share the folder a pid says nothing, so do not run two writers into one frame folder."""
    import re
    import shutil

    folder = Path(folder)
    out: list[tuple[Path, int]] = []
    if not folder.is_dir():
        return out
    levels, current = [folder], [folder]
    for _ in range(depth):
        current = [p for lv in current for p in lv.iterdir() if p.is_dir() and not p.name.startswith(".")]
        levels += current
    for base in levels:
        for p in base.glob(".*.partial-*"):
            if not p.is_dir():
                continue
            m = re.search(r"\.partial-(\d+)-", p.name)
            if m and _pid_alive(int(m.group(1))):
                continue
            size = sum(f.stat().st_size for f in p.rglob("*") if f.is_file())
            shutil.rmtree(p, ignore_errors=True)
            out.append((p, size))
    return out


def atomic_write_bytes(path: PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path: PathLike, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def write_json(path: PathLike, obj: Any) -> None:
    """Atomically write ``obj`` as indented UTF-8 JSON."""
    atomic_write_text(path, json.dumps(obj, indent=1, default=_json_default) + "\n")


def read_json(path: PathLike) -> Any:
    path = _existing(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise NpsimInputError(f"{path}: not valid JSON ({exc}); fix or regenerate the file") from None


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def write_npy(path: PathLike, array: np.ndarray) -> None:
    with atomic_path(path, suffix=".npy") as tmp:
        np.save(tmp, np.ascontiguousarray(array), allow_pickle=False)


def write_image(path: PathLike, image: np.ndarray) -> None:
    """Atomically write an image; RGB(A) arrays are given in RGB order.

    uint8 / uint16 grey or RGB; the format follows the suffix (``.png``, ``.jpg``…).
    """
    img = np.ascontiguousarray(image)
    if img.ndim == 3 and img.shape[2] in (3, 4):
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR if img.shape[2] == 3 else cv2.COLOR_RGBA2BGRA)
    path = Path(path)
    ok, buf = cv2.imencode(path.suffix or ".png", img)
    if not ok:
        raise NpsimInputError(f"{path}: OpenCV could not encode a {img.dtype} image of shape {image.shape}")
    atomic_write_bytes(path, buf.tobytes())


# --------------------------------------------------------------------------- reading
def _existing(path: PathLike) -> Path:
    path = Path(path)
    if not path.exists():
        raise NpsimInputError(f"{path}: file not found; check the path")
    if path.is_dir():
        raise NpsimInputError(f"{path}: is a folder, expected a file")
    return path


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _damage(data: bytes) -> str | None:
    """Why the bytes of a PNG or JPEG cannot be a whole image (truncated, a chunk's CRC wrong), or None.

    Checked before decoding, so the program names the file itself instead of libpng/libjpeg printing
    "libpng error: Read Error" on stderr (or OpenCV returning a half-decoded JPEG)."""
    if data.startswith(_PNG_SIGNATURE):
        pos, n = 8, len(data)
        while pos + 12 <= n:
            length = int.from_bytes(data[pos:pos + 4], "big")
            kind = data[pos + 4:pos + 8]
            end = pos + 12 + length
            if end > n:
                return f"truncated PNG (its {kind.decode('latin-1')} chunk ends after the file's {n} bytes)"
            if zlib.crc32(data[pos + 4:end - 4]) != int.from_bytes(data[end - 4:end], "big"):
                return f"corrupt PNG (checksum of its {kind.decode('latin-1')} chunk at byte {pos} is wrong)"
            if kind == b"IEND":
                return None
            pos = end
        return f"truncated PNG (no end chunk in its {n} bytes)"
    if data.startswith(b"\xff\xd8") and not data.rstrip(b"\0")[-2:] == b"\xff\xd9":
        return "truncated JPEG (no end marker)"
    return None


def imread(path: PathLike, flags: int = cv2.IMREAD_UNCHANGED) -> np.ndarray | None:
    """``cv2.imread`` that names a truncated or corrupt PNG/JPEG itself (:class:`NpsimInputError`)
    instead of letting the codec print to stderr; None for other undecodable files, like OpenCV."""
    path = _existing(path)
    data = path.read_bytes()
    why = _damage(data)
    if why:
        raise NpsimInputError(f"{path}: {why}; the file is damaged -- copy it again from its source")
    return cv2.imdecode(np.frombuffer(data, np.uint8), flags)


def read_image(path: PathLike, *, color: bool = True) -> np.ndarray:
    """Read an image: ``color=True`` -> HxWx3 uint8 RGB; ``False`` -> the raw single channel.

    Raw single-channel reads keep the bit depth (uint8 or uint16).
    """
    path = _existing(path)
    flag = cv2.IMREAD_COLOR if color else cv2.IMREAD_UNCHANGED
    img = imread(path, flag)
    if img is None:
        raise NpsimInputError(f"{path}: not a readable image (corrupt, or an unsupported format)")
    if color:
        if img.dtype != np.uint8:
            img = (img / 257).astype(np.uint8)
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return img


def instance_ids_path(label_path: PathLike) -> Path | None:
    """Where a frame's Cityscapes instanceIds are: ``X_instanceIds.png`` beside ``X_labelIds.png`` (or
    ``X_labelTrainIds.png``; a scene folder's ``<name>_labelIds.png`` alike); None when the label file's name has
    neither ending or that file does not exist."""
    label_path = Path(label_path)
    name = label_path.name.replace("_labelTrainIds.png", "_instanceIds.png").replace("_labelIds.png",
                                                                                    "_instanceIds.png")
    path = label_path.with_name(name)
    return path if path != label_path and path.exists() else None


def read_instance_ids(path: PathLike, shape: tuple[int, int]) -> np.ndarray:
    """Read a Cityscapes instanceIds PNG (``labelId * 1000 + k`` on things, the labelId elsewhere) as HxW int32,
    checked against the image's ``shape`` (H, W)."""
    inst = read_image(path, color=False)
    if inst.ndim != 2 or inst.shape != tuple(shape):
        raise NpsimInputError(f"{path}: instanceIds must be a single-channel {shape[1]}x{shape[0]} PNG like the "
                              f"labels, got shape {inst.shape}")
    return inst.astype(np.int32)


def read_label_image(path: PathLike, *, trainids: bool = False) -> np.ndarray:
    """Read a labelIds PNG as HxW uint8 (trainIds mapped to labelIds when asked)."""
    from .labels import cityscapes

    path = _existing(path)
    img = imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise NpsimInputError(f"{path}: not a readable label image")
    if img.ndim == 3:
        if np.all(img[..., 0] == img[..., 1]) and np.all(img[..., 1] == img[..., 2]):
            img = img[..., 0]
        else:
            raise NpsimInputError(
                f"{path}: label image is colour; NPSim needs a single-channel labelIds PNG "
                "(Cityscapes *_gtFine_labelIds.png), not the *_color.png visualisation")
    if img.dtype != np.uint8:
        if img.max() > 255:
            raise NpsimInputError(f"{path}: label values up to {img.max()} exceed labelIds 0..33")
        img = img.astype(np.uint8)
    table = cityscapes()
    if trainids:
        img = table.trainid_to_labelid()[img]
    table.validate(img, str(path))
    if not trainids:
        table.check_not_trainids(img, str(path))
    return img


def read_array(path: PathLike) -> np.ndarray:
    """Read a ``.npy`` array without pickles."""
    path = _existing(path)
    try:
        return np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise NpsimInputError(f"{path}: not a readable .npy array ({exc})") from None


def read_pfm(path: PathLike) -> np.ndarray:
    """Read a PFM (portable float map) as float32, top row first."""
    path = _existing(path)
    with open(path, "rb") as fh:
        header = fh.readline().strip()
        if header not in (b"PF", b"Pf"):
            raise NpsimInputError(f"{path}: not a PFM file (header {header[:8]!r})")
        channels = 3 if header == b"PF" else 1
        try:
            w, h = (int(x) for x in fh.readline().split())
            scale = float(fh.readline().strip())
        except ValueError:
            raise NpsimInputError(f"{path}: malformed PFM header") from None
        data = np.frombuffer(fh.read(), dtype="<f4" if scale < 0 else ">f4")
    if data.size != w * h * channels:
        raise NpsimInputError(f"{path}: PFM holds {data.size} values, header says {w}x{h}x{channels}")
    arr = data.reshape(h, w, channels) if channels == 3 else data.reshape(h, w)
    return np.flipud(arr).astype(np.float32)


def write_pfm(path: PathLike, array: np.ndarray) -> None:
    arr = np.asarray(array, dtype="<f4")
    header = b"PF\n" if arr.ndim == 3 else b"Pf\n"
    h, w = arr.shape[:2]
    atomic_write_bytes(path, header + f"{w} {h}\n-1.0\n".encode() + np.flipud(arr).tobytes())


def read_depth(path: PathLike, *, disparity_baseline: float | None = None,
               disparity_focal: float | None = None) -> np.ndarray:
    """Read a depth map in metres as HxW float32; invalid pixels become NaN.

    Formats: ``.npy``; ``.pfm``; ``.exr`` (when OpenCV's EXR codec is enabled);
    16-bit PNG holding metres×256 (0 = invalid); or, when ``disparity_baseline``
    (m) and ``disparity_focal`` (px) are given, a Cityscapes disparity PNG
    ``disp = (p - 1) / 256`` with ``depth = baseline * focal / disp``.
    """
    path = _existing(path)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        d = read_array(path)
    elif suffix == ".pfm":
        d = read_pfm(path)
    elif suffix == ".exr":
        os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
        d = cv2.imread(str(path), cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH)
        if d is None:
            raise NpsimInputError(f"{path}: OpenCV could not read this EXR (its EXR codec may be disabled); "
                                  "convert it to .npy or .pfm")
        if d.ndim == 3:
            d = d[..., 0]
    elif suffix == ".png":
        raw = imread(path, cv2.IMREAD_UNCHANGED)
        if raw is None:
            raise NpsimInputError(f"{path}: not a readable PNG")
        if raw.dtype != np.uint16 or raw.ndim != 2:
            raise NpsimInputError(f"{path}: depth PNG must be single-channel 16-bit (metres×256), got "
                                  f"{raw.dtype} with shape {raw.shape}")
        raw = raw.astype(np.float32)
        if disparity_baseline is not None or disparity_focal is not None:
            if not disparity_baseline or not disparity_focal:
                raise NpsimInputError(f"{path}: a disparity PNG needs both baseline (m) and focal (px)")
            disp = (raw - 1.0) / 256.0
            with np.errstate(divide="ignore"):
                d = np.where(raw > 0, disparity_baseline * disparity_focal / disp, np.nan)
        else:
            d = np.where(raw > 0, raw / 256.0, np.nan)
    else:
        raise NpsimInputError(f"{path}: unsupported depth format {suffix!r}; use .npy, .pfm, .exr or 16-bit .png")
    d = np.asarray(d)
    if d.ndim == 3 and d.shape[2] == 1:
        d = d[..., 0]
    if d.ndim != 2:
        raise NpsimInputError(f"{path}: depth must be a 2-D HxW map, got shape {d.shape}")
    if not np.issubdtype(d.dtype, np.floating) and not np.issubdtype(d.dtype, np.integer):
        raise NpsimInputError(f"{path}: depth dtype {d.dtype} is not numeric")
    d = d.astype(np.float32)
    with np.errstate(invalid="ignore"):
        d[~(np.isfinite(d) & (d > 0))] = np.nan
    return d


def write_depth_png(path: PathLike, depth: np.ndarray) -> None:
    """16-bit PNG, metres×256, 0 = invalid (max 255.99 m; farther is clipped)."""
    d = np.asarray(depth, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    raw = np.where(valid, np.clip(np.round(d * 256.0), 1, 65535), 0).astype(np.uint16)
    write_image(path, raw)


def read_normals(path: PathLike) -> np.ndarray:
    """Read normals as HxWx3 float32 unit vectors (camera frame, docs/method.md §1.3).

    ``.npy`` holds the vectors directly; an 8/16-bit RGB PNG encodes
    ``n = 2c/(2^b - 1) - 1`` per channel (x, y, z in R, G, B). Zero-length
    vectors and non-finite values become NaN (invalid).
    """
    path = _existing(path)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        n = read_array(path).astype(np.float32)
    elif suffix == ".png":
        raw = imread(path, cv2.IMREAD_UNCHANGED)
        if raw is None or raw.ndim != 3 or raw.shape[2] < 3:
            raise NpsimInputError(f"{path}: normal PNG must be 3-channel RGB (8 or 16 bit)")
        raw = cv2.cvtColor(raw[..., :3], cv2.COLOR_BGR2RGB)
        bits = 16 if raw.dtype == np.uint16 else 8
        n = 2.0 * raw.astype(np.float32) / (2 ** bits - 1) - 1.0
    else:
        raise NpsimInputError(f"{path}: unsupported normals format {suffix!r}; use .npy or an RGB .png")
    if n.ndim != 3 or n.shape[2] != 3:
        raise NpsimInputError(f"{path}: normals must be HxWx3, got shape {n.shape}")
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / norm
    n[~(np.isfinite(n).all(axis=-1) & (norm[..., 0] > 1e-6))] = np.nan
    return n.astype(np.float32)


def write_normals_png(path: PathLike, normals: np.ndarray, bits: int = 16) -> None:
    """Encode unit normals as ``c = (n + 1)/2 * (2^b - 1)``; invalid -> 0."""
    n = np.nan_to_num(np.asarray(normals, dtype=np.float64), nan=-1.0)
    top = 2 ** bits - 1
    c = np.clip(np.round((n + 1.0) * 0.5 * top), 0, top).astype(np.uint16 if bits == 16 else np.uint8)
    write_image(path, c)


def normals_to_rgb(normals: np.ndarray) -> np.ndarray:
    """Visualise normals as uint8 RGB ((n+1)/2), invalid pixels black."""
    n = np.asarray(normals, dtype=np.float32)
    rgb = np.clip((n + 1.0) * 127.5, 0, 255)
    rgb[~np.isfinite(n).all(axis=-1)] = 0
    return rgb.astype(np.uint8)


def depth_to_rgb(depth: np.ndarray, vmax: float | None = None) -> np.ndarray:
    """Visualise depth as uint8 RGB (inverse depth, turbo colour map), invalid black."""
    d = np.asarray(depth, dtype=np.float32)
    valid = np.isfinite(d) & (d > 0)
    inv = np.zeros_like(d)
    inv[valid] = 1.0 / d[valid]
    if valid.any():
        lo = 1.0 / (vmax if vmax else float(np.percentile(d[valid], 99)))
        hi = float(np.percentile(inv[valid], 99.5))
        inv = np.clip((inv - lo) / max(hi - lo, 1e-9), 0, 1)
    img = cv2.applyColorMap((inv * 255).astype(np.uint8), cv2.COLORMAP_TURBO)
    img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    img[~valid] = 0
    return img


def map_files(folder: PathLike, pattern: str) -> list[Path]:
    """Sorted files in ``folder`` matching a glob ``pattern`` (recursive with '**')."""
    return sorted(Path(folder).glob(pattern))

