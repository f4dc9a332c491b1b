// Studio page: wires the library, the player, the plots and compare, and keeps every view
// state in the URL (take, frame, range, camera, speed, compare, plots) so a link reopens it.
// Only what draws a take's first frame is imported here; the tool panels (segmentation, edits,
// retarget, video) are imported once that frame is drawn (see loadPanels).
import {getJSON, loadTake, takeGlb} from './api.js';
import {LibraryView} from './library.js';
import {Player} from './player.js';
import {Plots} from './plots.js';

performance.mark('main');
const $ = id => document.getElementById(id);
const params = new URLSearchParams(location.search);
const state = {
  take: params.get('take'), frame: +(params.get('f') || 0), range: parseRange(params.get('range')),
  cam: params.get('cam') || 'side', orbit: (params.get('orbit') || '').split(',').filter(Boolean).map(Number),
  speed: +(params.get('speed') || 1), compare: params.get('cmp') || '', align: params.get('align') || 'dtw',
  offset: +(params.get('off') || 0), space: params.get('space') || 'root', alignFrame: +(params.get('af') || 0),
  joints: (params.get('joints') || '').split(',').filter(Boolean),
  q: (params.get('q') || 'bend').split(',').filter(Boolean),
  stick: params.get('stick') !== '0', body: params.get('body') !== '0', grid: params.get('grid') !== '0',
  trace: params.get('trace') === 'com' ? '' : params.get('trace') || '', loop: params.get('loop') !== '0',
  comTrace: params.get('comtrace') === '1' || params.get('trace') === 'com',
  seg: params.get('seg') === '1',
};
let take = null, ghostTake = null, ghostMap = null, series = null, ghostSeries = null;
const asked = {series: 0, compare: 0};  // only the latest request of each kind may update the page
let takeShown = null;  // resolves when the take opened first has its first frame (or failed)
const shown = new Promise(resolve => { takeShown = resolve; });

function parseRange(text) {
  const m = /^(\d+)-(\d+)$/.exec(text || '');
  return m ? [+m[1], +m[2]] : null;
}

// A linked page keeps the address it came with until its take's first frame is on the screen (see
// urlHeld below): in a software-rendered browser every new address repaints the browser's own window
// (its address bar) on the GPU process's one thread, about 100 ms at 1800x1200, and the take's first
// frame waited behind it (benchmarks/studio_url.py, traced)
let urlHeld = !!state.take;

function writeUrl() {
  if (urlHeld) return;
  const p = new URLSearchParams();
  if (state.take) p.set('take', state.take);
  p.set('f', player.frame);
  if (player.range) p.set('range', player.range.join('-'));
  p.set('cam', player.cameraMode);
  if (player.cameraMode === 'orbit') p.set('orbit', player.cameraPose().join(','));
  if (state.speed !== 1) p.set('speed', state.speed);
  if (state.compare) {
    p.set('cmp', state.compare); p.set('align', state.align); p.set('space', state.space);
    if (state.align === 'offset') p.set('off', state.offset);
    p.set('af', state.alignFrame);
  }
  if (state.joints.length) p.set('joints', state.joints.join(','));
  p.set('q', state.q.join(','));
  for (const k of ['stick', 'body', 'grid', 'loop']) if (!state[k]) p.set(k, '0');
  if (state.trace) p.set('trace', state.trace);
  if (state.comTrace) p.set('comtrace', '1');
  if ($('segment-panel').open) p.set('seg', '1');
  history.replaceState(null, '', `?${p}`);
}

