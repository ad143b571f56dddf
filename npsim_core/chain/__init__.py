"""The one chain every entry point goes through: the app, every command, batch and sweep.

* :mod:`.params`  -- every parameter, one frozen section per stage; presets; JSON.
* :mod:`.stages`  -- the stages, each a pure function with its parameters and result.
* :mod:`.engine`  -- the staged cache: keys, invalidation by parameter, cancel, progress, timings.
* :mod:`.chain`   -- :class:`Chain`, one frame's stages plus the per-night steps.
* :mod:`.session` -- one loader for every input source (scene, project, dataset image, dataset root).
* :mod:`.export`  -- one writer for every output kind, nights included, and the manifest.
"""

from ..lazy import lazy_exports

#: Public names and their modules, imported on first use (PEP 562): the command line imports
#: ``.params`` to build its parser and must not pay for the stages' imports.
_EXPORTS = {"Chain": "chain", "ChainResults": "chain", "NightFrame": "chain", "DEPTH_STAGES": "chain",
            "EXPORT_KINDS": "export", "check_output_folder": "export", "export_frame": "export",
            "frame_errors": "export", "verify_frame": "export", "ChainParams": "params", "CameraSetup": "params",
            "MeshParams": "params", "NightParams": "params", "FrameSource": "session", "iter_frames": "session",
            "load_frame": "session", "scaled_frame": "session"}
__all__ = list(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
