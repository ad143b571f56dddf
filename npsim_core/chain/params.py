"""Every parameter of the chain: one frozen section per stage, presets and JSON.

The sections are the stage packages' own parameter objects (``FilterParams``,
``UncertaintyParams``, ``RefineParams``, ``PostprocessParams``, ``DenoiseParams``)
plus the chain-level ones defined here. Names shown by the app's sliders (λ1..λ3,
per-class probabilities) are the app's business.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from ..errors import NpsimInputError
from ..mesh.postprocess import PostprocessParams
from ..refine.bilateral import FilterParams
from ..refine.params import OPTIMIZER_FIELDS, PRESETS, RefineParams
from ..refine.uncertainty import UncertaintyParams
from ..render.denoise import DENOISERS, DenoiseParams
from ..render.scene_builder import INTEGRATORS, RENDER_SAMPLER, SAMPLERS
from .names import DEPTH_SOURCES, LIGHT_SOURCES

__all__ = ["CameraSetup", "DepthSource", "ExportParams", "MeshParams", "NightParams", "ChainParams", "LightsParams",
           "LIGHT_SOURCES", "MESH_DEPTHS", "DEPTH_SOURCES", "parse_value", "unread_fields", "changed_fields",
           "set_fields"]

#: The only fields where infinity means something (keep every visible vertex's depth).
INFINITE_OK = {("postprocess", "keep_consistent")}

#: Which depth the mesh is built from: the refined depth (the method), or one of the
#: thesis's baselines -- the cross-bilateral-filtered depth or the input depth.
MESH_DEPTHS = ("refined", "filtered", "input")


@dataclass(frozen=True)
class CameraSetup:
    """hfov_deg: horizontal field of view in degrees; 0 keeps the frame's intrinsics."""

    hfov_deg: float = 0.0




@dataclass(frozen=True)
class DepthSource:
    """The input depth D and normals N of each frame.

    source : ``auto`` (default) takes the frame's own depth (a scene folder's ``depth_pred.npy``,
        from ``npsim estimate``) if it has one, else the dataset's stereo (disparity + camera
        JSON, holes filled from the aligned pop-up prior), else a network when ``checkpoint``
        is given, else the pop-up prior. ``files``, ``stereo``, ``network`` and ``prior``
        force one (an error names the frame when it lacks it).
    checkpoint : a local depth-network checkpoint folder ('' = none; nothing is downloaded).
    stereo_max_m : stereo depth beyond this many metres counts as a hole (filled from the prior)
        and is not used for scoring.
    stereo_holdout : fraction of the valid stereo pixels held out of the input when the stereo is
        the input depth (a fixed seed picks them; filled like holes) -- the frame is then scored
        against those pixels only, so the score measures the chain, not its copy of the input;
        0 = none (the scores then compare the result with its own input).
    near_limit : metres; any input depth nearer than this is invalid (NaN), from every source, and
        the pixels dropped are counted in the log (the far limit is ``mesh.far_limit``).
    stereo_surfaces : stereo depth is replaced by robust per-segment surface fits where the labels
        say the surface is simple (speckle and edge-fattening removal, local planes in inverse
        depth; :mod:`npsim_core.geometry.surfaces`, docs/relight.md). Off = the stereo as matched.
    """

    source: str = "auto"
    checkpoint: str = ""
    stereo_max_m: float = 80.0
    stereo_surfaces: bool = True
    near_limit: float = 0.1
    stereo_holdout: float = 0.1

    def __post_init__(self) -> None:
        if self.source not in DEPTH_SOURCES:
            raise NpsimInputError(f"depth.source must be one of {', '.join(DEPTH_SOURCES)}, got {self.source!r}")
        if self.source == "network" and not self.checkpoint:
            raise NpsimInputError("depth.source 'network' needs depth.checkpoint, a local checkpoint folder "
                                  "(CLI: --checkpoint DIR)")
        if not self.stereo_max_m > 0:
            raise NpsimInputError(f"depth.stereo_max_m must be > 0, got {self.stereo_max_m}")
        if not 0 <= float(self.stereo_holdout) < 1:
            raise NpsimInputError(f"depth.stereo_holdout must be a fraction in [0, 1), got {self.stereo_holdout}")
        if not (math.isfinite(float(self.near_limit)) and float(self.near_limit) >= 0):
            raise NpsimInputError(f"depth.near_limit must be a finite number of metres >= 0, got {self.near_limit}")


