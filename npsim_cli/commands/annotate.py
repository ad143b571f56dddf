"""``npsim annotate PATH``: open the light-source annotation editor.

PATH is a scene folder, a folder of scene folders, a folder of images (with
optional ``*_labelIds.png`` pairs) or one image. Annotation files are written
next to each image (see ``npsim_core.annotation``).
"""

from __future__ import annotations

import argparse
import importlib


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("annotate", help="label inactive light sources in an editor (GUI)")
    p.add_argument("path", help="scene folder, folder of scene folders / images, or one image")
    p.add_argument("--autosave-ms", type=int, default=2000,
                   help="write the recovery file this long after the last edit (default 2000)")
    p.add_argument("--list", action="store_true", help="only list the images found and their done flags")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from npsim_core.annotation import discover_items

    items = discover_items(args.path)  # raises NpsimInputError before any window opens
    if args.list:
        for it in items:
            flag = "done" if it.is_done() else ("started" if it.has_annotation() else "-")
            print(f"{it.name}\t{flag}\t{it.image_path}")
        return 0
    # The GUI is loaded only when the command runs: the other commands never import Qt.
    if not importlib.import_module("npsim_gui.app").has_display():
        from npsim_core.errors import NpsimInputError

        raise NpsimInputError("no display to open the editor on (DISPLAY is not set): run it on a desktop or "
                              "under 'xvfb-run -a npsim annotate …'; 'npsim annotate PATH --list' works without one")
    editor = importlib.import_module("npsim_gui.editor")
    return int(editor.main(args.path, autosave_ms=args.autosave_ms))
