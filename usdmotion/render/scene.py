"""Scene content for offscreen rendering: body and stick-figure meshes, ground grid,
trajectory traces and lights, all in render space (metres, Y up).

Geometry that changes per frame is computed for all its parts at once with NumPy
(stick figure: one prism per bone and one icosphere per joint, placed by array
maths) and written into :class:`~usdmotion.render.gl.DynamicMesh` buffers.
"""

from __future__ import annotations

import numpy as np

from usdmotion.render.camera import UP, look_at
from usdmotion.render.gl import DynamicMesh, import_pyrender
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
        self.colors = colors.astype(np.float32)  # (V, C) per vertex: bones', then joints'
        positions, normals = self.geometry(np.zeros((len(parents), 3)) + np.arange(len(parents))[:, None] * 0.01)
        self.dynamic = DynamicMesh(positions, normals, self.faces, material((1.0, 1.0, 1.0, 1.0)),
                                   colors=self.colors)

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


#: Pieces each grid line is cut into, so its width can follow the distance to the camera.
GRID_PIECES = 24


def grid_mesh(lo: np.ndarray, hi: np.ndarray, height: float, spacing: float, line_width: float,
              solid: bool = False, eye: np.ndarray | None = None, pixel_angle: float = 0.0):
    """Grid lines every ``spacing`` metres over ``[lo, hi]`` (x, z), on a floor quad if ``solid``.

    Lines are ``line_width`` metres wide, or, seen from ``eye`` (metres, render space) with
    ``pixel_angle`` radians a pixel, wide enough to cover 1.4 pixels where they lie: wider far
    away and where the floor is seen at a grazing angle (up to 5×), so a far line across the
    view is not dropped by the rasteriser (the FXAA pass then smooths its edges).
    """
    pyrender = import_pyrender()
    import trimesh

    x0, x1 = np.floor(lo[0] / spacing) * spacing, np.ceil(hi[0] / spacing) * spacing
    z0, z1 = np.floor(lo[2] / spacing) * spacing, np.ceil(hi[2] / spacing) * spacing
    quad = np.array([[x0, height, z0], [x1, height, z0], [x1, height, z1], [x0, height, z1]])
    ground = trimesh.Trimesh(quad, [[0, 2, 1], [0, 3, 2]], process=False)
    h = height + 1e-3 * max(spacing, 1.0)
    t = np.linspace(0.0, 1.0, GRID_PIECES + 1)
    xs = np.arange(x0, x1 + spacing / 2, spacing)
    zs = np.arange(z0, z1 + spacing / 2, spacing)
    # centre lines (L, P+1, 3) and the floor direction across each line (L, 3)
    along_z = np.stack(np.broadcast_arrays(xs[:, None], h, z0 + (z1 - z0) * t[None]), axis=-1)
    along_x = np.stack(np.broadcast_arrays(x0 + (x1 - x0) * t[None], h, zs[:, None]), axis=-1)
    centres = np.concatenate([along_z, along_x]).astype(np.float64)
    across = np.concatenate([np.tile([1.0, 0.0, 0.0], (len(xs), 1)), np.tile([0.0, 0.0, 1.0], (len(zs), 1))])
    width = np.full(centres.shape[:2], float(line_width))
    if eye is not None and pixel_angle > 0:
        ray = centres - np.asarray(eye, dtype=np.float64)
        distance = np.linalg.norm(ray, axis=-1)
        cosine = np.einsum("lpk,lk->lp", ray, across) / np.maximum(distance, 1e-9)
        foreshortening = np.maximum(np.sqrt(np.clip(1.0 - cosine ** 2, 0.0, 1.0)), 0.2)
        width = np.maximum(width, 1.4 * pixel_angle * distance / foreshortening)
    offset = 0.5 * width[..., None] * across[:, None, :]
    left, right = centres - offset, centres + offset  # (L, P+1, 3)
    corners = np.stack([left[:, :-1], right[:, :-1], right[:, 1:], left[:, 1:]], axis=2)  # (L, P, 4, 3)
    rects = corners.reshape(-1, 4, 3)
    faces = (np.array([[0, 2, 1], [0, 3, 2]])[None] + 4 * np.arange(len(rects))[:, None, None]).reshape(-1, 3)
    faces = np.where(np.repeat(across[:, 0] > 0, GRID_PIECES * 2)[:, None], faces, faces[:, [0, 2, 1]])
    lines = trimesh.Trimesh(rects.reshape(-1, 3), faces, process=False)
    meshes = [pyrender.Mesh.from_trimesh(lines, material=material(COLORS["grid"]), smooth=False)]
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

    left = np.cross(UP, forward)
    # one light: every light is a full lighting pass per pixel on a CPU rasteriser
    for direction, power in ((0.55 * forward + 0.45 * left + 1.1 * UP, intensity),):
        pose = look_at(direction, np.zeros(3), UP if abs(direction[1]) < 0.99 * np.linalg.norm(direction)
                       else forward)
        scene.add(pyrender.DirectionalLight(color=np.ones(3), intensity=power), pose=pose)
