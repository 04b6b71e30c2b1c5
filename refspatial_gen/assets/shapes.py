"""Procedural object geometry: the builder of each shape kind, by name (catalog entries name them).

The parts and the primitive helpers are in parts.py (why objects are built from convex pieces is told
there); the builders in shapes_containers.py (things that hold or pour) and shapes_objects.py (the rest).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from refspatial_gen.assets.parts import AssetGeometry, Dims, Part, matrix_from_quat, quat_from_matrix, rot_axis
from refspatial_gen.assets.shapes_containers import (
    build_book,
    build_bottle,
    build_box,
    build_can,
    build_carton,
    build_cylinder,
    build_mug,
    build_open_box,
    build_plate,
    build_spouted,
    build_spray,
    build_vase,
    build_vessel,
    build_wineglass,
)
from refspatial_gen.assets.shapes_objects import (
    build_backpack,
    build_ball,
    build_banana,
    build_camera,
    build_chair,
    build_clock,
    build_duck,
    build_flat_device,
    build_frame,
    build_fruit,
    build_lamp,
    build_laptop,
    build_monitor,
    build_mouse,
    build_pen,
    build_plant,
    build_scissors,
    build_speaker,
    build_stapler,
    build_stool,
    build_teddy,
    build_toy_car,
)

__all__ = ["BUILDERS", "AssetGeometry", "Dims", "Part", "matrix_from_quat", "quat_from_matrix", "rot_axis"]

BUILDERS: dict[str, Callable[[Dims, np.random.Generator], AssetGeometry]] = {
    "box": build_box,
    "book": build_book,
    "open_box": build_open_box,
    "cylinder": build_cylinder,
    "can": build_can,
    "bottle": build_bottle,
    "vase": build_vase,
    "vessel": build_vessel,
    "plate": build_plate,
    "mug": build_mug,
    "fruit": build_fruit,
    "ball": build_ball,
    "banana": build_banana,
    "laptop": build_laptop,
    "flat_device": build_flat_device,
    "pen": build_pen,
    "scissors": build_scissors,
    "spouted": build_spouted,
    "lamp": build_lamp,
    "chair": build_chair,
    "stool": build_stool,
    "monitor": build_monitor,
    "toy_car": build_toy_car,
    "duck": build_duck,
    "teddy": build_teddy,
    "frame": build_frame,
    "clock": build_clock,
    "speaker": build_speaker,
    "camera": build_camera,
    "stapler": build_stapler,
    "spray": build_spray,
    "plant": build_plant,
    "carton": build_carton,
    "backpack": build_backpack,
    "mouse": build_mouse,
    "wineglass": build_wineglass,
}
