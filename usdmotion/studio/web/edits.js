// Edits panel: MotionLab edits (equaliser per joint group, trim, cycle, speed curve, displacement,
// blend with a second take) previewed live: the server runs the CLI's edit pipeline and sends the
// edited positions like a take's; the edited take plays with the original as the compare ghost and
// the plots show both. Save as writes a new file in the output folder (a job) and lists it.
import {getFloats, getJSON} from './api.js';
import {JobBar, postJSON} from './jobs.js';

const $ = id => document.getElementById(id);

export function mountEdits(studio) {
  const {player, plots} = studio;
  const panel = {groups: [], bands: [], gains: {}, key: null, edited: null, timer: null, asked: 0};
  const saveBar = new JobBar($('edit-save-bar'));

  function gainsFor(name) {
    if (!panel.gains[name]) panel.gains[name] = panel.bands.map(() => 1);
    return panel.gains[name];
  }

  function drawSliders() {
    const group = $('eq-group').value;
    const gains = gainsFor(group);
    $('eq-bands').replaceChildren(...panel.bands.map((hz, b) => {
      const label = document.createElement('label');
      label.className = 'eq-band';
      const input = Object.assign(document.createElement('input'), {type: 'range', min: 0, max: 3, step: 0.05,
                                                                     value: gains[b]});
      input.dataset.band = b;
      input.setAttribute('orient', 'vertical');
      const value = document.createElement('span');
      value.textContent = `${(+gains[b]).toFixed(2)}×`;
      input.oninput = () => { gains[b] = +input.value; value.textContent = `${gains[b].toFixed(2)}×`; };
      input.onchange = () => schedule();
      label.append(value, input, document.createTextNode(hz >= 1 ? `${hz.toFixed(1)} Hz` : `${hz.toFixed(2)} Hz`));
      return label;
    }));
  }

  async function loadGroups(take) {
    panel.gains = {}; panel.key = null; panel.edited = null;
    $('edit-status').textContent = '';
    try {
      const answer = await getJSON('/api/edit/groups', {take: take.id});
      panel.groups = answer.groups; panel.bands = answer.bands_hz;
    } catch (e) {
      panel.groups = []; panel.bands = [];
      say(e.message, true);
    }
    // a choice made while the answer was on its way survives the refill
    refill('eq-group', panel.groups.map(g => new Option(g.label, g.name)));
    refill('disp-joint', take.joint_names.filter((n, j) => !take.end_sites[j]).map(n => new Option(n, n)));
    drawSliders();
  }

  function refill(id, options) {
    const chosen = $(id).value;
    $(id).replaceChildren(...options);
    if (options.some(o => o.value === chosen)) $(id).value = chosen;
  }

  function say(text, error = false) {
    $('edit-status').textContent = text;
    $('edit-status').className = error ? 'error-text' : '';
  }

  const num = id => { const v = $(id).value.trim(); return v === '' ? null : Number(v); };
  // seconds as the pipeline writes them ("1.5s"); a negative or non-number value is sent as it is,
  // so the server's check answers with its one line
  const seconds = v => (Number.isFinite(v) && v >= 0 ? `${v}s` : v);

  /** The original take's frame under the cursor (the ghost's while a preview plays). */
  function originalFrame() {
    return panel.edited && player.ghostMap ? Math.round(player.ghostMap[player.frame]) : player.frame;
  }

  /** The operations of the panel's controls, in the schema of ``usdmotion edit --pipeline``. */
  function operations() {
    const ops = [];
    for (const group of panel.groups) {
      const gains = panel.gains[group.name];
      if (!gains || gains.every(g => g === 1)) continue;
      for (const select of group.select) ops.push({op: 'equalize', gains: [...gains], ...select});
    }
    // the pipeline reads a number as frames and "1.5s" as seconds
    const rot = ['disp-rx', 'disp-ry', 'disp-rz'].map(num);
    if (rot.some(v => v)) {
      ops.push({op: 'displace', keys: [{joint: $('disp-joint').value, frame: num('disp-frame') ?? originalFrame(),
                                       rotate: rot.map(v => v || 0)}],
                ...(num('disp-falloff') !== null ? {falloff: seconds(num('disp-falloff'))} : {})});
    }
    if ($('blend-with').value) {
      const op = {op: 'blend', with: $('blend-with').value};
      if (num('blend-at') !== null) op.at = seconds(num('blend-at'));
      if (num('blend-transition') !== null) op.transition = seconds(num('blend-transition'));
      ops.push(op);
    }
    const speedText = $('edit-speed').value.trim();
    if (speedText && speedText !== '1') {
      const keys = speedText.split(',').map(s => s.trim()).filter(Boolean).map(s => s.split(':').map(Number));
      ops.push(keys.length === 1 && keys[0].length === 1 ? {op: 'speed', factor: keys[0][0]}
        : {op: 'speed', keys: keys.map(([t, v]) => [seconds(t), v])});
    }
    if (num('trim-start') !== null || num('trim-stop') !== null) {
      const op = {op: 'trim'};
      if (num('trim-start') !== null) op.start = num('trim-start');
      if (num('trim-stop') !== null) op.stop = num('trim-stop');
      ops.push(op);
    }
    if ($('cycle-on').checked) {
      const op = {op: 'cycle', loops: num('cycle-loops') || 2};
      if ($('cycle-auto').checked) op.stop = 'auto';
      ops.push(op);
    }
    return ops;
  }

  function schedule() {
    clearTimeout(panel.timer);
    panel.timer = setTimeout(preview, 120);
  }

  async function preview() {
    const take = studio.take();
    if (!take) return;
    const ops = operations();
    const mine = ++panel.asked;
    $('edit-panel').dataset.state = 'previewing';
    if (!ops.length) { await showOriginal(); return; }
    say('editing…');
    try {
      const answer = await postJSON('/api/edit/preview', {take: take.id, ops});
      const positions = await getFloats('/api/edit/positions', {key: answer.key});
      if (mine !== panel.asked) return;
      const edited = {...answer, id: `${take.id} (edited)`, positions, com: null, comLoaded: Promise.resolve(null)};
      panel.key = answer.key; panel.edited = edited; panel.ops = ops;
      const frame = player.frame;
      player.setTake(edited);
      player.setGhost(take, answer.map);
      player.setFrame(Math.min(frame, edited.frames - 1));
      $('scrub').max = edited.frames - 1;
      say(`preview: ${ops.map(o => o.op).join(' → ')}; ${edited.frames} frames at ${edited.fps} fps ` +
          '(original: orange ghost)');
      await showSeries(take, answer);
      $('edit-panel').dataset.state = 'preview';
    } catch (e) {
      if (mine !== panel.asked) return;
      say(e.message, true);
      $('edit-panel').dataset.state = 'error';
    }
  }

  async function showSeries(take, answer) {
    const q = studio.plotQuery();
    const [mine, original] = await Promise.all([getJSON('/api/edit/series', {key: answer.key, ...q}),
                                                getJSON('/api/series', {take: take.id, ...q}).catch(() => null)]);
    await plots.show(mine, original, answer.map, 'original');
  }

  async function showOriginal() {
    panel.key = null; panel.edited = null;
    say('');
    $('edit-panel').dataset.state = 'original';
    await studio.reopen();
  }

  async function save() {
    const take = studio.take();
    const ops = operations();
    if (!take || !ops.length) { say('nothing to save: no edit set', true); return; }
    const result = await saveBar.run('/api/edit/save', {take: take.id, ops, format: $('edit-format').value},
                                     'saved');
    if (result) {
      saveBar.say(`saved ${result.output}`);
      $('edit-panel').dataset.saved = result.id || '';
      await studio.refreshLibrary();
    }
  }

  $('eq-group').onchange = drawSliders;
  $('eq-reset').onclick = () => { panel.gains[$('eq-group').value] = panel.bands.map(() => 1); drawSliders(); schedule(); };
  for (const id of ['trim-start', 'trim-stop', 'edit-speed', 'cycle-on', 'cycle-auto', 'cycle-loops', 'disp-joint',
                    'disp-frame', 'disp-rx', 'disp-ry', 'disp-rz', 'disp-falloff', 'blend-with', 'blend-at',
                    'blend-transition']) {
    $(id).addEventListener('change', schedule);
  }
  $('edit-original').onclick = () => {
    panel.gains = {}; drawSliders();
    for (const id of ['trim-start', 'trim-stop', 'disp-frame', 'disp-rx', 'disp-ry', 'disp-rz', 'disp-falloff',
                      'blend-at', 'blend-transition']) $(id).value = '';
    $('edit-speed').value = '1'; $('cycle-on').checked = false; $('blend-with').value = '';
    ++panel.asked;
    showOriginal();
  };
  $('edit-save').onclick = save;
  return {
    opened: take => loadGroups(take),
    libraryFilled: options => {
      $('blend-with').replaceChildren(new Option('—', ''), ...options.map(o => new Option(o.text, o.value)));
    },
    operations,
  };
}
