"""The per-frame render loop: actors (one per motion) in one or two pyrender scenes."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from usdmotion.body_parts import NO_BODY, body_groups
from usdmotion.errors import UsdMotionError
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.render.angles import AngleOverlay, angle_values, parse_angle
from usdmotion.render.camera import forward_direction, project_frames
from usdmotion.render.compare import clock_text
from usdmotion.render.gl import DynamicMesh, import_pyrender, offscreen_renderer, render_rgba
from usdmotion.render.lod import detail, fewer_triangles, pixel_height
from usdmotion.render.overlay import draw_text
from usdmotion.render.panel import PlotStrip, panel_series, parse_panel, strip_height
from usdmotion.render.shadow import ContactShadow
from usdmotion.render.traces import trace_meshes
from usdmotion.skin import body_size, build_body, lbs, skinning_matrices
from usdmotion.skin_stage import stage_body_and_shapes
from usdmotion.render.scene import COLORS, StickFigure, add_lights, grid_mesh, material, to_render_space

#: Frames skinned at once (one BLAS product), one chunk ahead of the rendering.
CHUNK = 32
FIRST_CHUNK = 4

_UP_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def choose_body(motion: Motion, which: str, resolution: int, keep: float = 1.0):
    """The body to draw and its animated blend shapes' offsets (``(S, V, 3)`` or ``None``,
    :func:`usdmotion.skin_stage.stage_body_and_shapes`): the input's own skinned meshes
    (``"stage"``; ``"auto"`` when it has any) or the generated body (``"generated"``; ``"auto"``
    otherwise) with about ``keep`` of its triangles (:func:`usdmotion.render.lod.fewer_triangles`)."""
    if which not in ("auto", "stage", "generated"):
        raise UsdMotionError(f"--body must be auto, stage or generated, got {which!r}")
    if which != "generated" and motion.meshes:
        found = stage_body_and_shapes(motion)
        if found is not None:
            return found
    if which == "stage":
        raise UsdMotionError("--body stage: the input has no skinned mesh that fits its skeleton")
    return fewer_triangles(build_body(motion, resolution=resolution), keep), None


def stick_figure(motion: Motion, ghost: bool = False) -> StickFigure:
    """``motion``'s :class:`~usdmotion.render.scene.StickFigure` (render space: metres): a stick
    per bone of the body, none from a floor root or origin joint to the pelvis, none to or from
    a helper joint; joints red (a ``ghost``'s blue)."""
    rest_len = np.linalg.norm(motion.offsets[1:], axis=1)
    body = body_groups(motion) != NO_BODY
    bones = np.flatnonzero((rest_len > 1e-6 * body_size(motion)) & body[motion.parents[1:]] & body[1:]) + 1
    joint_color = COLORS["ghost_stick"] if ghost else COLORS["joint"]
    return StickFigure(motion.parents, bones, 0.012 * body_size(motion) * motion.meters_per_unit,
                       np.float32(COLORS["bone"]), np.float32(joint_color), np.flatnonzero(body))


@dataclass(frozen=True)
class Skinned:
    """A chunk of skinned frames, render space (metres, Y up)."""

    joints: np.ndarray                   # (K, J, 3) joint positions
    positions: np.ndarray | None = None  # (K, V, 3) body vertices (None: no body)
    normals: np.ndarray | None = None    # (K, V, 3) unit vertex normals


class Actor:
    """One motion's body and/or stick figure, skinned a chunk of frames at a time."""

    def __init__(self, motion: Motion, frames: np.ndarray, style: str, resolution: int, ghost: bool,
                 alignment=None, body: str = "auto", keep: float = 1.0):
        self.motion, self.frames = motion, frames
        self.local_t = local_translations(motion)
        self.turn = (_UP_Z if motion.up_axis == "Z" else np.eye(3)) * 1.0
        self.shift = np.zeros(3)
        if alignment is not None:  # the compared take, turned and moved onto the main one
            self.turn, self.shift = alignment.turn @ self.turn, alignment.shift
        self.scale = motion.meters_per_unit
        self.body = self.stick = self.shapes = None
        self.nodes = []
        self.inset = 0.0
        if style in ("body", "both"):
            self.body, self.shapes = choose_body(motion, body, resolution, keep)
            color = COLORS["ghost"] if ghost else COLORS["body"]
            # the ghost sits 1 % of the body size inside its own surface: where both motions
            # agree the opaque main body hides it, so it shows only where they differ
            self.inset = 0.01 * self.body.size * self.scale if ghost else 0.0
            if style == "both" and not ghost:
                color = color[:3] + (0.45,)
            self.weights = self.body.weight_matrix()
            self.body_mesh = DynamicMesh(self._space(self.body.vertices), self.body.normals @ self.turn.T,
                                         self.body.faces, material(color))
            self.nodes.append(self.body_mesh.mesh)
        if style in ("stick", "both"):
            self.stick = stick_figure(motion, ghost)
            self.nodes.append(self.stick.dynamic.mesh)

    def _space(self, points: np.ndarray) -> np.ndarray:
        return (points * self.scale) @ self.turn.T + self.shift

    def skin(self, index: np.ndarray) -> Skinned:
        """The output frames ``index`` (one chunk) skinned at once (a pure function of the motion)."""
        frames = self.frames[index]
        world_q, world_p = fk_arrays(self.motion.rotations[frames], self.local_t[frames], self.motion.parents)
        joints = self._space(world_p)
        if self.body is None:
            return Skinned(joints)
        matrices = skinning_matrices(world_q, world_p, self.body.bind_transforms)
        rest = self.body.vertices
        if self.shapes is not None:  # blend shapes first, then the skinning (UsdSkel's order)
            rest = rest + np.einsum("fs,svk->fvk", self.motion.blend_shape_weights[frames], self.shapes)
        positions, normals = lbs(rest, self.weights, matrices, self.body.normals)
        normals = normals @ self.turn.T
        return Skinned(joints, self._space(positions) - self.inset * normals, normals)

    def update(self, k: int, chunk: Skinned) -> None:
        """Load frame ``k`` of ``chunk`` (from :meth:`skin`) into the meshes."""
        if self.body is not None:
            self.body_mesh.update(chunk.positions[k], chunk.normals[k])
        if self.stick is not None:
            self.stick.update(chunk.joints[k])


class Views:
    """Scenes, camera, renderer; :meth:`run` renders every planned frame."""

    def __init__(self, motion: Motion, other: Motion | None, plan, options):
        pyrender = import_pyrender()
        self.plan, self.options = plan, options
        self.side = other is not None and options.compare_mode == "side"
        # the main take's joints (F, J, 3) in metres, render space: framing, grid, traces, angles
        fk = fk_arrays(motion.rotations[plan.frames], local_translations(motion)[plan.frames], motion.parents)
        self.frame_joints = to_render_space(fk[1], motion.meters_per_unit, motion.up_axis)
        root = self.frame_joints[:, 0]
        self.actors = [Actor(motion, plan.frames, options.style, options.body_resolution, ghost=False,
                             body=options.body, keep=self._detail(motion, root))]
        if other is not None:
            self.actors.append(Actor(other, plan.other_frames, options.style, options.body_resolution,
                                     ghost=not self.side, alignment=plan.alignment,
                                     keep=self._detail(other, root)))
        self.labels = options.labels
        self.other_fps = other.fps if other is not None else None
        scenes = [self._scene(pyrender) for _ in range(2 if self.side else 1)]
        for i, actor in enumerate(self.actors):
            for mesh in actor.nodes:
                scenes[i if self.side else 0].add(mesh)
        self.scenes = scenes
        self.view_grids = []  # the grid lines seen by each view (--layout)
        self._add_static(motion, other)
        self.angles = self._angles(motion) if options.angles else None
        self.shadow = self._contact_shadow() if options.contact_shadow else None
        self.strip = self._plot_strip(motion) if options.panel else None
        self.view_nodes = self._view_cameras(pyrender) if plan.cameras else []
        self.skin_seconds = 0.0
        self.renderer = offscreen_renderer(*plan.panel, msaa=options.msaa, fxaa=options.fxaa)

    def _detail(self, motion: Motion, root: np.ndarray) -> float:
        """The fraction of ``motion``'s generated body's triangles to draw (:mod:`usdmotion.render.lod`),
        from its height in pixels in the view that shows it largest, around ``root (N, 3)`` (render
        space, metres: the main take's root, which a compared take is aligned onto)."""
        if not self.options.lod:
            return 1.0
        size = body_size(motion) * motion.meters_per_unit
        return max(detail(pixel_height(size, np.linalg.norm(cam.poses[:, :3, 3] - root, axis=1), cam.yfov,
                                       self.plan.panel[1]))
                   for cam in (self.plan.cameras or (self.plan.camera,)))

    def _contact_shadow(self):
        """The :class:`~usdmotion.render.shadow.ContactShadow` under the main body (None: no body)."""
        main = self.actors[0]
        if main.body is None:
            return None
        size = main.body.size * main.scale
        shadow = ContactShadow(0.3 * size, self.plan.ground, size)
        self.scenes[0].add(shadow.dynamic.mesh)
        return shadow

    def _plot_strip(self, motion: Motion):
        """The ``--panel`` :class:`~usdmotion.render.panel.PlotStrip`: curves at every source frame."""
        plan, options = self.plan, self.options
        items = parse_panel(options.panel)
        every = np.arange(plan.frames.min(), plan.frames.max() + 1)
        return PlotStrip(panel_series(motion, items, every), every / motion.fps, options.width,
                         strip_height(options.height, len(items)), cursor_times=plan.frames / motion.fps)

    def _view_cameras(self, pyrender) -> list:
        """``--layout``: one camera node per view in the one scene."""
        nodes = []
        for cam in self.plan.cameras:
            camera = pyrender.PerspectiveCamera(yfov=cam.yfov, aspectRatio=self.plan.panel[0] / self.plan.panel[1],
                                                znear=cam.znear, zfar=cam.zfar)
            nodes.append(self.scenes[0].add(camera, pose=cam.poses[0]))
        return nodes

    def _angles(self, motion: Motion):
        """The :class:`~usdmotion.render.angles.AngleOverlay` of ``--angle`` on the main view."""
        plan = self.plan
        specs = [parse_angle(motion, text) for text in self.options.angles]
        joints = self.frame_joints
        values = angle_values(specs, joints, np.array([0.0, 1.0, 0.0]))  # bends: invariant to units and axes
        index = np.array([s.joints for s in specs])  # (K, 3); -1 (trunk's third) is replaced when drawn
        points = project_frames(joints[:, index.reshape(-1)], plan.camera.poses, plan.camera.yfov, *plan.panel)
        return AngleOverlay(specs, values, points.reshape(len(plan.frames), len(specs), 3, 2), plan.panel[1])

    def _scene(self, pyrender):
        scene = pyrender.Scene(bg_color=np.array(COLORS["background"]), ambient_light=np.full(3, 0.45))
        cam = self.plan.camera
        camera = pyrender.PerspectiveCamera(yfov=cam.yfov, aspectRatio=self.plan.panel[0] / self.plan.panel[1],
                                            znear=cam.znear, zfar=cam.zfar)
        scene.camera_node = scene.add(camera, pose=cam.poses[0])
        return scene

    def _add_static(self, motion: Motion, other: Motion | None) -> None:
        plan, options = self.plan, self.options
        joints = self.frame_joints
        height = float(np.ptp(joints[..., 1])) or 1.0
        forward = forward_direction(joints[:, 0], height)
        distance = float(np.median(np.linalg.norm(plan.camera.poses[:, :3, 3] - joints[:, 0], axis=1)))
        static = []
        if options.grid:
            margin = max(2.0, 2 * options.grid_scale)
            lo = joints.reshape(-1, 3).min(axis=0) - margin
            hi = joints.reshape(-1, 3).max(axis=0) + margin
            pixel = distance * 2 * np.tan(plan.camera.yfov / 2) / plan.panel[1]  # metres per pixel at the body
            # the lines' widths follow the distance from the camera: one grid per view of a layout
            for k, camera in enumerate(plan.cameras or (plan.camera,)):
                meshes = grid_mesh(lo, hi, plan.ground, options.grid_scale,
                                   max(0.0025 * distance, 1.4 * pixel, 0.004),
                                   solid=options.shadows and k == 0,  # a floor to receive the shadows
                                   eye=np.median(camera.poses[:, :3, 3], axis=0),
                                   pixel_angle=2 * np.tan(camera.yfov / 2) / plan.panel[1])
                self.view_grids.append(meshes[-1])
                static += meshes
        static += trace_meshes(motion, options.traces, plan.frames, joints, distance, self.actors[0].body)
        for scene in self.scenes:
            add_lights(scene, forward)
            for mesh in static:
                scene.add(mesh)

    def run(self, emit, progress, timings: dict) -> None:
        """Render every frame; ``emit(images, index)`` receives each frame's rendered views, which
        :meth:`finish` turns into the output image (on the writer thread: see
        :class:`~usdmotion.render.output.WriterThread`).

        The next chunk of frames is skinned on a helper thread while this one renders (NumPy
        releases the GIL): the skinning leaves the rendering thread's path.
        """
        from concurrent.futures import ThreadPoolExecutor

        plan, options = self.plan, self.options
        draw = wait = 0.0
        n = len(plan.frames)
        # a short first chunk: the first frame waits for its skinning, the next ones are skinned meanwhile
        bounds = np.unique(np.r_[0, np.arange(FIRST_CHUNK, n, CHUNK), n].clip(0, n))
        chunks = [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
        with ThreadPoolExecutor(1, thread_name_prefix="usdmotion-skin") as pool:
            skinned = pool.submit(self._skin, chunks[0])
            for c, index in enumerate(chunks):
                t0 = time.perf_counter()
                chunk = skinned.result()
                wait += time.perf_counter() - t0
                if c + 1 < len(chunks):
                    skinned = pool.submit(self._skin, chunks[c + 1])
                for k, i in enumerate(index):
                    t0 = time.perf_counter()
                    self.renderer._platform.make_current()
                    for actor, data in zip(self.actors, chunk):
                        actor.update(k, data)
                    if self.shadow is not None:
                        self.shadow.update(chunk[0].joints[k])
                    images = self._render(i)
                    draw += time.perf_counter() - t0
                    emit(images, int(i))
                    if progress is not None:
                        progress(int(i) + 1, n, "rendering")
        timings.update(skin=self.skin_seconds, skin_wait=wait, render=draw)

    def _skin(self, index: np.ndarray) -> list:
        """Every actor's :class:`Skinned` frames ``index`` (on the helper thread)."""
        t0 = time.perf_counter()
        out = [actor.skin(index) for actor in self.actors]
        self.skin_seconds += time.perf_counter() - t0
        return out

    def _render(self, i: int) -> list[np.ndarray]:
        """The views of output frame ``i``: ``(H, W, 4)`` uint8 RGBA images (alpha meaningless), one per view."""
        plan, options = self.plan, self.options
        images = []
        if self.view_nodes:
            scene = self.scenes[0]
            for view, (node, cam) in enumerate(zip(self.view_nodes, plan.cameras)):
                for k, grid in enumerate(self.view_grids):
                    grid.is_visible = k == view
                scene.main_camera_node = node
                scene.set_pose(node, cam.poses[i])
                images.append(render_rgba(self.renderer, scene, options.shadows))
        else:
            for scene in self.scenes:
                scene.set_pose(scene.camera_node, plan.camera.poses[i])
                images.append(render_rgba(self.renderer, scene, options.shadows))
        return images

    def finish(self, images: list[np.ndarray], i: int) -> np.ndarray:
        """The output image of frame ``i`` from its rendered views: angle arcs and labels, the
        frame/time text, the views composed with the plot strip (see :meth:`_compose`)."""
        rgb = [image[..., :3] for image in images]  # drawn into in place
        if self.angles is not None:
            self.angles.draw(rgb[0], i)
        if self.options.overlay:
            self._overlay(rgb, i)
        return self._compose(images, i)

    def _compose(self, images: list[np.ndarray], i: int) -> np.ndarray:
        """The output frame: views side by side (or in the layout's grid, padded to the
        output size), the plot strip under them; ``(H, W, C)`` as the views (RGBA: the encoder
        takes it as it is, no repacking)."""
        rows, cols = self.plan.grid_shape
        if self.view_nodes:
            block = np.vstack([np.hstack(images[r * cols:(r + 1) * cols]) for r in range(rows)])
        else:
            block = images[0] if len(images) == 1 else np.hstack(images)
        parts = [block] if self.strip is None else [block, None]
        height = self.options.height - (0 if self.strip is None else self.strip.image.shape[0])
        if block.shape[:2] != (height, self.options.width):  # panels rounded down: pad with the background
            pad = np.empty((height, self.options.width, block.shape[2]), np.uint8)
            pad[...] = np.asarray(block[0, 0])
            pad[:block.shape[0], :block.shape[1]] = block
            parts[0] = pad
        if self.strip is not None:
            strip = self.strip.frame(i)
            parts[1] = strip if block.shape[2] == 3 else np.dstack([strip, np.full(strip.shape[:2], 255, np.uint8)])
        return np.ascontiguousarray(parts[0] if len(parts) == 1 else np.vstack(parts))

    def _overlay(self, images: list[np.ndarray], i: int) -> None:
        plan = self.plan
        if self.view_nodes:
            names = [c.strip() for c in self.options.camera.split(",")]
            for name, image in zip(names, images):
                draw_text(image, [f"{name}   frame {plan.frames[i]}   {plan.times[i]:7.3f} s"])
            return
        main = f"frame {plan.frames[i]}   {plan.times[i]:7.3f} s"
        names = [label for label in self.labels]
        if self.side:
            draw_text(images[0], [names[0], main] if names[0] else [main])
            draw_text(images[1], [clock_text(plan.alignment, i, self.other_fps, names[1])])
            return
        lines = [names[0], main] if names[0] else [main]
        if plan.other_frames is not None:
            lines.append("ghost " + clock_text(plan.alignment, i, self.other_fps, names[1]))
        draw_text(images[0], lines)

    def close(self) -> None:
        renderer = getattr(self, "renderer", None)
        if renderer is not None:
            renderer.delete()
            self.renderer = None