@dataclass(frozen=True)
class MeshParams:
    """Meshing.

    stride : vertex spacing in pixels (> 1 meshes a subsampled grid, for previews).
    far_limit : metres; no vertex deeper (a reduced mesh's vertices beyond it are pulled onto it
        along their camera rays, :func:`npsim_core.mesh.types.limit_far`).
    postprocess : the post-processing kernel (deletion, completion, step walls) on/off;
        off gives the plain Worldsheet grid.
    face_budget : 0 keeps every face; else the quadtree-reduced mesh of about that many faces
        (the chain's mesh itself: the 3D view, the export and the nights all get it).
    depth : ``refined`` (default), ``filtered`` or ``input`` -- the depth meshed (see MESH_DEPTHS).
    render_tolerance : > 0 renders the nights from the quadtree reduction of the post-processed
        mesh whose merged cells keep every pixel within this relative depth of the full mesh
        (0.01 = 1 %; label, light and silhouette borders stay at pixel resolution); 0 (default)
        renders the full mesh. Not applied when ``face_budget`` already reduced the mesh, nor to
        a mesh without post-processing (a plain grid has no sheets to merge). Measured
        (docs/relight.md): at 1 % the 2048x1024 scene builds in 2.9 s instead of 10.2 s but
        renders only ~5 % faster, and flattening the surface relief changes the shading
        (error on the benchmark crops 16 -> 31 sRGB levels at 64 spp), so it is off.
    """

    stride: int = 1
    far_limit: float = 300.0
    postprocess: bool = True
    face_budget: int = 0
    depth: str = "refined"
    render_tolerance: float = 0.0

    def __post_init__(self) -> None:
        if int(self.stride) < 1:
            raise NpsimInputError(f"mesh stride must be >= 1 pixel, got {self.stride}")
        if not 0 <= float(self.render_tolerance) < 1:
            raise NpsimInputError(f"mesh.render_tolerance must be in [0, 1) (0 = render the full mesh), "
                                  f"got {self.render_tolerance}")
        if int(self.face_budget) < 0:
            raise NpsimInputError(f"face budget must be >= 0 (0 = no reduction), got {self.face_budget}")
        if not self.far_limit > 0:
            raise NpsimInputError(f"far limit must be > 0 m, got {self.far_limit}")
        if self.depth not in MESH_DEPTHS:
            raise NpsimInputError(f"mesh.depth must be one of {MESH_DEPTHS}, got {self.depth!r}")


#: How a night's exposure is chosen: metered by the camera, or ``night.exposure`` stops.
EXPOSURE_MODES = ("auto", "manual")


