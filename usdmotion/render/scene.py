"""Scene content for offscreen rendering: body and stick-figure meshes, ground grid,
trajectory traces and lights, all in render space (metres, Y up).

Geometry that changes per frame is computed for all its parts at once with NumPy
(stick figure: one prism per bone and one icosphere per joint, placed by array
maths) and written into :class:`~usdmotion.render.gl.DynamicMesh` buffers.
"""

from __future__ import annotations

import numpy as np

from usdmotion.render.gl import FLOOR, DynamicMesh, import_pyrender
from usdmotion.render.space import to_render_space  # noqa: F401  (re-exported: scene content is in render space)

#: Colours (linear RGBA) of the scene's parts.
COLORS = {
    "background": (0.90, 0.91, 0.93, 1.0),
    "body": (0.86, 0.50, 0.32, 1.0),
    "ghost": (0.20, 0.45, 0.95, 0.45),
    "bone": (0.16, 0.17, 0.20, 1.0),
    "joint": (0.85, 0.15, 0.12, 1.0),
    "ghost_stick": (0.15, 0.35, 0.90, 1.0),
    "ground": (0.80, 0.81, 0.83, 1.0),
    "grid": (0.42, 0.44, 0.48, 1.0),
    "traces": ((0.05, 0.62, 0.25, 1.0), (0.65, 0.10, 0.70, 1.0), (0.95, 0.65, 0.05, 1.0), (0.05, 0.55, 0.75, 1.0)),
}


def material(color, double_sided: bool = False):
    pyrender = import_pyrender()
    color = tuple(float(c) for c in color)
    return pyrender.MetallicRoughnessMaterial(baseColorFactor=color, metallicFactor=0.0, roughnessFactor=0.75,
                                              alphaMode="BLEND" if color[3] < 1.0 else "OPAQUE",
                                              doubleSided=double_sided)




# ------------------------------------------------------------------ stick figure


def _icosphere():
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=1)
    return np.asarray(sphere.vertices), np.asarray(sphere.faces)


def _prism(sides: int = 8):
    angle = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    verts = np.concatenate([np.c_[ring, np.zeros(sides)], np.c_[ring, np.ones(sides)]])
    normals = np.concatenate([np.c_[ring, np.zeros(sides)]] * 2)
    k = np.arange(sides)
    n = (k + 1) % sides
    faces = np.concatenate([np.stack([k, n, k + sides], 1), np.stack([n, n + sides, k + sides], 1)])
    return verts, normals, faces


