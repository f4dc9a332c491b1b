"""pyrender plumbing: headless EGL, MSAA sample count, colour-only read-back, meshes whose
vertex buffer is rewritten in place every frame.

pyrender 0.1.45 re-uploads a mesh only when a new ``Mesh`` is added, allocates 4× MSAA
and reads back (and converts) the depth buffer on every frame. For a video we need
none of that: :class:`DynamicMesh` keeps one vertex buffer and overwrites it with
``glBufferSubData``; :func:`offscreen_renderer` picks the sample count and reads back
colour only.
"""

from __future__ import annotations

import os

import numpy as np

_MSAA = {"samples": 0}


def import_pyrender():
    """Import pyrender for headless EGL (``PYOPENGL_PLATFORM=egl`` unless set; ``np.infty``).

    pyrender imports its pyglet viewer too; ``PYGLET_HEADLESS`` (unless set) keeps pyglet off
    X11, so no X libraries are needed (GPU servers often have none).
    """
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    os.environ.setdefault("PYGLET_HEADLESS", "true")
    if not hasattr(np, "infty"):
        np.infty = np.inf  # pyrender's shadow code still uses the NumPy 1 alias
    import pyrender
    import pyrender.renderer as _renderer

    if not getattr(_renderer, "_usdmotion_patched", False):
        original = _renderer.glRenderbufferStorageMultisample

        def storage(target, samples, internal_format, width, height):
            return original(target, _MSAA["samples"], internal_format, width, height)

        _renderer.glRenderbufferStorageMultisample = storage
        _renderer._usdmotion_patched = True
    return pyrender


def offscreen_renderer(width: int, height: int, msaa: int = 0):
    """A pyrender ``OffscreenRenderer`` with ``msaa`` samples (0 = off) that reads colour only.

    ``renderer.render(scene)`` then returns an ``(H, W, 3)`` uint8 array (top row first).
    """
    pyrender = import_pyrender()
    from OpenGL import GL

    _MSAA["samples"] = int(msaa)
    renderer = pyrender.OffscreenRenderer(width, height)
    inner = renderer._renderer

    def read_color(scene, flags):  # replaces Renderer._read_main_framebuffer: no depth read-back
        w, h = inner._main_fb_dims
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, inner._main_fb_ms)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, inner._main_fb)
        GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, inner._main_fb)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        data = GL.glReadPixels(0, 0, w, h, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1], None

    inner._read_main_framebuffer = read_color
    return renderer


def render_rgb(renderer, scene, shadows: bool = False) -> np.ndarray:
    """Render ``scene``; a contiguous ``(H, W, 3)`` uint8 image."""
    pyrender = import_pyrender()
    flags = pyrender.RenderFlags.SHADOWS_DIRECTIONAL if shadows else pyrender.RenderFlags.NONE
    color = renderer.render(scene, flags=flags)
    color = color[0] if isinstance(color, tuple) else color
    return np.ascontiguousarray(color)


class DynamicMesh:
    """A single-primitive pyrender mesh with fixed topology whose vertices change per frame."""

    def __init__(self, positions: np.ndarray, normals: np.ndarray, faces: np.ndarray, material,
                 colors: np.ndarray | None = None):
        pyrender = import_pyrender()
        self.colors = None if colors is None else np.asarray(colors, np.float32)
        primitive = pyrender.Primitive(positions=positions.astype(np.float32), normals=normals.astype(np.float32),
                                       indices=np.asarray(faces, np.uint32), material=material,
                                       color_0=self.colors)
        self.mesh = pyrender.Mesh([primitive])
        self.primitive = primitive
        self._interleaved = None

    def update(self, positions: np.ndarray, normals: np.ndarray) -> None:
        """Overwrite the vertex buffer (the mesh must have been rendered once, i.e. uploaded)."""
        from OpenGL import GL

        parts = [positions, normals] if self.colors is None else [positions, normals, self.colors]
        width = sum(p.shape[1] for p in parts)
        if self._interleaved is None or self._interleaved.shape != (len(positions), width):
            self._interleaved = np.empty((len(positions), width), np.float32)
        column = 0
        for p in parts:
            self._interleaved[:, column:column + p.shape[1]] = p
            column += p.shape[1]
        if self.primitive._vaid is None:  # not uploaded yet: let pyrender upload these values
            self.primitive.positions = positions.astype(np.float32)
            self.primitive.normals = normals.astype(np.float32)
            return
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.primitive._buffers[0])
        GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, self._interleaved.nbytes, self._interleaved)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
