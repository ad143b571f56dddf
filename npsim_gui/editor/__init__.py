"""Light-source annotation editor (docs/method.md §7, docs/annotation.md): canvas, tools, palette, instance list, window.

``AnnotationEditor`` is the embeddable widget (canvas + side panels; ``canvas``
is the ``EditorCanvas`` with ``set_base_image``); ``EditorWindow`` wraps it with
files, autosave, recovery and image stepping; ``main(path)`` runs it.
"""

from .canvas import ArrayLayerItem, EditorCanvas
from .editor import AnnotationEditor
from .session import EditorSession
from .tools import Tool, ToolController, ToolOptions
from .window import EditorWindow, main

__all__ = ["AnnotationEditor", "ArrayLayerItem", "EditorCanvas", "EditorSession", "EditorWindow", "Tool",
           "ToolController", "ToolOptions", "main"]
