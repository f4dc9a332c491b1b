"""pyrender plumbing: headless EGL, anti-aliasing (FXAA pass or MSAA), colour-only read-back,
meshes whose vertex buffer is rewritten in place every frame.

pyrender 0.1.45 re-uploads a mesh only when a new ``Mesh`` is added, allocates 4× MSAA
and reads back (and converts) the depth buffer on every frame. For a video we need
none of that: :class:`DynamicMesh` keeps one vertex buffer and overwrites it with
``glBufferSubData``; :func:`offscreen_renderer` picks the sample count, smooths edges with
one FXAA pass where there is no multisampling, and reads back colour only.

Anti-aliasing on a CPU rasteriser (Mesa llvmpipe): MSAA stores and resolves 4 samples a
pixel (llvmpipe offers 4 only: 2 is rounded up) and halves the frame rate; FXAA (Lottes'
fast approximate anti-aliasing) is one full-screen pass that blends across luma edges, at
less than half of that cost (0.67-0.85x the frame rate without it, measured under load), so
it is the default.
"""

from __future__ import annotations

import os

import numpy as np

from usdmotion.errors import UsdMotionError

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


def offscreen_renderer(width: int, height: int, msaa: int = 0, fxaa: bool = True):
    """A pyrender ``OffscreenRenderer`` with ``msaa`` samples (0 = off) that reads colour only;
    with ``fxaa`` and no multisampling, edges are smoothed by one FXAA pass before read-back.

    ``renderer.render(scene)`` then returns an ``(H, W, 3)`` uint8 array (top row first).
    """
    pyrender = import_pyrender()
    from OpenGL import GL

    _MSAA["samples"] = int(msaa)
    renderer = pyrender.OffscreenRenderer(width, height)
    most = int(GL.glGetIntegerv(GL.GL_MAX_SAMPLES))
    if msaa > most:  # llvmpipe offers 4

        name = GL.glGetString(GL.GL_RENDERER).decode(errors="replace")
        renderer.delete()
        raise UsdMotionError(f"--msaa {msaa}: this OpenGL renderer ({name}) offers at most {most} samples")
    inner = renderer._renderer
    post = FxaaPass() if fxaa and not msaa else None

    def read_color(scene, flags):  # replaces Renderer._read_main_framebuffer: no depth read-back
        w, h = inner._main_fb_dims
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, inner._main_fb_ms)
        if post is None:
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, inner._main_fb)
            GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
        else:
            post.apply(w, h, inner._main_fb_ms, inner._main_fb)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, inner._main_fb)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        data = GL.glReadPixels(0, 0, w, h, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1], None

    inner._read_main_framebuffer = read_color
    return renderer




_FXAA_VERTEX = """#version 330 core
out vec2 uv;
void main() {  // one triangle over the whole picture
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    uv = p;
    gl_Position = vec4(2.0 * p - 1.0, 0.0, 1.0);
}
"""