// A linked take's arrays (asked for by index.html) are read before the player opens the WebGL context,
// which waits for the browser's GPU process to start (see index.html): they are read meanwhile.
const linkedId = state.take;
let linkedTake = linkedId ? loadTake(linkedId) : null;
if (linkedTake) await linkedTake.catch(() => null);  // a failure is shown by openTake
const player = new Player(frame => {
  const t = frame / player.fps;
  $('readout').textContent = `frame ${frame} / ${player.frames - 1} · ${t.toFixed(3)} s`;
  $('scrub').value = frame;
  plots.setTime(t);
  if (segments) segments.setFrame(frame);
  if (!player.playing) writeUrl();
});
// a linked page shows its view alone until the take's first frame is on the screen (index.html): the
// canvas is the only content, so the first contentful paint is that frame's
player.onFirstFrame = () => {
  player.onFirstFrame = null;
  window.early.release();  // the page is rendered from now on, this frame first
  new PerformanceObserver((list, observer) => {
    if (list.getEntriesByName('first-contentful-paint').length) { observer.disconnect(); window.early.reveal(); }
  }).observe({type: 'paint', buffered: true});
};
// the joint spheres' lit program (left out of a linked take's first frame) is compiled once it is on the screen
Promise.all([window.early.revealed, shown]).then(() => {
  if (!player.jointsCompiled && player.figure) player.compileJoints();
});
player.holdEmpty = !!state.take;  // and draws nothing before its take: the first frame drawn is the take's
player.onStop = () => { $('play').textContent = '▶'; writeUrl(); };
player.onOrbit = () => { player.cameraMode = 'orbit'; $('camera').value = 'orbit'; };
player.onCamera = () => { clearTimeout(player.urlTimer); player.urlTimer = setTimeout(writeUrl, 300); };
if (urlHeld) window.early.revealed.then(() => { urlHeld = false; writeUrl(); });
performance.mark('player');
const plots = new Plots($('plots'), t => player.setFrame(Math.round(t * player.fps)));
const library = new LibraryView($('takes'), $('filter'), $('library-status'), id => openTake(id, true));
// the tool panels (edits, retarget, video) see the page through these few hooks
const tools = {player, plots, take: () => take, state, reopen: () => openTake(state.take, false),
  plotQuery: () => ({joints: state.joints.join(','), q: state.q.join(',')}),
  refreshLibrary: async () => { await library.load(); await library.fill(); fillTakeLists(); }};
let segments = null, edits = null, retargeting = null, panelsLoaded = null;
const PANELS = '.tool-panel, #segment-panel';

/** Import and mount the tool panels (once; resolves when they are there). A fresh page on a take's
 *  URL draws the take first: these modules, their requests and their uPlot are not needed for that. */
function loadPanels() {
  return panelsLoaded || (panelsLoaded = Promise.all(['segment', 'edits', 'retarget', 'video']
    .map(name => import(`./${name}.js`))).then(([{SegmentEditor}, {mountEdits}, {mountRetarget}, {mountVideo}]) => {
    segments = new SegmentEditor($('segment-panel'), {player, seek: f => player.setFrame(f),
      setRange: r => { player.range = state.range = r; showRange(); applyTrace(); writeUrl(); },
      playToggle: () => $('play').click(), refreshLibrary: () => tools.refreshLibrary()});
    edits = mountEdits(tools);
    retargeting = mountRetarget(tools);
    mountVideo(tools);
    document.querySelectorAll(PANELS).forEach(panel => blurAfterClick(panel));
    if (take) { segments.setTake(take); segments.setFrame(player.frame); edits.opened(take); retargeting.opened(take); }
    fillTakeLists();
  }));
}

