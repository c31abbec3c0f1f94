"""The Vector pass's inputs through the Python module: frame_matrices of
add_mesh / add_instances and set_camera_frames are checked and named, and
the same placements with the same motion one frame away (rotations, scales,
mirrors) give the same vectors whether the mesh is placed as instances or
as world-space triangles."""

import numpy as np
import pytest

from native_module import native
from test_module_instances import OCTA_I, OCTA_P, base_scene, placements


def test_frame_inputs_are_checked_and_named():
    s = base_scene()
    with pytest.raises(ValueError, match="frame_matrices"):
        s.add_mesh("octa", OCTA_P, OCTA_I, np.eye(4), frame_matrices=np.zeros((3, 4, 4)))
    bad = np.stack([np.eye(4), np.eye(4)]).astype(np.float32)
    bad[1, 0, 3] = np.nan
    with pytest.raises(ValueError, match="frame_matrices"):
        s.add_mesh("octa", OCTA_P, OCTA_I, np.eye(4), frame_matrices=bad)
    proto = s.add_prototype("octa", OCTA_P, OCTA_I)
    with pytest.raises(ValueError, match="frame_matrices"):
        s.add_instances(proto, placements(3), frame_matrices=np.zeros((2, 2, 4, 4)))
    with pytest.raises(ValueError, match="previous"):
        s.set_camera_frames(np.full((4, 4), np.inf), np.eye(4))


def test_instances_and_world_triangles_get_the_same_vectors():
    opens = placements(12, seed=3)
    rng = np.random.default_rng(5)
    frames = np.repeat(opens[:, None], 2, axis=1)
    for k in range(len(opens)):
        for f, sign in ((0, -1.0), (1, 1.0)):
            turn = np.eye(4, dtype=np.float32)
            c, s_ = np.cos(0.2 * sign), np.sin(0.2 * sign)
            turn[:2, :2] = [[c, -s_], [s_, c]]  # a turn about the world z axis ...
            turn[:3, 3] = sign * rng.uniform(-0.3, 0.3, 3)  # ... and a shift
            frames[k, f] = turn @ opens[k]
    instanced, flattened = base_scene(), base_scene()
    proto = instanced.add_prototype("octa", OCTA_P, OCTA_I)
    assert instanced.add_instances(proto, opens, frame_matrices=frames) == len(opens)
    for m, f in zip(opens, frames):
        flattened.add_mesh("octa", OCTA_P, OCTA_I, m, frame_matrices=f)
    camera = np.eye(4, dtype=np.float32)  # only its position and axes matter
    camera[:3, :3] = [[1, 0, 0], [0, 0.7071, -0.7071], [0, 0.7071, 0.7071]]  # columns: right, up, back
    camera[:3, 3] = (0.2, -6.0, 6.0)
    for s in (instanced, flattened):
        s.set_camera_frames(camera, camera)

    def vectors(scene):
        r = native.Renderer(scene, width=48, height=48, spp=1, traversal="single", sampler="spt", passes=["Vector"])
        r.render()
        return r.pass_pixels("Vector")

    a, b = vectors(instanced), vectors(flattened)
    moving = np.abs(b).max(axis=1) > 0.5
    assert moving.sum() > 100  # the octahedra move by pixels, the floor by the camera's 0.2
    # The same sample positions hit the same points up to float rounding of the two placements
    # (measured: 1.1e-5 pixels apart on vectors of up to 9.5 pixels).
    assert np.abs(a - b).max() < 1e-2, np.abs(a - b).max()
