"""pyrender plumbing: headless EGL, anti-aliasing (FXAA pass or MSAA), colour-only read-back,
meshes whose vertex buffer is rewritten in place every frame.

pyrender 0.1.45 re-uploads a mesh only when a new ``Mesh`` is added, allocates 4× MSAA
and reads back (and converts) the depth buffer on every frame. For a video we need
none of that: :class:`DynamicMesh` keeps one vertex buffer and overwrites it with
``glBufferSubData``; :func:`offscreen_renderer` picks the sample count, smooths edges with
one FXAA pass where there is no multisampling, and reads back colour only.

Anti-aliasing on a CPU rasteriser (Mesa llvmpipe): MSAA stores and resolves 4 samples a
pixel (llvmpipe offers 4 only: 2 is rounded up) and halves the frame rate; FXAA (Lottes'
fast approximate anti-aliasing) smooths luma edges after rendering and is the default. It
is drawn only over the 4×4 tiles near drawn pixels (:class:`FxaaPass`): the same picture as a
full-screen pass for about 0.35 of its CPU time (7 instead of 19 ms a 720p frame on llvmpipe).
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
        mesh_program = _renderer.Renderer._get_primitive_program

        # A primitive with ``usdmotion_shader = "unlit"`` is drawn in the colour pass with pyrender's own
        # unlit program (flat.frag: base colour times vertex colour), not the lit mesh.frag that
        # every pixel pays for on a CPU rasteriser (the contact shadow: black, so the same pixels).
        def program(self, primitive, flags, program_flags):
            own = getattr(primitive, "usdmotion_shader", None)
            if own is None or not program_flags & _renderer.ProgramFlags.USE_MATERIAL or flags & (
                    _renderer.RenderFlags.DEPTH_ONLY | _renderer.RenderFlags.FLAT | _renderer.RenderFlags.SEG):
                return mesh_program(self, primitive, flags, program_flags)
            return mesh_program(self, primitive, flags | _renderer.RenderFlags.FLAT, program_flags)

        _renderer.Renderer._get_primitive_program = program
        _renderer._usdmotion_patched = True
    return pyrender


def offscreen_renderer(width: int, height: int, msaa: int = 0, fxaa: bool = True):
    """A pyrender ``OffscreenRenderer`` with ``msaa`` samples (0 = off) that reads colour only;
    with ``fxaa`` and no multisampling, edges are smoothed by one FXAA pass before read-back.

    ``renderer.render(scene)`` then returns an ``(H, W, 4)`` uint8 RGBA array (top row first;
    the alpha channel means nothing): read back as RGBA, the framebuffer's own layout, it is a
    plain copy (0.67 ms of CPU a 720p frame on llvmpipe, 1.33 ms as RGB).
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
            post.apply(w, h, inner._main_fb_ms, inner._main_fb)  # drawn top row first: no flip here
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, inner._main_fb)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        image = np.empty((h, w, 4), np.uint8)  # RGBA: a plain copy out of the framebuffer (RGB is repacked)
        GL.glReadPixels(0, 0, w, h, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, image)
        return (image if post is not None else np.ascontiguousarray(image[::-1])), None

    inner._read_main_framebuffer = read_color
    return renderer




_FULL_SCREEN_VERTEX = """#version 410 core
uniform float flip;  // -1: upside down (the FXAA pass writes the top row first), 1: as is
void main() {  // one triangle over the whole picture
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(2.0 * p.x - 1.0, flip * (2.0 * p.y - 1.0), 0.0, 1.0);
}
"""

#: The FXAA pass drawn over quads in pixel coordinates (the runs of tiles that need it),
#: upside down: the picture is read back top row first without a flip.
_QUAD_VERTEX = """#version 410 core
layout(location = 0) in vec2 pixel;
uniform vec2 size;
void main() { gl_Position = vec4(2.0 * pixel.x / size.x - 1.0, 1.0 - 2.0 * pixel.y / size.y, 0.0, 1.0); }
"""