async function openTake(id, fresh) {
  player.openedAt = performance.now();
  if (fresh) {
    Object.assign(state, {frame: 0, range: null, compare: '', joints: [], alignFrame: 0});
    ghostTake = ghostMap = ghostSeries = null;
    $('compare').value = '';
    $('compare-status').textContent = '';
  }
  state.take = id;
  library.select(id);
  $('player').hidden = false;
  $('welcome').hidden = true;
  $('view-message').textContent = 'loading…';
  try {
    const loading = linkedTake && id === linkedId ? linkedTake : loadTake(id);
    linkedTake = null;
    take = await loading;
    performance.mark('take');
  } catch (e) {
    const line = e.message;  // the server's line: the CLI's for the same file (usdmotion: error: FILE[:LINE]: ...)
    if (player.figure) {  // the take shown before stays, with the line under it
      $('view-message').textContent = line;
      $('view-message').className = 'error-text';
    } else {  // nothing to play (a link to a take that is missing or fails to read): the line alone
      $('view-message').textContent = '';
      $('player').hidden = true;
      $('welcome').hidden = false;
      $('open-error').textContent = line;
    }
    if (segments) segments.setTake(null);
    player.holdEmpty = false;
    window.early.reveal();
    takeShown();
    return;
  }
  $('open-error').textContent = '';
  $('view-message').className = '';
  $('take-name').textContent = id.split('/').slice(1).join('/');
  const figure = player.setTake(take);
  $('scrub').max = take.frames - 1;
  player.range = state.range && state.range[1] < take.frames ? state.range : null;
  showRange();
  player.speed = state.speed;
  $('speed').value = String(state.speed);
  applyToggles();
  player.setCamera(state.cam, state.orbit.length === 6 ? state.orbit : null);
  $('camera').value = state.cam;
  fillJoints();
  if (segments) segments.setTake(take);
  player.setFrame(state.frame);
  if (edits) { edits.opened(take); retargeting.opened(take); }
  player.draw();
  takeShown();
  $('view-message').textContent = 'body: loading…';
  // the body first, then the plots (their analysis would slow the body's first build on the server)
  const glb = window.early.revealed.then(() => takeGlb(id));
  await Promise.all([glb.catch(() => null).then(loadSeries), state.comTrace && take.comLoaded.then(applyTrace),
                     state.compare ? openCompare() : Promise.resolve(), (async () => {
    const ok = await figure.loadBody(glb);
    $('view-message').textContent = ok ? '' : 'no skinned body from this server: stick figure';
    applyToggles();
  })()]);
  document.body.dataset.ready = '1';
  writeUrl();
}

function fillJoints() {
  const names = take.joint_names.filter((n, j) => !take.end_sites[j]);
  if (!state.joints.length) state.joints = names.filter(n => /(knee|leg$|elbow|forearm)/i.test(n)).slice(0, 2);
  if (!state.joints.length) state.joints = names.slice(1, 3);
  $('joints').replaceChildren(...names.map(n => new Option(n, n, false, state.joints.includes(n))));
  const trace = $('trace');
  trace.replaceChildren(new Option('none', ''), ...names.map(n => new Option(n, n)));
  trace.value = state.trace;
  $('com-trace').checked = state.comTrace;
  document.querySelectorAll('input[name=q]').forEach(c => { c.checked = state.q.includes(c.value); });
}

async function loadSeries() {
  const ask = id => getJSON('/api/series', {take: id, joints: state.joints.join(','), q: state.q.join(',')});
  const mine = ++asked.series;
  try {
    const [mainSeries, otherSeries] = await Promise.all([ask(take.id),
      ghostTake ? ask(ghostTake.id).catch(() => null) : null]);
    if (mine !== asked.series) return;
    [series, ghostSeries] = [mainSeries, otherSeries];
    await plots.show(series, ghostSeries, ghostMap);
    plots.setTime(player.frame / player.fps);
  } catch (e) {
    $('plots').textContent = `plots: ${e.message}`;
  }
}

function applyToggles() {
  for (const fig of [player.figure, player.ghost].filter(Boolean)) {
    fig.stickGroup.visible = state.stick;
    if (fig.body) fig.body.visible = state.body;
  }
  player.grid.visible = state.grid;
  $('show-stick').checked = state.stick; $('show-body').checked = state.body; $('show-grid').checked = state.grid;
  $('loop').checked = state.loop;
  player.loop = state.loop;
  applyTrace();
  player.dirty = true;
}

function applyTrace() {
  for (const fig of [player.figure, player.ghost].filter(Boolean)) {
    const ghost = fig !== player.figure, lines = [];
    if (state.comTrace && fig.take.com) lines.push([fig.take.com, ghost ? 0xb05000 : 0xd02020]);
    const j = state.trace ? fig.take.joint_names.indexOf(state.trace) : -1;
    if (j >= 0) lines.push([fig.jointPath(j), ghost ? 0xe09040 : 0x2060d0]);
    fig.setTraces(lines, ghost ? 0 : player.first, ghost ? fig.take.frames - 1 : player.last);
  }
  player.dirty = true;
}

