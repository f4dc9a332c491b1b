"""The per-frame render loop: actors (one per motion) in one or two pyrender scenes."""

from __future__ import annotations

import time

import numpy as np

from usdmotion.errors import UsdMotionError
from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.render.gl import DynamicMesh, import_pyrender, offscreen_renderer, render_rgb
from usdmotion.render.overlay import draw_text
from usdmotion.render.scene import (COLORS, StickFigure, add_lights, grid_mesh, material, to_render_space,
                                    tube_mesh)
from usdmotion.skin import body_size, build_body, centre_of_mass, lbs, skinning_matrices

_UP_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def choose_body(motion: Motion, which: str, resolution: int):
    """The body to draw: the input's own skinned meshes (``"stage"``; ``"auto"`` when it has
    any) or the generated one (``"generated"``; ``"auto"`` otherwise)."""
    if which not in ("auto", "stage", "generated"):
        raise UsdMotionError(f"--body must be auto, stage or generated, got {which!r}")
    if which != "generated" and motion.meshes:
        from usdmotion.skin_stage import stage_body

        body = stage_body(motion)
        if body is not None:
            return body
    if which == "stage":
        raise UsdMotionError("--body stage: the input has no skinned mesh that fits its skeleton")
    return build_body(motion, resolution=resolution)


class Actor:
    """One motion's body and/or stick figure, skinned a chunk of frames at a time."""

    def __init__(self, motion: Motion, frames: np.ndarray, style: str, resolution: int, ghost: bool,
                 body: str = "auto"):
        self.motion, self.frames = motion, frames
        self.local_t = local_translations(motion)
        self.turn = (_UP_Z if motion.up_axis == "Z" else np.eye(3)) * 1.0
        self.scale = motion.meters_per_unit
        self.body = self.stick = None
        self.nodes = []
        self.inset = 0.0
        if style in ("body", "both"):
            self.body = choose_body(motion, body, resolution)
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
            rest_len = np.linalg.norm(motion.offsets[1:], axis=1)
            bones = np.flatnonzero(rest_len > 1e-6 * body_size(motion)) + 1
            joint_color = COLORS["ghost_stick"] if ghost else COLORS["joint"]
            self.stick = StickFigure(motion.parents, bones, 0.012 * body_size(motion) * self.scale,
                                     np.float32(COLORS["bone"]), np.float32(joint_color))
            self.nodes.append(self.stick.dynamic.mesh)

    def _space(self, points: np.ndarray) -> np.ndarray:
        return (points * self.scale) @ self.turn.T

    def prepare(self, index: np.ndarray) -> None:
        """Skin the output frames ``index`` (one chunk) at once."""
        frames = self.frames[index]
        world_q, world_p = fk_arrays(self.motion.rotations[frames], self.local_t[frames], self.motion.parents)
        self.joints = self._space(world_p)
        if self.body is not None:
            matrices = skinning_matrices(world_q, world_p, self.body.bind_transforms)
            positions, normals = lbs(self.body.vertices, self.weights, matrices, self.body.normals)
            self.normals = normals @ self.turn.T
            self.positions = self._space(positions) - self.inset * self.normals

    def update(self, k: int) -> None:
        if self.body is not None:
            self.body_mesh.update(self.positions[k], self.normals[k])
        if self.stick is not None:
            self.stick.update(self.joints[k])


