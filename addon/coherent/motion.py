"""Object motion blur: object transforms at shutter open and close.

Blender's Render Properties > Motion Blur: `render.use_motion_blur`,
`render.motion_blur_shutter` (in frames) and `render.motion_blur_position`
(shutter centred on the frame, starting or ending at it). Like Cycles, the
final render re-evaluates the depsgraph at the shutter's two ends with
RenderEngine.frame_set() and records each mesh instance's world matrix; an
instance whose matrix differs between the two moves linearly from one to the
other during the shutter (the native Scene's matrix / matrix_close). Objects
that stand still cost nothing: the engine only builds motion data, and only
draws ray times, when something moves.

Supported: transform motion of objects and their instances (location,
rotation, scale, parenting, constraints). Not supported: deformation motion
(armatures, shape keys, modifiers) and camera motion; the scene is exported
at the current frame for those.

The Vector pass (frame_matrices) reads the same transforms, and the
camera's, one frame before and one after the current one, as Cycles does
for its motion pass. Cycles has that pass only with motion blur off (its
Passes panel greys the tick out otherwise); we fill it either way, the hit
point then being the one seen at the sample's shutter time.
"""
import math

import numpy as np


def shutter_times(render, frame, subframe=0.0):
    """(open, close) scene times in frames for this render's shutter."""
    shutter = max(float(render.motion_blur_shutter), 0.0)
    now = frame + subframe
    position = getattr(render, "motion_blur_position", "CENTER")
    if position == "START":
        return now, now + shutter
    if position == "END":
        return now - shutter, now
    return now - 0.5 * shutter, now + 0.5 * shutter


def instance_key(inst, ob):
    """Identifies one mesh instance across depsgraph evaluations."""
    if inst is not None and inst.is_instance:
        parent = inst.parent.original.name if inst.parent is not None else ""
        return (ob.original.name, parent, tuple(inst.persistent_id))
    return (ob.original.name, "", ())


def _matrices(depsgraph, mesh_types):
    out = {}
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type in mesh_types:
            out[instance_key(inst, ob)] = np.array(inst.matrix_world, dtype=np.float32)
    return out


def _camera_matrix(depsgraph, camera):
    return None if camera is None else np.array(camera.evaluated_get(depsgraph).matrix_world, dtype=np.float32)


def frame_matrices(engine, depsgraph, mesh_types, camera):
    """The Vector pass's motion: ({instance key: (matrix_previous,
    matrix_next)} for the instances whose transform differs one frame
    before or after the current one, and (camera_previous, camera_next), or
    None when `camera` (an object, or None) stands still.

    Leaves the depsgraph evaluated at the current frame again.
    """
    scene = depsgraph.scene
    frame, subframe = scene.frame_current, scene.frame_subframe
    camera = camera.original if camera is not None else None  # evaluated anew at each frame
    now = _matrices(depsgraph, mesh_types)
    camera_now = _camera_matrix(depsgraph, camera)
    try:
        _set_time(engine, frame + subframe - 1.0)
        previous, camera_previous = _matrices(depsgraph, mesh_types), _camera_matrix(depsgraph, camera)
        _set_time(engine, frame + subframe + 1.0)
        following, camera_next = _matrices(depsgraph, mesh_types), _camera_matrix(depsgraph, camera)
    finally:
        engine.frame_set(int(frame), float(subframe))
    moving = {}
    for key, matrix in now.items():
        # An instance missing one frame away is taken as still (Cycles: no motion data, no motion).
        before, after = previous.get(key, matrix), following.get(key, matrix)
        if not (np.array_equal(before, matrix) and np.array_equal(after, matrix)):
            moving[key] = (before, after)
    cameras = None
    if camera is not None and not (np.array_equal(camera_previous, camera_now)
                                   and np.array_equal(camera_next, camera_now)):
        cameras = (camera_previous, camera_next)
    return moving, cameras


def _set_time(engine, time):
    frame = math.floor(time)
    engine.frame_set(int(frame), float(time - frame))


def shutter_matrices(engine, depsgraph, mesh_types):
    """{instance key: (matrix_open, matrix_close)} for the instances that move
    during the shutter, or {} when motion blur is off or nothing moves.

    Leaves the depsgraph evaluated at the current frame again.
    """
    scene = depsgraph.scene
    render = scene.render
    if not render.use_motion_blur or not (render.motion_blur_shutter > 0.0):
        return {}
    frame, subframe = scene.frame_current, scene.frame_subframe
    t_open, t_close = shutter_times(render, frame, subframe)
    try:
        _set_time(engine, t_open)
        opened = _matrices(depsgraph, mesh_types)
        _set_time(engine, t_close)
        closed = _matrices(depsgraph, mesh_types)
    finally:
        engine.frame_set(int(frame), float(subframe))
    moving = {}
    for key, m_open in opened.items():
        m_close = closed.get(key)
        if m_close is not None and not np.array_equal(m_open, m_close):
            moving[key] = (m_open, m_close)
    return moving