#: FXAA (T. Lottes, NVIDIA 2009/2011), the "fast" variant: luma of the 4 diagonal neighbours
#: gives the edge direction; 2 + 2 samples along it are blended; pixels off edges are kept.
#: The five taps are plain texel reads (no filtering: cheap on a CPU rasteriser); only edge
#: pixels take the four filtered samples.
_FXAA_FRAGMENT = """#version 330 core
uniform sampler2D image;
in vec2 uv;
out vec4 color;
float luma(vec3 c) { return dot(c, vec3(0.299, 0.587, 0.114)); }
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 m = texelFetch(image, p, 0).rgb;
    float lm = luma(m);
    float nw = luma(texelFetch(image, p + ivec2(-1, 1), 0).rgb);
    float ne = luma(texelFetch(image, p + ivec2(1, 1), 0).rgb);
    float sw = luma(texelFetch(image, p + ivec2(-1, -1), 0).rgb);
    float se = luma(texelFetch(image, p + ivec2(1, -1), 0).rgb);
    float lo = min(lm, min(min(nw, ne), min(sw, se)));
    float hi = max(lm, max(max(nw, ne), max(sw, se)));
    if (hi - lo < max(1.0 / 32.0, hi / 8.0)) { color = vec4(m, 1.0); return; }
    vec2 dir = vec2((nw + ne) - (sw + se), (nw + sw) - (ne + se));  // along the edge (y up)
    float reduce = max(0.25 * (nw + ne + sw + se) / 8.0, 1.0 / 128.0);
    dir = clamp(dir / (min(abs(dir.x), abs(dir.y)) + reduce), -8.0, 8.0) / vec2(textureSize(image, 0));
    vec3 a = 0.5 * (texture(image, uv - dir / 6.0).rgb + texture(image, uv + dir / 6.0).rgb);
    vec3 b = 0.5 * a + 0.25 * (texture(image, uv - 0.5 * dir).rgb + texture(image, uv + 0.5 * dir).rgb);
    float lb = luma(b);
    color = vec4(lb < lo || lb > hi ? a : b, 1.0);
}
"""


class FxaaPass:
    """One FXAA pass (GL objects made in the current context on first use): the picture in the
    bound read framebuffer is copied to a texture and drawn, smoothed, into ``target``."""

    def __init__(self) -> None:
        self.program = None
        self.size = None
        self.source = None  # the framebuffer whose colour buffer is the pass's texture

    def _make(self, width: int, height: int) -> None:
        from OpenGL import GL
        from OpenGL.GL import shaders

        if self.program is None:
            self.program = GL.glCreateProgram()
            for source, kind in ((_FXAA_VERTEX, GL.GL_VERTEX_SHADER), (_FXAA_FRAGMENT, GL.GL_FRAGMENT_SHADER)):
                GL.glAttachShader(self.program, shaders.compileShader(source, kind))
            GL.glLinkProgram(self.program)
            if not GL.glGetProgramiv(self.program, GL.GL_LINK_STATUS):
                raise RuntimeError(f"FXAA shader: {GL.glGetProgramInfoLog(self.program)!r}")
            self.vao = GL.glGenVertexArrays(1)
        self.texture = GL.glGenTextures(1)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.texture)
        GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, GL.GL_RGBA8, width, height, 0, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, None)
        for name, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR), (GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR),
                            (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, name, value)
        self.framebuffer = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.framebuffer)
        GL.glFramebufferTexture2D(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D, self.texture, 0)
        self.size = (width, height)

    def apply(self, width: int, height: int, source: int, target: int) -> None:
        """Smooth the picture in framebuffer ``source`` into framebuffer ``target``. The first
        time, the picture is copied into the pass's texture, which then becomes ``source``'s
        colour buffer: the next pictures are drawn straight into it (no copy a frame)."""
        from OpenGL import GL

        if self.size != (width, height):
            self._make(width, height)
            self.source = None
        if self.source != source:
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, source)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.framebuffer)
            GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, source)
            GL.glFramebufferTexture2D(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D,
                                      self.texture, 0)
            complete = GL.glCheckFramebufferStatus(GL.GL_DRAW_FRAMEBUFFER) == GL.GL_FRAMEBUFFER_COMPLETE
            if not complete:
                raise RuntimeError("FXAA: the picture's framebuffer cannot draw into a texture")
            self.source = source
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, target)
        GL.glViewport(0, 0, width, height)
        for cap in (GL.GL_DEPTH_TEST, GL.GL_BLEND, GL.GL_CULL_FACE):
            GL.glDisable(cap)
        GL.glUseProgram(self.program)
        GL.glActiveTexture(GL.GL_TEXTURE0)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.texture)
        GL.glUniform1i(GL.glGetUniformLocation(self.program, "image"), 0)
        GL.glBindVertexArray(self.vao)
        GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
        GL.glBindVertexArray(0)
        GL.glUseProgram(0)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        GL.glEnable(GL.GL_DEPTH_TEST)


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
