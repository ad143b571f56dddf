"""NPSim core library: day image + labels -> 3D scene mesh -> nighttime renders.

No Qt is imported anywhere in this package (a test enforces it). Conventions
(docs/method.md §1): OpenCV camera frame (x right, y down, z forward), z-depth in metres
as float32 HxW, pixel (u, v) = (column, row) with centres at integer
coordinates, unit normals pointing toward the camera, Cityscapes labelIds.
"""

__version__ = "0.1.0"