@dataclass(frozen=True)
class NightParams:
    """Night rendering and camera.

    seed : light activation and noise seed (night k of an export uses seed + k).
    spp : preview samples per pixel (a 4-spp first frame, then the rest).
    preview_scale : preview resolution as a fraction of the image.
    preview_max_depth : path length of the preview: 3 = one bounce (default since session 3: with
        OIDN, 4 spp of one bounce are as close to the reference as 16 of direct light), 2 = direct.
    final_spp : samples per pixel of exported nights (16 since session 3, docs/relight.md; 64
        before). With the multi-jittered sampler 12 would cost 3/4 of the render's CPU but is not as
        close to a 4096-spp reference after OIDN (2048x1024 crops, 3 seeds: RMSE 18.1 vs 17.1
        levels, SSIM 0.729 vs 0.730 for 16; ``benchmarks/render.py --frontier --samplers``). The
        multi-jittered sampler takes the product of two near-equal factors (14 -> 15 spp).
    final_max_depth : path length of exported nights: 3 = one bounce (default), 2 = direct
        light only (about half the time), 4 = two bounces.
    sampler : Mitsuba sampler of the nights, previews and guides (``scene_builder.SAMPLERS``):
        ``multijitter`` (the default: stratified samples, lower noise at the same spp
        than ``independent``, the sampler before; ``benchmarks/render.py --frontier --samplers``).
    integrator : path tracer of the nights and previews at max_depth 3 (``scene_builder.INTEGRATORS``):
        ``onebounce`` (default, ``render/integrator.py``: Mitsuba's path without its last BSDF ray,
        27 % less render CPU at 2048x1024, 16 spp; on the frontier crops within the seed spread
        of ``path``, docs/relight.md "One bounce without the last ray") or ``path`` (Mitsuba's).
    iso : camera noise preset (0 = no noise).
    exposure_mode : ``auto`` (default): the camera meters the lit pixels of the night (geometric
        mean of their luminance, light sources, sky and ego vehicle left out) and exposes them to
        ``exposure_target`` within [``exposure_min``, ``exposure_max``] stops; ``manual``: exactly
        ``exposure`` stops (docs/relight.md, "Exposure").
    exposure : stops; in ``auto`` mode an exposure compensation added to the metered value.
    exposure_target : linear level (1 = sensor white) the metered value is brought to. 0.027
        (0.029 before de-lighting became the default), fitted with ``white_balance``,
        ``tone_contrast`` and ``glare`` on four nights (SGM and exact depth, seeds 0 and 1 of the
        2048x1024 fixture, de-lit albedo; docs/relight.md "De-lit textures").
    exposure_min, exposure_max : the automatic exposure's range, stops.
    white_balance : the camera's automatic white balance, the part of the way (in log gain) from
        the render's own white toward neutralising the lit pixels' mean colour (0 = off, 1 = full
        grey world; :func:`~npsim_core.render.camera_post.auto_white_balance`). 0.3 (0.25 before
        de-lighting, whose warm façades raised the lit R/B): a camera under warm night light
        corrects it only partly (docs/relight.md "The camera of real night photos").
    tone_contrast : the camera's global tone curve, log-luminance slope around its mid-grey
        (1 = a linear sensor with the sRGB curve; :func:`~npsim_core.render.camera_post.tone_contrast`).
        0.73 with de-lit albedo (0.8 with the photo's fallback albedo, 0.9 before the glare;
        docs/relight.md "Glare", "De-lit textures"): de-lit white cars and pale façades are as
        bright as they are, and the camera holds them below the lamps.
    ego_headlights, group_all_together, noise : switches.
    probabilities : ((class_id, p), ...) overriding the light table's activation range with (p, p).
    denoise : remove the Monte Carlo noise before the camera noise (the on/off switch).
    denoiser : which denoiser when ``denoise`` is on: ``oidn`` (Intel Open Image Denoise with
        albedo and normal guides), ``guided`` (the à-trous filter guided by the mesh; strengths: the
        ``denoise`` section) or ``none``; :meth:`denoiser_used` is the one that runs.
    motion_blur_px : horizontal blur (px) of moving vehicles.
    bloom : glare around what exceeds sensor white, strength in [0, 1] (0 = off, the default;
        ``CameraParams.bloom``, docs/relight.md says why it is off).
    glare : share of all light the camera's lens and windscreen scatter over a long-tailed PSF
        (:func:`~npsim_core.render.camera_post.lens_glare`; 0 = off), with the heads of throwing
        lamps at their visible radiance: lamps get saturated halos larger than themselves, broad
        areas stay (docs/relight.md "Glare"). 0.2, fitted (0.1 with the fallback albedo): chosen
        and fitted, not measured on ACDC's camera (a lens alone scatters a few per cent; a car
        camera's windscreen adds to it).
    glare_radius : the glare PSF's core radius, fraction of the image width.
    light_table : a user light table JSON merged over the default ('' = the default).
    variant : Mitsuba variant ('' = probed: llvm_ad_rgb when usable, else scalar_rgb).
    delight : without albedo maps, estimate the day's sun and sky from the photo and the
        reconstructed geometry and divide them out of the photo
        (:func:`npsim_core.render.materials.delit_albedo`; on, the default since issue #25: on
        the 2048x1024 fixture from SGM geometry it halves the albedo error of photo-as-albedo on
        road, building and car); off = the per-class prior fallback (docs/relight.md "De-lit
        textures"). The manifest's ``nights[k].materials`` says which albedo a night used.
    """

    seed: int = 0
    spp: int = 16
    preview_scale: float = 0.5
    preview_max_depth: int = 3
    final_spp: int = 16
    final_max_depth: int = 3
    sampler: str = RENDER_SAMPLER
    integrator: str = "onebounce"
    iso: int = 1600
    exposure: float = 0.0
    exposure_mode: str = "auto"
    exposure_target: float = 0.027
    exposure_min: float = -3.0
    exposure_max: float = 4.0
    white_balance: float = 0.3
    tone_contrast: float = 0.73
    ego_headlights: bool = True
    group_all_together: bool = False
    noise: bool = True
    probabilities: tuple = ()
    denoise: bool = True
    denoiser: str = "oidn"
    motion_blur_px: int = 0
    bloom: float = 0.0
    glare: float = 0.2
    glare_radius: float = 0.0008
    light_table: str = ""
    variant: str = ""
    delight: bool = True

    def __post_init__(self) -> None:
        for name in ("final_max_depth", "preview_max_depth"):
            if int(getattr(self, name)) not in (2, 3, 4):
                raise NpsimInputError(f"night.{name} must be 2 (direct light), 3 (one bounce) or 4, "
                                      f"got {getattr(self, name)}")
        if int(self.spp) < 1 or int(self.final_spp) < 1:
            raise NpsimInputError(f"night.spp and night.final_spp must be >= 1, got {self.spp}, {self.final_spp}")
        if not 0 < float(self.preview_scale) <= 1:
            raise NpsimInputError(f"night.preview_scale must be in (0, 1], got {self.preview_scale}")
        if int(self.iso) < 0:
            raise NpsimInputError(f"night.iso must be >= 0 (0 = no noise), got {self.iso}")
        if int(self.motion_blur_px) < 0:
            raise NpsimInputError(f"night.motion_blur_px must be >= 0, got {self.motion_blur_px}")
        if not 0.0 <= float(self.bloom) <= 1.0:
            raise NpsimInputError(f"night.bloom must be in [0, 1] (0 = off), got {self.bloom}")
        if not (0.0 <= float(self.glare) <= 0.5 and 0.0 < float(self.glare_radius) <= 0.05):
            raise NpsimInputError(f"night.glare must be in [0, 0.5] (0 = off) and night.glare_radius in (0, 0.05] "
                                  f"image widths, got {self.glare}, {self.glare_radius}")
        if self.sampler not in SAMPLERS:
            raise NpsimInputError(f"night.sampler must be one of {', '.join(SAMPLERS)}, got {self.sampler!r}")
        if self.integrator not in INTEGRATORS:
            raise NpsimInputError(f"night.integrator must be one of {', '.join(INTEGRATORS)}, got {self.integrator!r}")
        if self.variant not in ("", "scalar_rgb", "llvm_ad_rgb"):
            raise NpsimInputError(f"night.variant must be '', 'scalar_rgb' or 'llvm_ad_rgb', got {self.variant!r}")
        if self.exposure_mode not in EXPOSURE_MODES:
            raise NpsimInputError(f"night.exposure_mode must be one of {', '.join(EXPOSURE_MODES)}, "
                                  f"got {self.exposure_mode!r}")
        if not (math.isfinite(float(self.exposure_min)) and math.isfinite(float(self.exposure_max))
                and float(self.exposure_min) <= float(self.exposure_max)):
            raise NpsimInputError(f"night.exposure_min must be <= night.exposure_max (finite stops), got "
                                  f"{self.exposure_min}, {self.exposure_max}")
        if not (math.isfinite(float(self.exposure_target)) and float(self.exposure_target) > 0):
            raise NpsimInputError(f"night.exposure_target must be a positive linear level, got {self.exposure_target}")
        if not 0.0 <= float(self.white_balance) <= 1.0:
            raise NpsimInputError(f"night.white_balance must be in [0, 1] (0 = off, 1 = full grey world), got "
                                  f"{self.white_balance}")
        if not 0.3 <= float(self.tone_contrast) <= 1.5:
            raise NpsimInputError(f"night.tone_contrast must be in [0.3, 1.5] (1 = off), got {self.tone_contrast}")
        if self.denoiser is None:  # ``--set night.denoiser=none`` parses as JSON null
            object.__setattr__(self, "denoiser", "none")
        if self.denoiser not in DENOISERS:
            raise NpsimInputError(f"night.denoiser must be one of {', '.join(DENOISERS)}, got {self.denoiser!r}")

    def probability(self, class_id: int) -> float | None:
        return dict(self.probabilities).get(int(class_id))

    @property
    def denoiser_used(self) -> str:
        """The denoiser that runs: ``denoiser``, or ``none`` when ``denoise`` is off."""
        return self.denoiser if self.denoise else "none"


