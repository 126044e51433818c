"""Inside-out closed objects (core/scene/orientation.py): the signed volume of shapes with a
known volume, closedness, and the objects named."""

import numpy as np
import pytest

from core.scene import orientation, shapes


def flipped(part):
    return shapes.Part(part.corners[:, ::-1], -part.normals)


def test_signed_volume_of_a_box_and_a_sphere():
    box = shapes.box([0, 0, 0], [1, 2, 3])
    sphere = shapes.uv_sphere([5, 0, 0], 1.0, rings=64, segments=128)
    mesh = shapes.assemble([(box, 0), (sphere, 0), (flipped(box), 0)])
    v = orientation.signed_volumes(mesh, 3)
    assert v[0] == pytest.approx(6.0, rel=1e-6)
    assert v[1] == pytest.approx(4 / 3 * np.pi, rel=2e-3)  # the polygon's volume, below the sphere's
    assert v[1] < 4 / 3 * np.pi
    assert v[2] == pytest.approx(-6.0, rel=1e-6)


def test_far_from_the_origin_keeps_the_sign():
    box = shapes.transform(shapes.box([0, 0, 0], [0.01, 0.01, 0.01]), offset=(1e5, 0, 0))
    v = orientation.signed_volumes(shapes.assemble([(box, 0), (flipped(box), 0)]), 2)
    assert v[0] > 0 > v[1]


def test_open_or_inconsistent_surfaces_are_not_closed():
    box = shapes.box([0, 0, 0], [1, 1, 1])
    open_box = shapes.Part(box.corners[2:], box.normals[2:])  # one face (two triangles) gone
    mixed = shapes.Part(np.concatenate([box.corners[:2, ::-1], box.corners[2:]]),
                        box.normals)  # one face wound the other way
    plane = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    sphere = shapes.uv_sphere([3, 0, 0], 1.0)  # split at its seam: matched by position
    mesh = shapes.assemble([(box, 0), (open_box, 0), (mixed, 0), (plane, 0), (sphere, 0)])
    assert orientation.closed_objects(mesh, 5).tolist() == [True, False, False, False, True]


def test_only_closed_inward_objects_among_the_chosen_triangles_are_named():
    glass_in = flipped(shapes.uv_sphere([0, 0, 0], 0.5))
    glass_out = shapes.uv_sphere([2, 0, 0], 0.5)
    room = shapes.box([-5, -5, -5], [5, 5, 5], inward=True)  # inside out too, but not glass
    plane = flipped(shapes.quad([0, 0, -1], [1, 0, 0], [0, 1, 0]))  # open
    mesh = shapes.assemble([(glass_in, 1), (glass_out, 1), (room, 0), (plane, 1)],
                           names=("Glass", "Good glass", "Room", "Pane"))
    glass = mesh.material_index == 1
    assert orientation.inside_out(mesh, glass) == [0]
    assert orientation.inside_out(mesh, ~glass) == [2]
    assert orientation.inside_out(mesh, np.zeros(mesh.triangle_count, bool)) == []