class Views:
    """Scenes, camera, renderer; :meth:`run` renders every planned frame."""

    def __init__(self, motion: Motion, other: Motion | None, plan, options):
        pyrender = import_pyrender()
        self.plan, self.options = plan, options
        self.side = other is not None and options.compare_mode == "side"
        self.actors = [Actor(motion, plan.frames, options.style, options.body_resolution, ghost=False,
                             body=options.body)]
        if other is not None:
            self.actors.append(Actor(other, plan.other_frames, options.style, options.body_resolution,
                                     ghost=not self.side))
        self.labels = options.labels
        scenes = [self._scene(pyrender) for _ in range(2 if self.side else 1)]
        for i, actor in enumerate(self.actors):
            for mesh in actor.nodes:
                scenes[i if self.side else 0].add(mesh)
        self.scenes = scenes
        self._add_static(motion, other)
        self.renderer = offscreen_renderer(*plan.panel, msaa=options.msaa)

    def _scene(self, pyrender):
        scene = pyrender.Scene(bg_color=np.array(COLORS["background"]), ambient_light=np.full(3, 0.45))
        cam = self.plan.camera
        camera = pyrender.PerspectiveCamera(yfov=cam.yfov, aspectRatio=self.plan.panel[0] / self.plan.panel[1],
                                            znear=cam.znear, zfar=cam.zfar)
        scene.camera_node = scene.add(camera, pose=cam.poses[0])
        return scene

    def _add_static(self, motion: Motion, other: Motion | None) -> None:
        from usdmotion.render.camera import forward_direction

        plan, options = self.plan, self.options
        main = self.actors[0]
        main.prepare(np.arange(min(len(plan.frames), 1)))
        joints = to_render_space(fk_arrays(motion.rotations[plan.frames], main.local_t[plan.frames],
                                           motion.parents)[1], motion.meters_per_unit, motion.up_axis)
        height = float(np.ptp(joints[..., 1])) or 1.0
        forward = forward_direction(joints[:, 0], height)
        distance = float(np.median(np.linalg.norm(plan.camera.poses[:, :3, 3] - joints[:, 0], axis=1)))
        static = []
        if options.grid:
            margin = max(2.0, 2 * options.grid_scale)
            lo = joints.reshape(-1, 3).min(axis=0) - margin
            hi = joints.reshape(-1, 3).max(axis=0) + margin
            static += grid_mesh(lo, hi, plan.ground, options.grid_scale, max(0.0025 * distance, 0.004),
                              solid=options.shadows)  # a floor to receive the shadows
        for k, name in enumerate(options.traces):
            path = self._trace_path(motion, name, joints)
            color = COLORS["traces"][k % len(COLORS["traces"])]
            static.append(tube_mesh(path, max(0.0015 * distance, 0.003), color))
        for scene in self.scenes:
            add_lights(scene, forward)
            for mesh in static:
                scene.add(mesh)

    def _trace_path(self, motion: Motion, name: str, joints: np.ndarray) -> np.ndarray:
        if name.lower() in ("com", "centre_of_mass", "center_of_mass"):
            actor = self.actors[0]
            body = actor.body if actor.body is not None else build_body(motion, resolution=48)
            return to_render_space(centre_of_mass(motion, body, self.plan.frames), motion.meters_per_unit,
                                   motion.up_axis)
        try:
            return joints[:, motion.joint_index(name)]
        except KeyError as exc:
            raise UsdMotionError(f"--trace: {exc.args[0]}") from None

    def run(self, emit, progress, timings: dict) -> None:
        """Render every frame; ``emit(image, index)`` receives each finished image."""
        plan, options = self.plan, self.options
        skin = draw = 0.0
        n = len(plan.frames)
        for start in range(0, n, 32):
            index = np.arange(start, min(start + 32, n))
            t0 = time.perf_counter()
            for actor in self.actors:
                actor.prepare(index)
            skin += time.perf_counter() - t0
            for k, i in enumerate(index):
                t0 = time.perf_counter()
                self.renderer._platform.make_current()
                for actor in self.actors:
                    actor.update(k)
                images = []
                for scene in self.scenes:
                    scene.set_pose(scene.camera_node, plan.camera.poses[i])
                    images.append(render_rgb(self.renderer, scene, options.shadows))
                if options.overlay:
                    self._overlay(images, i)
                image = images[0] if len(images) == 1 else np.ascontiguousarray(np.hstack(images))
                draw += time.perf_counter() - t0
                emit(image, int(i))
                if progress is not None:
                    progress(int(i) + 1, n, "rendering")
        timings.update(skin=skin, render=draw)

    def _overlay(self, images: list[np.ndarray], i: int) -> None:
        plan = self.plan
        main = f"frame {plan.frames[i]}   {plan.times[i]:7.3f} s"
        names = [label for label in self.labels]
        if self.side:
            draw_text(images[0], [names[0], main] if names[0] else [main])
            other = f"frame {plan.other_frames[i]}"
            draw_text(images[1], [names[1], other] if names[1] else [other])
            return
        lines = [names[0], main] if names[0] else [main]
        if plan.other_frames is not None:
            lines.append(f"ghost: {names[1] or 'compare'}  frame {plan.other_frames[i]}")
        draw_text(images[0], lines)

    def close(self) -> None:
        renderer = getattr(self, "renderer", None)
        if renderer is not None:
            renderer.delete()
            self.renderer = None