#: FXAA (T. Lottes, NVIDIA 2009/2011), the "fast" variant: luma of the 4 diagonal neighbours
#: gives the edge direction; 2 + 2 samples along it are blended; pixels off edges are kept.
#: The five taps are plain texel reads (no filtering: cheap on a CPU rasteriser), clamped to the
#: picture (a tap outside it would read black and make an edge of the picture's border); only
#: edge pixels take the four filtered samples. It writes the picture upside down (row y of
#: ``image`` to row H-1-y).
_FXAA_FRAGMENT = """#version 410 core
uniform sampler2D image;
out vec4 color;
float luma(vec3 c) { return dot(c, vec3(0.299, 0.587, 0.114)); }
float tap(ivec2 p, ivec2 last) { return luma(texelFetch(image, clamp(p, ivec2(0), last), 0).rgb); }
void main() {
    ivec2 last = textureSize(image, 0) - 1;
    ivec2 p = ivec2(gl_FragCoord.x, float(last.y + 1) - gl_FragCoord.y);  // the source pixel
    vec2 uv = (vec2(p) + 0.5) / vec2(last + 1);
    vec3 m = texelFetch(image, p, 0).rgb;
    float lm = luma(m);
    float nw = tap(p + ivec2(-1, 1), last);
    float ne = tap(p + ivec2(1, 1), last);
    float sw = tap(p + ivec2(-1, -1), last);
    float se = tap(p + ivec2(1, -1), last);
    float lo = min(lm, min(min(nw, ne), min(sw, se)));
    float hi = max(lm, max(max(nw, ne), max(sw, se)));
    if (hi - lo < max(1.0 / 32.0, hi / 8.0)) { color = vec4(m, 1.0); return; }
    vec2 dir = vec2((nw + ne) - (sw + se), (nw + sw) - (ne + se));  // along the edge (y up)
    float reduce = max(0.25 * (nw + ne + sw + se) / 8.0, 1.0 / 128.0);
    dir = clamp(dir / (min(abs(dir.x), abs(dir.y)) + reduce), -8.0, 8.0) / vec2(last + 1);
    vec3 a = 0.5 * (texture(image, uv - dir / 6.0).rgb + texture(image, uv + dir / 6.0).rgb);
    vec3 b = 0.5 * a + 0.25 * (texture(image, uv - 0.5 * dir).rgb + texture(image, uv + 0.5 * dir).rgb);
    float lb = luma(b);
    color = vec4(lb < lo || lb > hi ? a : b, 1.0);
}
"""

#: Side of the square tiles the FXAA pass is drawn in (pixels).
TILE = 4

#: Which tiles need the pass: one fragment per tile; 1 where any pixel of the tile or of the
#: one-pixel ring around it was drawn (depth < 1: FXAA changes a pixel only when one of its
#: taps differs from the background), 0 where all of them are background.
_TILE_FRAGMENT = """#version 410 core
uniform sampler2D depth;
out float keep;
void main() {
    vec2 size = vec2(textureSize(depth, 0));
    vec2 corner = vec2(ivec2(gl_FragCoord.xy) * %(tile)d - 1);  // the ring's first pixel
    float near = 1.0;
    for (int j = 0; j < %(ring)d; j += 2)
        for (int i = 0; i < %(ring)d; i += 2) {  // 2x2 pixels a read, exact values
            vec4 d = textureGather(depth, (corner + vec2(i, j) + 1.0) / size);
            near = min(near, min(min(d.x, d.y), min(d.z, d.w)));
        }
    keep = near < 1.0 ? 1.0 : 0.0;
}
""" % {"tile": TILE, "ring": TILE + 2}

#: ``False`` draws the FXAA pass over the whole picture (the tiles' peer in benchmarks/render.py
#: and in the test that the tiles lose no pixel; same output).
FXAA_TILES = True