function showRange() {
  $('range').textContent = player.range ? `loop ${player.range[0]}–${player.range[1]}` : 'loop: whole take';
}

async function openCompare() {
  if (!state.compare || !take) {
    asked.compare++;
    player.clearGhost();
    ghostTake = ghostMap = ghostSeries = null;
    if (take) await loadSeries();
    $('compare-status').textContent = '';
    writeUrl();
    return;
  }
  $('compare-status').textContent = 'aligning…';
  $('compare-status').className = '';
  const mine = ++asked.compare;
  try {
    const [other, answer] = await Promise.all([loadTake(state.compare), getJSON('/api/compare', {
      a: take.id, b: state.compare, mode: state.align, offset: state.offset, frame: state.alignFrame})]);
    if (mine !== asked.compare) return;
    ghostTake = other;
    ghostMap = answer.map;
    if (state.comTrace) other.comLoaded.then(() => { if (player.ghost && player.ghost.take === other) applyTrace(); });
    const ghost = player.setGhost(ghostTake, ghostMap);
    player.split = state.space === 'split';
    if (state.space === 'root' || state.space === 'split') player.placeGhost(answer.align);
    if (state.space === 'side') {  // aligned, then beside the take as the camera sees it
      const [rx, rz] = player.screenRight(), s = Math.max(1, player.extent.height * 0.6);
      const m = answer.align.map(row => [...row]);
      m[0][3] += rx * s;
      m[2][3] += rz * s;
      player.placeGhost(m);
    }
    $('compare-status').textContent = `${ghostTake.id.split('/').slice(1).join('/')}: ` +
      (state.align === 'dtw' ? 'aligned in time by DTW' : `offset ${state.offset} s`);
    applyToggles();
    await loadSeries();
    await ghost.loadBody(`/api/glb?take=${encodeURIComponent(ghostTake.id)}`);
    applyToggles();
  } catch (e) {
    if (mine !== asked.compare) return;
    $('compare-status').textContent = `compare: ${e.message}`;
    $('compare-status').className = 'error-text';
    player.clearGhost();
  }
  writeUrl();
}

function setRangeEnd(which) {
  const r = player.range ? [...player.range] : [0, player.frames - 1];
  r[which] = player.frame;
  if (r[0] > r[1]) r.reverse();
  player.range = r;
  state.range = r;
  showRange();
  applyTrace();
  writeUrl();
}