EXPORT_MESHES = ("reduced", "full", "both", "none")


@dataclass(frozen=True)
class ExportParams:
    """What an export writes for a frame (docs/design.md; README "Files and formats").

    mesh : ``reduced`` (default): the quadtree mesh whose merged cells stay within
        ``mesh_tolerance`` (relative) of the full mesh's depth, as ``<name>_mesh.<fmt>``;
        ``full``: the chain's mesh as ``<name>_mesh.<fmt>``; ``both``: the reduced one plus
        ``<name>_mesh_full.<fmt>``; ``none``.
    mesh_formats : subset of ply, obj, glb.
    extras : also the 16-bit depth and normal PNGs, the normals as ``.npy`` and each night's
        linear render ``<name>_night_<k>_linear.npy`` (float32: 24 MB a night at 2048x1024).
    """

    mesh: str = "reduced"
    mesh_tolerance: float = 0.01
    mesh_formats: tuple = ("glb",)
    extras: bool = False

    def __post_init__(self) -> None:
        if self.mesh not in EXPORT_MESHES:
            raise NpsimInputError(f"export.mesh must be one of {', '.join(EXPORT_MESHES)}, got {self.mesh!r}")
        if not 0 < float(self.mesh_tolerance) < 1:
            raise NpsimInputError(f"export.mesh_tolerance must be in (0, 1), got {self.mesh_tolerance}")
        from ..mesh.export import FORMATS

        bad = [f for f in self.mesh_formats if f not in FORMATS]
        if bad or not self.mesh_formats:
            raise NpsimInputError(f"export.mesh_formats: unknown {bad or 'empty'}; choose from {', '.join(FORMATS)}")




