# SPDX-License-Identifier: Apache-2.0
"""Drawing the Rendered viewport: the latest completed pass as a GPU texture.

Renderer.snapshot() hands over the film as of the last *completed* sample
pass, so a drawn frame is never torn. A restarted render never shows the
previous image (which would be stale): the session waits up to
FIRST_FRAME_WAIT for the new coarse pass instead. While a render refines, a
one-shot timer asks for the next redraw; once the last sample is drawn no
timer is left.
"""

from __future__ import annotations

import time
import weakref

import bpy

# Seconds between redraws while a viewport render is refining.
REDRAW_INTERVAL = 0.05
# Seconds draw() waits for a restarted render's first pass.
FIRST_FRAME_WAIT = 0.2


def tag_rendered_views():
    """Asks every 3D View in Rendered shading for a redraw (main thread)."""
    wm = bpy.context.window_manager
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D" and area.spaces.active.shading.type == "RENDERED":
                area.tag_redraw()


class ViewportDisplay:
    """The texture a viewport shows and the redraws that keep it current (main thread)."""

    def __init__(self):
        self.texture = None
        self.texture_stamp = None     # (view_key, stage, samples) of the texture
        self.texture_current = False  # the texture shows the current scene and view
        self._redraw_pending = False

    def invalidate(self):
        """A restart: the old image must not be shown any more."""
        self.texture_current = False

    def free(self):
        self.texture = None
        self.texture_current = False

    def upload(self, render, wait=0.0):
        """Uploads `render`'s latest completed pass as the texture, waiting up to
        `wait` s for a first one; True if this made the texture current again
        (the restart's first frame)."""
        import gpu

        renderer = render.renderer
        if renderer is None:
            return False
        deadline = time.perf_counter() + wait
        while True:
            samples, pixels = renderer.snapshot()
            if pixels is not None or time.perf_counter() >= deadline or not renderer.running:
                break
            time.sleep(0.002)  # releases the GIL; the render thread never needs it anyway
        if pixels is None:
            return False
        stamp = (render.view_key, render.stage, samples)
        if stamp == self.texture_stamp:
            return False
        buffer = gpu.types.Buffer("FLOAT", pixels.size, pixels)
        self.texture = gpu.types.GPUTexture((renderer.film_width, renderer.film_height), format="RGBA16F",
                                            data=buffer)
        self.texture_stamp = stamp
        if self.texture_current:
            return False
        self.texture_current = True
        return True

    def shows(self, render, samples):
        """Whether the texture is `render`'s current stage at `samples` samples."""
        return self.texture_stamp == (render.view_key, render.stage, samples)

    def draw(self, engine, scene, region):
        """Draws the texture over the region, if it shows the current scene and view."""
        import gpu
        from gpu_extras.presets import draw_texture_2d

        if self.texture is None or not self.texture_current:
            return
        gpu.state.blend_set("ALPHA_PREMULT")
        engine.bind_display_space_shader(scene)
        draw_texture_2d(self.texture, (0, 0), region.width, region.height)
        engine.unbind_display_space_shader()
        gpu.state.blend_set("NONE")

    def schedule_redraw(self, render):
        """Asks for a redraw in REDRAW_INTERVAL s if `render` is still running then."""
        if self._redraw_pending:
            return
        self._redraw_pending = True
        # The timer must not keep a closed viewport's session alive.
        display_ref, render_ref = weakref.ref(self), weakref.ref(render)

        def redraw():
            display, render = display_ref(), render_ref()
            if display is None or render is None:
                return None
            display._redraw_pending = False
            if render.renderer is not None:
                tag_rendered_views()
            return None  # one-shot: draw() re-arms it while the render refines

        bpy.app.timers.register(redraw, first_interval=REDRAW_INTERVAL)
