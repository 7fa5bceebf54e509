"""Modelling: parametric primitives (and, beside them, the scene graph in ``scene``)."""

from .mesh import Mesh
from .primitives import (
    PRIMITIVE_TYPES,
    Box,
    Cylinder,
    Frame,
    Frustum,
    Primitive,
    Quad,
    Sphere,
    Wedge,
    primitive_from_dict,
)
from .room import Room  # registers the room type (it builds on the primitives above)

__all__ = [
    "PRIMITIVE_TYPES",
    "Box",
    "Cylinder",
    "Frame",
    "Frustum",
    "Mesh",
    "Primitive",
    "Quad",
    "Room",
    "Sphere",
    "Wedge",
    "primitive_from_dict",
]
