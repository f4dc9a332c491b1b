// One take drawn in the scene: stick figure (from the server's joint positions), the skinned
// body (GLB from the server, skinned on the GPU by three.js), a trace; all in one group so a
// compare ghost can be moved by the spatial alignment.
import * as THREE from 'three';

// The glTF loader is fetched when the first body is (the stick figure is drawn without it).
let addons = null;
const loadAddons = () => addons || (addons = Promise.all([import('three/addons/loaders/GLTFLoader.js'),
                                                         import('three/addons/utils/SkeletonUtils.js')]));

/** The material of the stick figures' bones and the floor grid: lines coloured per vertex. A raw shader
 *  of a few lines instead of three.js's LineBasicMaterial (its program carries every chunk three.js
 *  may need): software WebGL (SwiftShader) compiles it before the first frame of a take, with the
 *  page waiting: 16 ms against 127 for three.js's after a fresh start (benchmarks/studio_url.py). */
export function lineMaterial({opacity = 1, transparent = false, depthTest = true} = {}) {
  return new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3, transparent, depthTest, uniforms: {opacity: {value: opacity}},
    vertexShader: `uniform mat4 modelViewMatrix, projectionMatrix;
in vec3 position, color;
out vec3 vColor;
void main() { vColor = color; gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
    fragmentShader: `precision mediump float;
uniform float opacity;
in vec3 vColor;
out vec4 colour;
void main() {  // linear colours (three.js's working space) to the canvas's sRGB, as three.js's own shaders end
  vec3 srgb = mix(1.055 * pow(vColor, vec3(1.0 / 2.4)) - 0.055, 12.92 * vColor, vec3(lessThanEqual(vColor, vec3(0.0031308))));
  colour = vec4(srgb, opacity);
}`});
}

export class Figure {
  constructor(take, {color = 0x1f5fbf, opacity = 1} = {}) {
    this.take = take;
    this.J = take.joint_names.length;
    this.group = new THREE.Group();
    this.color = color;
    this.opacity = opacity;
    this.bones = take.parents.map((p, j) => [j, p]).filter(([, p]) => p >= 0);
    const transparent = opacity < 1;
    const lineGeometry = new THREE.BufferGeometry();
    lineGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(this.bones.length * 6), 3));
    // the colour per vertex, as the floor grid has it: one shader program for both (a program is a
    // costly compile in software WebGL, before the first frame)
    const rgb = new THREE.Color(color).toArray();
    lineGeometry.setAttribute('color', new THREE.BufferAttribute(
      Float32Array.from({length: this.bones.length * 6}, (_, i) => rgb[i % 3]), 3));
    this.stick = new THREE.LineSegments(lineGeometry, lineMaterial({transparent, opacity, depthTest: !transparent}));
    const sphere = new THREE.SphereGeometry(0.025, 10, 8);
    this.joints = new THREE.InstancedMesh(sphere,
      new THREE.MeshStandardMaterial({color, transparent, opacity}), this.J);
    this.stickGroup = new THREE.Group();
    this.stickGroup.add(this.stick, this.joints);
    this.group.add(this.stickGroup);
    this.body = null;
    this.mixer = null;
    this.traces = [];
    this.frame = 0;
  }

  /** Joint j's position at frame f (metres, viewer axes), from the server's array. */
  joint(f, j) {
    const i = (f * this.J + j) * 3, p = this.take.positions;
    return new THREE.Vector3(p[i], p[i + 1], p[i + 2]);
  }

  setFrame(frame) {
    const f = Math.max(0, Math.min(this.take.frames - 1, Math.round(frame)));
    this.frame = f;
    const p = this.take.positions, base = f * this.J * 3;
    const line = this.stick.geometry.attributes.position.array;
    this.bones.forEach(([j, q], b) => {
      for (let k = 0; k < 3; k++) {
        line[b * 6 + k] = p[base + j * 3 + k];
        line[b * 6 + 3 + k] = p[base + q * 3 + k];
      }
    });
    this.stick.geometry.attributes.position.needsUpdate = true;
    this.stick.geometry.computeBoundingSphere();
    const m = new THREE.Matrix4();
    for (let j = 0; j < this.J; j++) {
      m.makeTranslation(p[base + j * 3], p[base + j * 3 + 1], p[base + j * 3 + 2]);
      this.joints.setMatrixAt(j, m);
    }
    this.joints.instanceMatrix.needsUpdate = true;
    this.joints.computeBoundingSphere();
    if (this.mixer) this.mixer.setTime(f / this.take.fps);
  }

  /** Load the skinned body GLB (a URL, or a promise of its bytes); resolves false (stick figure
   *  only) where the server has none. */
  async loadBody(glb) {
    let gltf;
    try {
      const [{GLTFLoader}, {clone}] = await loadAddons();
      this.cloneSkinned = clone;
      gltf = await (typeof glb === 'string' ? new GLTFLoader().loadAsync(glb)
                                            : new GLTFLoader().parseAsync(await glb, ''));
    } catch (e) {
      return false;
    }
    const body = gltf.scene;
    body.traverse(o => {
      if (o.isMesh) {
        o.frustumCulled = false;
        o.material = new THREE.MeshStandardMaterial({color: this.opacity < 1 ? 0xd07020 : 0xc8b8a8, roughness: 0.8,
          transparent: this.opacity < 1, opacity: this.opacity < 1 ? 0.4 : 1, depthWrite: this.opacity >= 1});
      }
    });
    this.body = body;
    this.clips = gltf.animations;
    if (gltf.animations.length) {
      this.mixer = new THREE.AnimationMixer(body);
      this.mixer.clipAction(gltf.animations[0]).play();
    }
    this.group.add(body);
    this.setFrame(this.frame);
    return true;
  }

  /** Paths over frames first..last: ``lines`` = [[values (F*3), colour], ...] (replaces the previous ones). */
  setTraces(lines, first, last) {
    this.traces.forEach(t => { this.group.remove(t); t.geometry.dispose(); });
    this.traces = lines.map(([values, color]) => {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(values.slice(first * 3, (last + 1) * 3), 3));
      const line = new THREE.Line(g, new THREE.LineBasicMaterial({color, transparent: this.opacity < 1,
                                                                  opacity: this.opacity}));
      this.group.add(line);
      return line;
    });
  }

  /** Positions (n*3) of one joint over all frames, for a trace. */
  jointPath(j) {
    const out = new Float32Array(this.take.frames * 3), p = this.take.positions;
    for (let f = 0; f < this.take.frames; f++) {
      const i = (f * this.J + j) * 3;
      out[f * 3] = p[i]; out[f * 3 + 1] = p[i + 1]; out[f * 3 + 2] = p[i + 2];
    }
    return out;
  }

  /** A static copy of the figure at frame f (stroboscope). */
  snapshot(f, opacity) {
    const copy = new Figure(this.take, {color: this.color, opacity});
    copy.setFrame(f);
    copy.stickGroup.visible = this.stickGroup.visible;  // as the player shows it (the body's clone keeps its own)
    const g = new THREE.Group();
    g.add(copy.stickGroup);
    if (this.body && this.clips && this.clips.length) {
      const body = this.cloneSkinned(this.body);
      const mixer = new THREE.AnimationMixer(body);
      mixer.clipAction(this.clips[0]).play();
      mixer.setTime(f / this.take.fps);
      g.add(body);
    }
    return g;
  }

  dispose() {
    this.group.traverse(o => { if (o.geometry) o.geometry.dispose(); });
  }
}
