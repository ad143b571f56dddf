"""The one chain every entry point goes through: the app, every command, batch and sweep.

* :mod:`.params`  -- every parameter, one frozen section per stage; presets; JSON.
* :mod:`.stages`  -- the stages, each a pure function with its parameters and result.
* :mod:`.engine`  -- the staged cache: keys, invalidation by parameter, cancel, progress, timings.
* :mod:`.chain`   -- :class:`Chain`, one frame's stages plus the per-night steps.
* :mod:`.session` -- one loader for every input source (scene, project, dataset image, dataset root).
* :mod:`.export`  -- one writer for every output kind, nights included, and the manifest.
"""

from .chain import DEPTH_STAGES, Chain, ChainResults, NightFrame
from .export import EXPORT_KINDS, check_output_folder, export_frame, frame_errors, verify_frame
from .params import CameraSetup, ChainParams, MeshParams, NightParams
from .session import FrameSource, iter_frames, load_frame, scaled_frame

__all__ = ["Chain", "ChainResults", "NightFrame", "DEPTH_STAGES", "ChainParams", "CameraSetup", "MeshParams",
           "NightParams", "EXPORT_KINDS", "export_frame", "frame_errors", "check_output_folder", "verify_frame", "FrameSource", "iter_frames", "load_frame",
           "scaled_frame"]
