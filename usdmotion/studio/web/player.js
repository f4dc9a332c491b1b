// The 3-D view: scene, camera presets and orbit, playback clock (real time: frames are
// dropped, never slowed), loop range, compare ghost and stroboscope.
import * as THREE from 'three';
import {OrbitControls} from 'three/addons/controls/OrbitControls.js';
import {Figure, lineMaterial} from './figure.js';

export class Player {
  constructor(onFrame) {
    const {canvas, gl, antialias} = window.early.openContext();  // index.html (#canvas; blocks until the GPU process runs)
    this.canvas = canvas;
    this.onFrame = onFrame;
    this.renderer = new THREE.WebGLRenderer({canvas, context: gl, antialias});
    // no error checks after each shader compile and link: each is a round trip that waits for the GPU
    // process (busy compositing the page in software WebGL), and three's own shaders do not fail
    this.renderer.debug.checkShaderErrors = false;
    // three.js's pixel ratio is 1 already: no setPixelRatio(1), which would remake the drawing buffer
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xdfe3e6);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(3, 6, 4);
    this.scene.add(sun);
    this.grid = new THREE.GridHelper(40, 80, 0x888888, 0xbbbbbb);
    this.grid.material.dispose();
    this.grid.material = lineMaterial();  // the stick figures' program (figure.js)
    this.scene.add(this.grid);
    this.camera = new THREE.PerspectiveCamera(35, 16 / 9, 0.05, 200);
    this.controls = new OrbitControls(this.camera, canvas);
    // 'start' is a user's drag or wheel (not a preset's update): from then on the camera is 'orbit'
    this.controls.addEventListener('start', () => { if (this.onOrbit) this.onOrbit(); });
    this.controls.addEventListener('change', () => { this.dirty = true; if (this.onCamera) this.onCamera(); });
    this.figure = null;
    this.ghost = null;
    this.ghostMap = null;
    this.strobe = null;
    this.frame = 0;
    this.playing = false;
    this.speed = 1;
    this.loop = true;
    this.range = null;
    this.cameraMode = 'side';
    this.rendered = 0;      // frames drawn (benchmarks read it)
    this.playLog = [];      // [time ms, frame] of each frame drawn while playing (benchmarks read it)
    this.firstDrawnAt = this.bodyDrawnAt = null;  // when a take, then its body, were first drawn
    this.firstPixelsAt = this.bodyPixelsAt = null;  // ... and their pixels were there (window.studioTimings)
    this.jointsCompiled = false;  // the joint spheres' shader program (see compileJoints)
    this.holdEmpty = false;  // true: nothing is drawn before a take is set (a linked page: main.js)
    this.dirty = true;
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
    this.lastTick = performance.now();
    // a hidden tab gets no animation frames: resume from where it was, not from where it would be
    document.addEventListener('visibilitychange', () => { this.lastTick = performance.now(); });
    this.renderer.setAnimationLoop(now => this.tick(now));
  }

  /** Compile the figure's shaders while a take is being fetched (software WebGL takes a
   *  while): a two-joint figure of each opacity (1: a take, 0.7: a compare ghost), drawn once and dropped. */
  warmUp(opacities = [1, 0.7]) {
    const take = {joint_names: ['a', 'b'], parents: [-1, 0], frames: 1, fps: 1,
                  positions: new Float32Array([0, 0, 0, 0, 1, 0])};
    for (const opacity of opacities) {
      const figure = new Figure(take, {opacity});
      figure.setFrame(0);
      this.scene.add(figure.group);
      this.renderer.render(this.scene, this.camera);
      this.scene.remove(figure.group);
      figure.dispose();
    }
    if (opacities.includes(1)) this.jointsCompiled = true;
    this.dirty = true;  // the next frame is drawn without it
  }

  /** The joints' spheres have a lit material, a costly shader program in software WebGL: a linked
   *  take's first frame is drawn without them (the stick figure's lines and the floor share one
   *  program), and they are compiled after it (in parallel where KHR_parallel_shader_compile is) and
   *  shown when ready. */
  compileJoints() {
    this.jointsCompiled = true;
    const joints = this.figure.joints;
    this.renderer.compileAsync(joints, this.camera, this.scene)
      .then(() => { joints.visible = true; this.dirty = true; });
  }

  resize() {
    const w = this.canvas.clientWidth || 640, h = this.canvas.clientHeight || 360;
    // a new size reallocates the drawing buffer (slow in software WebGL): only when it changed
    if (w !== this.canvas.width || h !== this.canvas.height) this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.dirty = true;
  }

  get frames() { return this.figure ? this.figure.take.frames : 0; }
  get fps() { return this.figure ? this.figure.take.fps : 1; }
  get first() { return this.range ? this.range[0] : 0; }
  get last() { return this.range ? this.range[1] : Math.max(0, this.frames - 1); }

  setTake(take) {
    if (this.figure) { this.scene.remove(this.figure.group); this.figure.dispose(); }
    this.clearGhost();
    this.clearStrobe();
    this.figure = new Figure(take);
    this.figure.joints.visible = !!this.jointsCompiled;  // see compileJoints
    this.scene.add(this.figure.group);
    this.firstDrawnAt = this.bodyDrawnAt = this.firstPixelsAt = this.bodyPixelsAt = null;
    this.range = null;
    this.frame = 0;
    this.extent = this.measure(take);
    this.setFrame(0);
    this.setCamera(this.cameraMode);
    return this.figure;
  }

  /** Root path centre, travel direction (unit, horizontal) and body size, for the camera presets. */
  measure(take) {
    const f = take.frames, J = take.joint_names.length, p = take.positions;
    const root = i => new THREE.Vector3(p[i * J * 3], 0, p[i * J * 3 + 2]);
    const box = new THREE.Box3();
    for (let i = 0; i < f; i += Math.max(1, Math.floor(f / 200))) {
      for (let j = 0; j < J; j++) box.expandByPoint(new THREE.Vector3(p[(i * J + j) * 3], p[(i * J + j) * 3 + 1],
                                                                      p[(i * J + j) * 3 + 2]));
    }
    const travel = root(f - 1).sub(root(0));
    const direction = travel.length() > 0.5 ? travel.normalize() : new THREE.Vector3(0, 0, 1);
    const size = box.getSize(new THREE.Vector3());
    return {box, centre: box.getCenter(new THREE.Vector3()), direction, height: Math.max(size.y, 0.5),
            span: Math.max(size.x, size.z, size.y)};
  }

  /** Camera presets: side (perpendicular to the travel), front (facing it), top, follow, orbit. */
  setCamera(mode, pose = null) {
    this.cameraMode = mode;
    this.controls.enabled = mode === 'orbit' || mode === 'side' || mode === 'front' || mode === 'top';
    if (!this.figure) return;
    const e = this.extent, d = e.direction, side = new THREE.Vector3(d.z, 0, -d.x);
    const target = e.centre.clone();
    const distance = Math.max(e.span * 1.1, e.height * 3.2);
    let eye;
    if (mode === 'front') eye = target.clone().addScaledVector(d, distance);
    else if (mode === 'top') eye = target.clone().add(new THREE.Vector3(0, distance, 0.001));
    else if (mode === 'follow') {
      this.followCamera();
      this.dirty = true;
      return;
    } else eye = target.clone().addScaledVector(side, distance);
    if (mode === 'orbit' && pose) {
      eye = new THREE.Vector3(pose[0], pose[1], pose[2]);
      target.set(pose[3], pose[4], pose[5]);
    } else if (mode === 'orbit') {
      return;  // keep the current camera; the user orbits from here
    }
    eye.y = Math.max(eye.y, mode === 'top' ? eye.y : e.height * 0.6);
    this.camera.position.copy(eye);
    this.controls.target.copy(target);
    this.controls.update();
    this.dirty = true;
  }

  followCamera() {
    const e = this.extent, d = e.direction, side = new THREE.Vector3(d.z, 0, -d.x);
    const root = this.figure.joint(this.frame, 0);
    const target = new THREE.Vector3(root.x, e.height * 0.5, root.z);
    this.camera.position.copy(target).addScaledVector(side, e.height * 2.6 + 1.0).setY(e.height * 0.6);
    this.camera.lookAt(target);
    this.controls.target.copy(target);
  }

  cameraPose() {
    const p = this.camera.position, t = this.controls.target;
    return [p.x, p.y, p.z, t.x, t.y, t.z].map(v => +v.toFixed(3));
  }

  setFrame(frame) {
    if (!this.figure) return;
    const f = Math.max(0, Math.min(this.frames - 1, Math.round(frame)));
    this.frame = f;
    this.figure.setFrame(f);
    if (this.ghost) this.ghost.setFrame(this.ghostMap ? this.ghostMap[f] : f);
    if (this.cameraMode === 'follow') this.followCamera();
    this.dirty = true;
    if (this.onFrame) this.onFrame(f);
  }

  play(on = !this.playing) {
    if (!this.figure) return;
    this.playing = on;
    if (on) {
      if (this.frame >= this.last) this.frame = this.first;
      this.clock = this.frame / this.fps;
    }
  }

  /** Animation loop: advance the take's clock by the real time elapsed × speed. */
  tick(now) {
    const dt = (now - this.lastTick) / 1000;  // never capped: a slow frame drops frames, it does not slow time
    this.lastTick = now;
    if (this.playing && this.figure) {
      this.clock += dt * this.speed;
      let f = Math.floor(this.clock * this.fps + 1e-6);
      if (f > this.last || f < this.first) {
        if (this.loop) {
          const length = (this.last - this.first + 1) / this.fps;
          this.clock = this.first / this.fps + ((this.clock - this.first / this.fps) % length + length) % length;
          f = Math.floor(this.clock * this.fps + 1e-6);
        } else {
          f = this.last;
          this.playing = false;
          if (this.onStop) this.onStop();
        }
      }
      if (f !== this.frame) this.setFrame(f);
    }
    this.draw();
  }

  /** Draw the view if anything changed (the animation loop calls it; a take just opened draws its
   *  first frame at once with it, not one animation frame later: a busy GPU process delays those). */
  draw() {
    if (this.dirty && (this.figure || !this.holdEmpty)) {
      if (this.split && this.ghost) this.renderSplit();
      else this.renderer.render(this.scene, this.camera);
      this.rendered++;
      this.dirty = false;
      const t = performance.now();  // for benchmarks: when the take, then its body, were first drawn
      const firstBody = this.figure && this.figure.body && this.bodyDrawnAt === null;
      const firstFrame = this.figure && this.firstDrawnAt === null;
      if (firstFrame) this.firstDrawnAt = t;
      if (firstBody) this.bodyDrawnAt = t;
      // benchmarks set window.studioTimings: also when those frames' pixels were there (the GPU
      // process compiles and draws after render() returns; reading one pixel waits for it)
      if (window.studioTimings && this.figure && (this.firstPixelsAt === null || firstBody)) {
        const gl = this.renderer.getContext();
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
        if (this.firstPixelsAt === null) this.firstPixelsAt = performance.now();
        if (firstBody) this.bodyPixelsAt = performance.now();
      }
      if (firstFrame && this.onFirstFrame) this.onFirstFrame();
      if (this.playing) this.playLog.push([t, this.frame]);
      if (this.playLog.length > 4000) this.playLog.splice(0, 2000);
    }
  }

  /** Two synchronized views: the take on the left, the ghost on the right, one camera. */
  renderSplit() {
    const r = this.renderer, w = this.canvas.width, h = this.canvas.height, half = Math.floor(w / 2);
    this.camera.aspect = half / h;
    this.camera.updateProjectionMatrix();
    r.setScissorTest(true);
    for (const [x, shown, hidden] of [[0, this.figure, this.ghost], [half, this.ghost, this.figure]]) {
      shown.group.visible = true;
      hidden.group.visible = false;
      r.setViewport(x, 0, half, h);
      r.setScissor(x, 0, half, h);
      r.render(this.scene, this.camera);
    }
    r.setScissorTest(false);
    r.setViewport(0, 0, w, h);
    this.figure.group.visible = this.ghost.group.visible = true;
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  setGhost(take, frameMap) {
    this.clearGhost();
    this.ghost = new Figure(take, {color: 0xd07020, opacity: 0.7});
    this.ghostMap = frameMap;
    this.scene.add(this.ghost.group);
    this.setFrame(this.frame);
    return this.ghost;
  }

  /** Place the ghost with a 4x4 matrix (rows, column vectors; from the server's alignment). */
  placeGhost(rows) {
    if (!this.ghost) return;
    const m = new THREE.Matrix4();
    m.set(...rows.flat());
    this.ghost.group.matrixAutoUpdate = false;
    this.ghost.group.matrix.copy(m);
    this.ghost.group.matrixWorldNeedsUpdate = true;
    this.dirty = true;
  }

  clearGhost() {
    if (this.ghost) { this.scene.remove(this.ghost.group); this.ghost.dispose(); }
    this.ghost = null;
    this.ghostMap = null;
    this.dirty = true;
  }

  /** Stroboscope: n poses evenly spread over the loop range, drawn together; returns a PNG data URL. */
  stroboscope(n) {
    this.clearStrobe();
    this.strobe = new THREE.Group();
    for (let i = 0; i < n; i++) {
      const f = Math.round(this.first + (this.last - this.first) * i / Math.max(1, n - 1));
      this.strobe.add(this.figure.snapshot(f, 0.35 + 0.65 * (i + 1) / n));
    }
    this.scene.add(this.strobe);
    this.figure.group.visible = false;
    this.renderer.render(this.scene, this.camera);
    const url = this.canvas.toDataURL('image/png');
    this.dirty = true;
    return url;
  }

  clearStrobe() {
    if (this.strobe) this.scene.remove(this.strobe);
    this.strobe = null;
    if (this.figure) this.figure.group.visible = true;
    this.dirty = true;
  }

  /** The camera's right direction on the ground ``[x, z]`` (unit). */
  screenRight() {
    const e = this.camera.matrixWorld.elements, n = Math.hypot(e[0], e[2]) || 1;
    return [e[0] / n, e[2] / n];
  }

  /** Screen position (CSS pixels from the canvas's top-left) of a world point. */
  project(point) {
    const v = point.clone().project(this.camera);
    return [(v.x + 1) / 2 * this.canvas.clientWidth, (1 - v.y) / 2 * this.canvas.clientHeight];
  }
}