function wire() {
  $('play').onclick = () => { player.play(); $('play').textContent = player.playing ? '❚❚' : '▶'; writeUrl(); };
  $('step-back').onclick = () => player.setFrame(player.frame - 1);
  $('step-fwd').onclick = () => player.setFrame(player.frame + 1);
  $('scrub').oninput = e => player.setFrame(+e.target.value);
  $('speed').onchange = e => { state.speed = +e.target.value; player.speed = state.speed; writeUrl(); };
  $('loop').onchange = e => { state.loop = e.target.checked; player.loop = state.loop; writeUrl(); };
  $('range-clear').onclick = () => { player.range = state.range = null; showRange(); applyTrace(); writeUrl(); };
  $('camera').onchange = e => { player.setCamera(e.target.value); writeUrl(); };
  for (const [box, key] of [['show-body', 'body'], ['show-stick', 'stick'], ['show-grid', 'grid']]) {
    $(box).onchange = e => { state[key] = e.target.checked; applyToggles(); writeUrl(); };
  }
  $('trace').onchange = e => { state.trace = e.target.value; applyTrace(); writeUrl(); };
  $('com-trace').onchange = async e => {
    state.comTrace = e.target.checked;
    await Promise.all([take, ghostTake].filter(Boolean).map(t => t.comLoaded));
    applyTrace();
    writeUrl();
  };
  $('joints').onchange = e => { state.joints = [...e.target.selectedOptions].map(o => o.value); loadSeries();
    writeUrl(); };
  document.querySelectorAll('input[name=q]').forEach(c => c.addEventListener('change', () => {
    state.q = [...document.querySelectorAll('input[name=q]:checked')].map(x => x.value); loadSeries(); writeUrl();
  }));
  $('compare').onchange = e => { state.compare = e.target.value; openCompare(); };
  $('align-mode').onchange = e => { state.align = e.target.value; openCompare(); };
  $('offset').onchange = e => { state.offset = +e.target.value || 0; if (state.align === 'offset') openCompare(); };
  $('align-space').onchange = e => { state.space = e.target.value; openCompare(); };
  $('align-here').onclick = () => { state.alignFrame = player.frame; state.space = 'root';
    $('align-space').value = 'root'; openCompare(); };
  $('strobe').onclick = () => {
    const link = $('strobe-png');
    link.href = player.stroboscope(Math.max(2, Math.min(40, +$('strobe-count').value || 8)));
    link.hidden = false;
    setTimeout(() => player.clearStrobe(), 4000);
  };
  blurAfterClick(document, PANELS);  // the panels' controls: when they are mounted
  window.addEventListener('keydown', e => {
    if (e.target.tagName === 'INPUT' && e.target.type !== 'range' && e.target.type !== 'checkbox') return;
    if (e.target.tagName === 'SELECT') return;
    const keys = {' ': () => $('play').click(), ArrowLeft: () => player.setFrame(player.frame - 1),
                  ArrowRight: () => player.setFrame(player.frame + 1), '[': () => setRangeEnd(0),
                  ']': () => setRangeEnd(1)};
    if (keys[e.key]) { e.preventDefault(); keys[e.key](); }
  });
  $('align-mode').value = state.align; $('offset').value = state.offset; $('align-space').value = state.space;
}

/** After a mouse click, the controls under ``root`` (but not under ``except``) give the keyboard back
 *  to the player (space = play, not 'press again'). */
function blurAfterClick(root, except = null) {
  root.querySelectorAll('button, input[type=checkbox], input[type=range]').forEach(el => {
    if (!except || !el.closest(except)) el.addEventListener(el.type === 'range' ? 'change' : 'click', () => el.blur());
  });
}

function fillTakeLists() {
  const options = library.readable().map(t => new Option(t.name, t.id));
  $('compare').replaceChildren(new Option('—', ''), ...options.map(o => o.cloneNode(true)));
  $('compare').value = state.compare;
  if (edits) { edits.libraryFilled(options); retargeting.libraryFilled(options); }
}

async function start() {
  wire();
  $('segment-panel').open = state.seg;
  $('segment-panel').addEventListener('toggle', () => writeUrl());
  // the shaders of a take's first frame, compiled while the user picks one; a linked take's arrays are
  // there by the time three.js is (the server has read the file meanwhile): its first frame compiles
  // them, a warm-up would only draw one frame more (the compare ghost's are compiled once it is drawn)
  if (!state.take) player.warmUp();
  const opening = state.take ? openTake(state.take, false) : null;
  if (opening) {  // a linked take is drawn before the library is listed (hidden until then: index.html)
    // and read, and before the panels are loaded: once that frame is on the screen (revealed), so that
    // neither the page's work nor the server's listing takes the two cores from the frame's compositing
    await Promise.race([shown, opening]);
    await window.early.revealed;
  }
  await library.load();  // the list of takes, at once
  const panels = loadPanels();
  await library.fill();
  fillTakeLists();
  await Promise.all([opening, panels]);
  if (opening) player.warmUp([0.7]);
  document.body.dataset.loaded = '1';
}

// for tests and benchmarks: read-only views of the page's state
window.studio = {player, plots, state, get segments() { return segments; }, projectJoints: () => player.figure ?
  player.figure.take.joint_names.map((_, j) => player.project(player.figure.joint(player.frame, j))) : []};
start();