@dataclass(frozen=True)
class LightsParams:
    """The inactive light sources a frame's nights switch on.

    source : ``auto`` (default) uses the frame's hand annotation when it has one, else the
        automatic proposals (:mod:`npsim_core.proposals`); ``annotation`` only the hand annotation
        (none = only the ego headlights and the sky light the night); ``proposed`` always the
        proposals; ``none`` no light sources; ``file`` the annotation in ``file``.
    file : a light annotation (the editor's ``<name>_lights.json`` or a COCO JSON) for ``file``.
    min_confidence : proposals below this confidence in [0, 1] are not used.
    """

    source: str = "auto"
    file: str = ""
    min_confidence: float = 0.5

    def __post_init__(self) -> None:
        if self.source not in LIGHT_SOURCES:
            raise NpsimInputError(f"lights.source must be one of {', '.join(LIGHT_SOURCES)}, got {self.source!r}")
        if not 0.0 <= float(self.min_confidence) <= 1.0:
            raise NpsimInputError(f"lights.min_confidence must be in [0, 1], got {self.min_confidence}")


@dataclass(frozen=True)
class ChainParams:
    """Every parameter of the chain, one frozen section per stage."""

    camera: CameraSetup = CameraSetup()
    depth: DepthSource = DepthSource()
    filter: FilterParams = FilterParams()
    uncertainty: UncertaintyParams = UncertaintyParams()
    refine: RefineParams = RefineParams()
    mesh: MeshParams = MeshParams()
    postprocess: PostprocessParams = PostprocessParams()
    night: NightParams = NightParams()
    denoise: DenoiseParams = DenoiseParams()
    export: ExportParams = ExportParams()
    lights: LightsParams = LightsParams()

    # ------------------------------------------------------------------ edits
    def with_value(self, section: str, name: str, value: Any) -> "ChainParams":
        """A copy with ``section.name`` set to ``value`` (errors name the field and the fix)."""
        if section not in {f.name for f in fields(self)}:
            raise NpsimInputError(f"unknown parameter section {section!r}; sections are "
                                  f"{', '.join(f.name for f in fields(self))}")
        sec = getattr(self, section)
        names = {f.name for f in fields(sec)}
        if name not in names:
            raise NpsimInputError(f"unknown parameter {section}.{name}; {section} has {', '.join(sorted(names))}")
        cur = getattr(sec, name)
        if isinstance(value, float) and not math.isfinite(value) and not (math.isinf(value) and (section, name)
                                                                          in INFINITE_OK):
            raise NpsimInputError(f"bad value {value!r} for {section}.{name}: must be a finite number")
        if isinstance(cur, tuple) and isinstance(value, list):
            value = tuple(tuple(x) if isinstance(x, list) else x for x in value)
        elif isinstance(cur, frozenset) and isinstance(value, (list, tuple, set)):
            value = frozenset(value)
        try:
            return replace(self, **{section: replace(sec, **{name: value})})
        except (TypeError, ValueError) as exc:
            raise NpsimInputError(f"bad value {value!r} for {section}.{name}: {exc}") from None

    def with_lambdas(self, l1: float, l2: float, l3: float) -> "ChainParams":
        """The refinement's loss weights λ1 (normal), λ2 (continuity), λ3 (depth)."""
        return replace(self, refine=replace(self.refine, lambdas=(float(l1), float(l2), float(l3))))

    def with_preset(self, name: str) -> "ChainParams":
        """A named λ preset (``appendix_b`` or ``section_3_4_3``, docs/method.md)."""
        if name not in PRESETS:
            raise NpsimInputError(f"unknown λ preset {name!r}; choose one of {sorted(PRESETS)}")
        return replace(self, refine=replace(self.refine, lambdas=PRESETS[name]))

    def with_sets(self, items: list[str], source: str = "--set") -> "ChainParams":
        """Apply ``SECTION.FIELD=VALUE`` strings (values: JSON, or a bare string)."""
        out = self
        for item in items:
            if "=" not in item or "." not in item.split("=", 1)[0]:
                raise NpsimInputError(f"{source} {item!r}: use SECTION.FIELD=VALUE, e.g. refine.n_steps=200")
            key, raw = item.split("=", 1)
            section, name = key.strip().split(".", 1)
            out = out.with_value(section, name, parse_value(raw))
        return out

    # ------------------------------------------------------------------ JSON
    def to_json(self) -> dict:
        d = {}
        for f in fields(self):
            sec = asdict(getattr(self, f.name))
            for k, v in list(sec.items()):
                if isinstance(v, (set, frozenset)):
                    sec[k] = sorted(v)
            d[f.name] = sec
        return d

    @classmethod
    def from_json(cls, doc: Any, source: str = "parameters") -> "ChainParams":
        """Parameters from a JSON object; unknown sections or fields are errors naming ``source``."""
        if not isinstance(doc, dict):
            raise NpsimInputError(f"{source}: parameters must be a JSON object of sections "
                                  f"({', '.join(f.name for f in fields(cls))}), got {type(doc).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(doc) - known)
        if unknown:
            raise NpsimInputError(f"{source}: unknown parameter sections {unknown}; known: {sorted(known)}")
        out = cls()
        for section, values in doc.items():
            if not isinstance(values, dict):
                raise NpsimInputError(f"{source}: section '{section}' must be a JSON object, "
                                      f"got {type(values).__name__}")
            for name, v in values.items():
                try:
                    out = out.with_value(section, name, v)
                except NpsimInputError as exc:
                    raise NpsimInputError(f"{source}: {exc}") from None
        return out


def parse_value(raw: str) -> Any:
    """A ``--set`` value: JSON (numbers, true/false, null, lists, quoted strings), else a float
    (``inf``), else the raw string. ``none`` is accepted for null."""
    text = raw.strip()
    if text.lower() == "none":
        return None
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    try:
        return json.loads(text)
    except ValueError:
        pass
    try:
        return float(text)  # inf, nan, 1e-3
    except ValueError:
        return text


#: The ``denoise`` fields each denoiser reads (docs/relight.md; :func:`npsim_core.render.denoise.denoise_night`).
DENOISER_FIELDS: dict[str, tuple[str, ...]] = {
    "guided": ("iterations", "sigma_depth", "sigma_normal", "sigma_luminance", "min_albedo", "firefly_ratio",
               "firefly_floor"),
    "oidn": ("oidn_quality", "oidn_max_memory_mb"),
    "none": ("firefly_ratio", "firefly_floor"),
}


def unread_fields(params: ChainParams) -> dict[tuple[str, str], str]:
    """The fields the chosen optimiser, denoiser, source or mode of ``params`` does not read:
    (section, field) -> a sentence naming what reads it and the choice that would (a
    ``--set refine.lr=10`` with the default Gauss-Newton solver changed nothing and said nothing)."""
    out: dict[tuple[str, str], str] = {}
    opt = params.refine.optimizer
    for name, readers in OPTIMIZER_FIELDS.items():
        if opt not in readers:
            out[("refine", name)] = (f"refine.{name} is read only by the {' and '.join(readers)} optimizer"
                                     f"{'s' if len(readers) > 1 else ''}, and refine.optimizer is {opt!r} "
                                     f"(--set refine.optimizer={readers[0]})")
    used = params.night.denoiser_used
    for name in (f.name for f in fields(DenoiseParams)):
        if name not in DENOISER_FIELDS[used]:
            readers = [d for d, names in DENOISER_FIELDS.items() if name in names]
            why = "night.denoise is off" if not params.night.denoise else f"night.denoiser is {used!r}"
            out[("denoise", name)] = (f"denoise.{name} is read only by the {' and '.join(readers)} denoiser"
                                      f"{'s' if len(readers) > 1 else ''}, and {why} (--denoiser {readers[0]})")
    if params.night.exposure_mode == "manual":
        for name in ("exposure_target", "exposure_min", "exposure_max"):
            out[("night", name)] = (f"night.{name} is read only by the automatic exposure, and "
                                    "night.exposure_mode is 'manual' (--exposure-mode auto)")
    src = params.depth.source
    if src not in ("auto", "network"):
        out[("depth", "checkpoint")] = (f"depth.checkpoint is read only by the network depth source, and "
                                        f"depth.source is {src!r} (--depth network or auto)")
    if src not in ("auto", "stereo"):
        out[("depth", "stereo_max_m")] = (f"depth.stereo_max_m is read only by the stereo depth source (and "
                                          f"scoring against stereo), and depth.source is {src!r}")
        for name in ("stereo_holdout", "stereo_surfaces"):
            out[("depth", name)] = (f"depth.{name} is read only by the stereo depth source, and depth.source is "
                                    f"{src!r} (--depth stereo or auto)")
    ls = params.lights.source
    if ls != "file":
        out[("lights", "file")] = f"lights.file is read only by lights.source 'file', and it is {ls!r} (--lights FILE)"
    if ls not in ("auto", "proposed"):
        out[("lights", "min_confidence")] = (f"lights.min_confidence is read only for proposed lights, and "
                                             f"lights.source is {ls!r} (--lights auto or proposed)")
    if params.export.mesh not in ("reduced", "both"):
        out[("export", "mesh_tolerance")] = (f"export.mesh_tolerance is read only for a reduced mesh export, and "
                                             f"export.mesh is {params.export.mesh!r}")
    if params.mesh.render_tolerance and (params.mesh.face_budget or not params.mesh.postprocess):
        out[("mesh", "render_tolerance")] = ("mesh.render_tolerance is not applied when mesh.face_budget already "
                                             "reduced the mesh or without post-processing (mesh.postprocess)")
    return out


def set_fields(items: list[str]) -> list[tuple[str, str]]:
    """(section, field) of ``--set SECTION.FIELD=VALUE`` strings (malformed ones are left out)."""
    out = []
    for item in items:
        key = item.split("=", 1)[0].strip()
        if "=" in item and "." in key:
            section, name = key.split(".", 1)
            out.append((section.strip(), name.strip()))
    return out


def changed_fields(params: ChainParams, base: ChainParams | None = None) -> list[tuple[str, str]]:
    """(section, field) whose value in ``params`` differs from ``base`` (default: the defaults)."""
    a, b = params.to_json(), (base or ChainParams()).to_json()
    return [(sec, name) for sec, vals in a.items() for name, v in vals.items() if v != b[sec].get(name)]
