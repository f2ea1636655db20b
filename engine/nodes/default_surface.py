"""What Cycles renders on an object without a material: its default surface, a Principled BSDF
at the node's own defaults (the same image as a new material's node tree), not a plain grey
diffuse. The inputs are Blender 5.0's defaults by socket identifier;
tests/test_export_material.py checks them against a Principled node made in bpy."""
from __future__ import annotations

from .graph import Graph, Input, Link, Node

PRINCIPLED_DEFAULTS = (
    ("Base Color", "rgba", (0.8, 0.8, 0.8)),
    ("Metallic", "value", 0.0),
    ("Roughness", "value", 0.5),
    ("IOR", "value", 1.5),
    ("Alpha", "value", 1.0),
    ("Normal", "vector", (0.0, 0.0, 0.0)),
    ("Weight", "value", 0.0),
    ("Diffuse Roughness", "value", 0.0),
    ("Subsurface Weight", "value", 0.0),
    ("Subsurface Radius", "vector", (1.0, 0.2, 0.1)),
    ("Subsurface Scale", "value", 0.05),
    ("Subsurface IOR", "value", 1.4),
    ("Subsurface Anisotropy", "value", 0.0),
    ("Specular IOR Level", "value", 0.5),
    ("Specular Tint", "rgba", (1.0, 1.0, 1.0)),
    ("Anisotropic", "value", 0.0),
    ("Anisotropic Rotation", "value", 0.0),
    ("Tangent", "vector", (0.0, 0.0, 0.0)),
    ("Transmission Weight", "value", 0.0),
    ("Coat Weight", "value", 0.0),
    ("Coat Roughness", "value", 0.03),
    ("Coat IOR", "value", 1.5),
    ("Coat Tint", "rgba", (1.0, 1.0, 1.0)),
    ("Coat Normal", "vector", (0.0, 0.0, 0.0)),
    ("Sheen Weight", "value", 0.0),
    ("Sheen Roughness", "value", 0.5),
    ("Sheen Tint", "rgba", (1.0, 1.0, 1.0)),
    ("Emission Color", "rgba", (1.0, 1.0, 1.0)),
    ("Emission Strength", "value", 0.0),
    ("Thin Film Thickness", "value", 0.0),
    ("Thin Film IOR", "value", 1.33),
)
PRINCIPLED_PROPS = (("distribution", "MULTI_GGX"), ("subsurface_method", "RANDOM_WALK"))


def default_surface() -> Graph:
    """The graph of Cycles' default surface: Principled BSDF -> Surface."""
    node = Node("ShaderNodeBsdfPrincipled", "Principled BSDF", PRINCIPLED_PROPS,
                tuple(Input(name, kind, value) for name, kind, value in PRINCIPLED_DEFAULTS), (("BSDF", "shader"),))
    return Graph((node,), (("surface", Input("Surface", "shader", 0.0, Link(0, "BSDF", "shader"))),))
