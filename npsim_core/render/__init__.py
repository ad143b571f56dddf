"""Nighttime relighting (docs/method.md §6): light table and activation, materials, Mitsuba scene, rendering, camera.

Typical use::

    table = load_light_table()
    mats = estimate_materials(scene.image, scene.labels, albedo=scene.albedo, roughness=scene.roughness,
                              light_classes=scene.lights.class_map())
    built = build_scene(mesh, scene.intrinsics, mats, table, scene.lights)
    for seed in range(3):
        built.apply_lights(activate_lights(scene.lights, table, seed, image=scene.image))  # in place
        srgb, _ = apply_camera(render_final(built, spp=64, seed=seed), CameraParams(seed=seed))

Mitsuba is imported lazily (only by the builder/renderer), so importing this
package is cheap and never touches LLVM.
"""

from .camera_post import CameraParams, ISO_PRESETS, apply_camera, add_noise, iso_noise, linear_to_srgb
from .lights import (ActiveLights, LightState, LightTable, activate_lights, cct_to_chromaticity, load_light_table)
from .materials import MaterialParams, Materials, estimate_materials
from .render import PreviewFrame, PreviewParams, render_final, render_labels, render_linear, render_preview
from .scene_builder import BuildParams, BuiltScene, build_label_scene, build_scene, camera_dict
from .variant import VariantChoice, choose_variant, resolve_variant

__all__ = ["CameraParams", "ISO_PRESETS", "apply_camera", "add_noise", "iso_noise", "linear_to_srgb",
           "ActiveLights", "LightState", "LightTable", "activate_lights", "cct_to_chromaticity", "load_light_table",
           "MaterialParams", "Materials", "estimate_materials", "PreviewFrame", "PreviewParams", "render_final",
           "render_labels", "render_linear", "render_preview", "BuildParams", "BuiltScene", "build_label_scene",
           "build_scene", "camera_dict", "VariantChoice", "choose_variant", "resolve_variant"]
