"""Lightings beyond one point light (torch-free): point, directional, area lights and environment
maps, their JSON files, and the point and directional lights that stand for them
(docs/relighting.md)."""

from olatbench.datasets.lighting.envmap import BUILT_IN_MAPS, load_map, sample_map
from olatbench.datasets.lighting.files import (
    environment_lighting,
    lighting_from_dict,
    lighting_to_dict,
    read_lighting,
    write_lighting,
)
from olatbench.datasets.lighting.sources import (
    DirectionalLight,
    EnvironmentMap,
    Lighting,
    LightSource,
    RectLight,
    SampledLights,
    SphereLight,
)

__all__ = [
    "BUILT_IN_MAPS",
    "DirectionalLight",
    "EnvironmentMap",
    "LightSource",
    "Lighting",
    "RectLight",
    "SampledLights",
    "SphereLight",
    "environment_lighting",
    "lighting_from_dict",
    "lighting_to_dict",
    "load_map",
    "read_lighting",
    "sample_map",
    "write_lighting",
]