def _texture(internal_format: int, width: int, height: int, layout: tuple[int, int], filtering: int) -> int:
    """A 2-D texture of ``internal_format`` (clamped at its edges) for a framebuffer attachment."""
    from OpenGL import GL

    texture = GL.glGenTextures(1)
    GL.glBindTexture(GL.GL_TEXTURE_2D, texture)
    GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, internal_format, width, height, 0, *layout, None)
    for name, value in ((GL.GL_TEXTURE_MIN_FILTER, filtering), (GL.GL_TEXTURE_MAG_FILTER, filtering),
                        (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
        GL.glTexParameteri(GL.GL_TEXTURE_2D, name, value)
    return texture


def _program(vertex: str, fragment: str) -> int:
    from OpenGL import GL
    from OpenGL.GL import shaders

    program = GL.glCreateProgram()
    for source, kind in ((vertex, GL.GL_VERTEX_SHADER), (fragment, GL.GL_FRAGMENT_SHADER)):
        GL.glAttachShader(program, shaders.compileShader(source, kind))
    GL.glLinkProgram(program)
    if not GL.glGetProgramiv(program, GL.GL_LINK_STATUS):
        raise RuntimeError(f"FXAA shader: {GL.glGetProgramInfoLog(program)!r}")
    return program


def tile_runs(keep: np.ndarray, tile: int = TILE) -> np.ndarray:
    """Quads over the runs of kept tiles, row by row: ``(Q, 6, 2)`` float32 pixel corners (two
    triangles a quad) for a ``(rows, columns)`` bool tile mask (row 0 at the bottom)."""
    padded = np.zeros((keep.shape[0], keep.shape[1] + 2), np.int8)
    padded[:, 1:-1] = keep
    step = np.diff(padded, axis=1)
    row, first = np.nonzero(step == 1)  # row-major order: the k-th start and end are one run
    end = np.nonzero(step == -1)[1]
    x0, x1, y0 = first * tile, end * tile, row * tile
    y1 = y0 + tile
    corners = np.stack([np.stack([x0, y0], -1), np.stack([x1, y0], -1), np.stack([x1, y1], -1),
                        np.stack([x0, y0], -1), np.stack([x1, y1], -1), np.stack([x0, y1], -1)], axis=1)
    return corners.astype(np.float32)


class FxaaPass:
    """One FXAA pass (GL objects made in the current context on first use): the picture drawn
    into framebuffer ``source`` is smoothed into framebuffer ``target``.

    On a CPU rasteriser a full-screen pass costs about as much as its pixels, edges or not
    (llvmpipe runs every instruction for every pixel: a branch does not skip work), while only a
    few per cent of a video frame lie near anything drawn. So the picture is cut into
    :data:`TILE` × :data:`TILE` tiles; one small pass over the depth buffer marks the tiles with
    a drawn pixel in or around them, ``target`` is cleared to the background colour and the FXAA
    shader is drawn over the marked tiles only (one quad per run of tiles in a row). Pixels
    elsewhere are background with only background around them, which FXAA leaves as it is: the
    result is the full-screen pass's (:data:`FXAA_TILES` ``False``), bit for bit.
    """

    def __init__(self, tiles: bool | None = None) -> None:
        self.tiles = FXAA_TILES if tiles is None else tiles
        self.programs = None
        self.size = None
        self.source = None  # the framebuffer whose colour and depth buffers are the pass's textures

    def _make(self, width: int, height: int) -> None:
        from OpenGL import GL

        if self.programs is None:
            self.programs = {"full": _program(_FULL_SCREEN_VERTEX, _FXAA_FRAGMENT),
                             "quads": _program(_QUAD_VERTEX, _FXAA_FRAGMENT),
                             "tiles": _program(_FULL_SCREEN_VERTEX, _TILE_FRAGMENT)}
            self.empty_vao = GL.glGenVertexArrays(1)
            self.quad_vao = GL.glGenVertexArrays(1)
            self.quad_buffer = GL.glGenBuffers(1)
            GL.glBindVertexArray(self.quad_vao)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.quad_buffer)
            GL.glEnableVertexAttribArray(0)
            GL.glVertexAttribPointer(0, 2, GL.GL_FLOAT, GL.GL_FALSE, 0, None)
            GL.glBindVertexArray(0)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        self.texture = _texture(GL.GL_RGBA8, width, height, (GL.GL_RGBA, GL.GL_UNSIGNED_BYTE), GL.GL_LINEAR)
        self.depth = _texture(GL.GL_DEPTH_COMPONENT24, width, height, (GL.GL_DEPTH_COMPONENT, GL.GL_UNSIGNED_INT),
                              GL.GL_NEAREST)
        self.framebuffer = GL.glGenFramebuffers(1)  # the textures alone: the first picture is copied here
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.framebuffer)
        GL.glFramebufferTexture2D(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D, self.texture, 0)
        GL.glFramebufferTexture2D(GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_TEXTURE_2D, self.depth, 0)
        self.tile_shape = (-(-height // TILE), -(-width // TILE))
        self.tile_texture = _texture(GL.GL_R8, self.tile_shape[1], self.tile_shape[0],
                                     (GL.GL_RED, GL.GL_UNSIGNED_BYTE), GL.GL_NEAREST)
        self.tile_framebuffer = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.tile_framebuffer)
        GL.glFramebufferTexture2D(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D,
                                  self.tile_texture, 0)
        self.size = (width, height)

    def _adopt(self, source: int, width: int, height: int) -> None:
        """Copy the picture and depth in ``source`` into the pass's textures, then make them
        ``source``'s buffers: the next pictures are drawn straight into them."""
        from OpenGL import GL

        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, source)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.framebuffer)
        GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height,
                             GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT, GL.GL_NEAREST)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, source)
        GL.glFramebufferTexture2D(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D, self.texture, 0)
        GL.glFramebufferTexture2D(GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_TEXTURE_2D, self.depth, 0)
        if GL.glCheckFramebufferStatus(GL.GL_DRAW_FRAMEBUFFER) != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError("FXAA: the picture's framebuffer cannot draw into textures")
        self.source = source

    def _kept_tiles(self) -> np.ndarray:
        """``(Q, 6, 2)`` quads over the tiles that need the pass (see :func:`tile_runs`)."""
        from OpenGL import GL

        rows, columns = self.tile_shape
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.tile_framebuffer)
        GL.glViewport(0, 0, columns, rows)
        GL.glUseProgram(self.programs["tiles"])
        GL.glUniform1f(GL.glGetUniformLocation(self.programs["tiles"], "flip"), 1.0)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.depth)
        GL.glUniform1i(GL.glGetUniformLocation(self.programs["tiles"], "depth"), 0)
        GL.glBindVertexArray(self.empty_vao)
        GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self.tile_framebuffer)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        keep = np.frombuffer(GL.glReadPixels(0, 0, columns, rows, GL.GL_RED, GL.GL_UNSIGNED_BYTE), np.uint8)
        return tile_runs(keep.reshape(rows, columns) > 0)

    def _tile_quads(self, width: int, height: int, target: int) -> tuple[int, int]:
        """Clear ``target`` to the background and load the quads over the kept tiles:
        ``(program, vertex count)`` to draw."""
        from OpenGL import GL

        quads = self._kept_tiles()
        # the tiles left out hold only background: the clear colour the picture was drawn on
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, target)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT)
        program = self.programs["quads"]
        GL.glUseProgram(program)
        GL.glUniform2f(GL.glGetUniformLocation(program, "size"), float(width), float(height))
        GL.glBindVertexArray(self.quad_vao)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.quad_buffer)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, quads.nbytes, quads if len(quads) else None, GL.GL_STREAM_DRAW)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        return program, 6 * len(quads)

    def apply(self, width: int, height: int, source: int, target: int) -> None:
        """Smooth the picture in framebuffer ``source`` into framebuffer ``target``, upside down
        (``target`` read back from row 0 up is the picture top row first)."""
        from OpenGL import GL

        if self.size != (width, height):
            self._make(width, height)
            self.source = None
        if self.source != source:
            self._adopt(source, width, height)
        for cap in (GL.GL_DEPTH_TEST, GL.GL_BLEND, GL.GL_CULL_FACE):
            GL.glDisable(cap)
        GL.glActiveTexture(GL.GL_TEXTURE0)
        if self.tiles:
            program, count = self._tile_quads(width, height, target)
        else:
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, target)
            program, count = self.programs["full"], 3
            GL.glUseProgram(program)
            GL.glUniform1f(GL.glGetUniformLocation(program, "flip"), -1.0)
            GL.glBindVertexArray(self.empty_vao)
        GL.glViewport(0, 0, width, height)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.texture)
        GL.glUniform1i(GL.glGetUniformLocation(program, "image"), 0)
        if count:
            GL.glDrawArrays(GL.GL_TRIANGLES, 0, count)
        GL.glBindVertexArray(0)
        GL.glUseProgram(0)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        GL.glEnable(GL.GL_DEPTH_TEST)


def render_rgba(renderer, scene, shadows: bool = False) -> np.ndarray:
    """Render ``scene``; a contiguous ``(H, W, 4)`` uint8 image (RGB and a meaningless alpha)."""
    pyrender = import_pyrender()
    flags = pyrender.RenderFlags.SHADOWS_DIRECTIONAL if shadows else pyrender.RenderFlags.NONE
    color = renderer.render(scene, flags=flags)
    return color[0] if isinstance(color, tuple) else color


def render_rgb(renderer, scene, shadows: bool = False) -> np.ndarray:
    """Render ``scene``; a contiguous ``(H, W, 3)`` uint8 image."""
    return np.ascontiguousarray(render_rgba(renderer, scene, shadows)[..., :3])


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