class StickFigure:
    """Bones as prisms and joints as spheres: one mesh, re-placed every frame."""

    def __init__(self, parents: np.ndarray, bones: np.ndarray, radius: float, bone_color, joint_color,
                 shown: np.ndarray | None = None):
        self.parents = parents
        self.bones = bones  # child joint indices of drawn bones
        self.shown = np.arange(len(parents)) if shown is None else np.asarray(shown)  # joints drawn as spheres
        self.radius = radius
        self.prism_v, self.prism_n, prism_f = _prism()
        self.sphere_v, sphere_f = _icosphere()
        n_b, n_j = len(bones), len(self.shown)
        pv, sv = len(self.prism_v), len(self.sphere_v)
        faces = [prism_f[None] + pv * np.arange(n_b)[:, None, None],
                 sphere_f[None] + n_b * pv + sv * np.arange(n_j)[:, None, None]]
        self.faces = np.concatenate([f.reshape(-1, 3) for f in faces])
        colors = np.concatenate([np.tile(bone_color, (n_b * pv, 1)), np.tile(joint_color, (n_j * sv, 1))])
        positions, normals = self.geometry(np.zeros((len(parents), 3)) + np.arange(len(parents))[:, None] * 0.01)
        self.dynamic = DynamicMesh(positions, normals, self.faces, material((1.0, 1.0, 1.0, 1.0)),
                                   colors=colors.astype(np.float32))

    def geometry(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(positions, normals)`` of the whole figure for joint positions ``(J, 3)``."""
        a, b = joints[self.parents[self.bones]], joints[self.bones]
        axis = b - a
        length = np.linalg.norm(axis, axis=1)
        z = axis / np.maximum(length, 1e-12)[:, None]
        helper = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        y = np.cross(z, x)
        frame = np.stack([x, y, z], axis=-1)  # (B, 3, 3): columns x, y, z
        scale = np.stack([np.full_like(length, 0.6 * self.radius), np.full_like(length, 0.6 * self.radius),
                          length], axis=-1)
        bone_v = np.einsum("bij,bvj->bvi", frame, self.prism_v[None] * scale[:, None]) + a[:, None]
        bone_n = np.einsum("bij,vj->bvi", frame, self.prism_n)
        joint_v = joints[self.shown][:, None] + self.radius * self.sphere_v[None]
        joint_n = np.broadcast_to(self.sphere_v, joint_v.shape)
        return (np.concatenate([bone_v.reshape(-1, 3), joint_v.reshape(-1, 3)]),
                np.concatenate([bone_n.reshape(-1, 3), joint_n.reshape(-1, 3)]))

    def update(self, joints: np.ndarray) -> None:
        self.dynamic.update(*self.geometry(joints))


# ------------------------------------------------------------------ static parts


#: Texels per grid cell of the grid texture (the lines' edges are anti-aliased in it).
GRID_TEXELS = 256


def grid_texture(line_fraction: float, texels: int = GRID_TEXELS) -> np.ndarray:
    """One grid cell as an RGBA texture ``(T, T, 4)`` uint8: white, opaque on lines of
    ``line_fraction`` of the cell centred on its edges, transparent between; each texel's alpha
    is the fraction of it the line covers (anti-aliased edges)."""
    width = min(max(float(line_fraction), 1.0 / texels), 0.5)
    edges = np.arange(texels + 1) / texels
    lo, hi = edges[:-1], edges[1:]
    # the line is [-w/2, w/2] around 0 (and 1): overlap with each texel, in texels
    coverage = (np.clip(np.minimum(hi, width / 2) - lo, 0, None)
                + np.clip(hi - np.maximum(lo, 1 - width / 2), 0, None)) * texels
    coverage = np.clip(coverage, 0.0, 1.0)
    alpha = np.maximum(coverage[:, None], coverage[None, :])
    rgba = np.full((texels, texels, 4), 255, np.uint8)
    rgba[..., 3] = np.rint(255 * alpha).astype(np.uint8)
    return rgba


def _anisotropic_texture(pyrender, source: np.ndarray):
    """A mip-mapped, repeating pyrender texture sampled anisotropically (16×, or the driver's
    most): grid lines seen at a grazing angle stay lines instead of vanishing or shimmering."""
    from OpenGL import GL
    from OpenGL.error import GLError

    max_anisotropy, most_anisotropy = 0x84FE, 0x84FF  # GL 4.6 / EXT_texture_filter_anisotropic

    class AnisotropicTexture(pyrender.Texture):
        def _add_to_context(self):
            super()._add_to_context()
            GL.glBindTexture(GL.GL_TEXTURE_2D, self._texid)
            try:
                most = float(GL.glGetFloatv(most_anisotropy))
                GL.glTexParameterf(GL.GL_TEXTURE_2D, max_anisotropy, min(16.0, most))
            except GLError:  # a driver without anisotropic filtering: mip-mapped only
                pass
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    sampler = pyrender.Sampler(magFilter=GL.GL_LINEAR, minFilter=GL.GL_LINEAR_MIPMAP_LINEAR,
                               wrapS=GL.GL_REPEAT, wrapT=GL.GL_REPEAT)
    return AnisotropicTexture(source=source, source_channels="RGBA", sampler=sampler)


def grid_mesh(lo: np.ndarray, hi: np.ndarray, height: float, spacing: float, line_width: float,
              solid: bool = False):
    """Grid lines every ``spacing`` metres over ``[lo, hi]`` (x, z), on a floor quad if ``solid``.

    The lines are a texture on one quad (:func:`grid_texture`, mip-mapped and sampled
    anisotropically): anti-aliased at every distance and angle at the cost of one textured quad.
    """
    pyrender = import_pyrender()
    import trimesh

    x0, x1 = np.floor(lo[0] / spacing) * spacing, np.ceil(hi[0] / spacing) * spacing
    z0, z1 = np.floor(lo[2] / spacing) * spacing, np.ceil(hi[2] / spacing) * spacing
    quad = np.array([[x0, height, z0], [x1, height, z0], [x1, height, z1], [x0, height, z1]])
    faces = np.array([[0, 2, 1], [0, 3, 2]])
    ground = trimesh.Trimesh(quad, faces, process=False)
    lifted = quad + [0.0, 1e-3 * max(spacing, 1.0), 0.0]
    grid = material(COLORS["grid"][:3] + (0.999,))  # BLEND: the texture's alpha is the lines
    grid.baseColorTexture = _anisotropic_texture(pyrender, grid_texture(line_width / spacing))
    lines = pyrender.Primitive(positions=lifted.astype(np.float32), normals=np.tile([[0.0, 1.0, 0.0]], (4, 1)),
                               texcoord_0=(lifted[:, [0, 2]] / spacing).astype(np.float32),
                               indices=faces.astype(np.uint32), material=grid)
    meshes = [pyrender.Mesh([lines], name=FLOOR)]
    if solid:  # a shaded floor costs a lighting pass for half the image on a CPU rasteriser
        meshes.insert(0, pyrender.Mesh.from_trimesh(ground, material=material(COLORS["ground"]), smooth=False))
    return meshes


def tube_mesh(path: np.ndarray, radius: float, color, max_points: int = 4000):
    """A closed-ring tube along a polyline ``(N, 3)`` (decimated to ``max_points``)."""
    pyrender = import_pyrender()
    import trimesh

    if len(path) > max_points:
        path = path[np.linspace(0, len(path) - 1, max_points).astype(int)]
    keep = np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-6]
    path = path[keep]
    if len(path) < 2:
        return pyrender.Mesh.from_trimesh(trimesh.creation.icosphere(1, radius).apply_translation(path[0]),
                                          material=material(color))
    tangent = np.gradient(path, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    helper = np.where(np.abs(tangent[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(tangent, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(tangent, u)
    angle = 2 * np.pi * np.arange(6) / 6
    ring = np.cos(angle)[None, :, None] * u[:, None] + np.sin(angle)[None, :, None] * v[:, None]  # (N, 6, 3)
    verts = (path[:, None] + radius * ring).reshape(-1, 3)
    i = np.arange(len(path) - 1)[:, None] * 6
    k = np.arange(6)[None]
    n = (k + 1) % 6
    faces = np.concatenate([np.stack([i + k, i + n, i + 6 + k], -1), np.stack([i + n, i + 6 + n, i + 6 + k], -1)],
                           axis=1).reshape(-1, 3)
    mesh = trimesh.Trimesh(verts, faces, vertex_normals=ring.reshape(-1, 3), process=False)
    return pyrender.Mesh.from_trimesh(mesh, material=material(color), smooth=True)


def add_lights(scene, forward: np.ndarray, intensity: float = 3.0):
    """A key light from above the subject's front left (it casts the shadows)."""
    pyrender = import_pyrender()
    from usdmotion.render.camera import UP, look_at

    left = np.cross(UP, forward)
    # one light: every light is a full lighting pass per pixel on a CPU rasteriser
    for direction, power in ((0.55 * forward + 0.45 * left + 1.1 * UP, intensity),):
        pose = look_at(direction, np.zeros(3), UP if abs(direction[1]) < 0.99 * np.linalg.norm(direction)
                       else forward)
        scene.add(pyrender.DirectionalLight(color=np.ones(3), intensity=power), pose=pose)
