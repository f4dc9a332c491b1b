// Retarget panel: choose a target rig (a take of the library, or the take's own rig with joints
// removed), see the automatic joint map and what could not be mapped, retarget as a job with a
// progress bar, then play the target with the source as the ghost and the per-joint error;
// Save as USD or BVH (the CLI's writer). Every number comes from usdmotion.ops.retarget.
import * as THREE from 'three';
import {getFloats, getJSON} from './api.js';
import {JobBar, postJSON} from './jobs.js';

const $ = id => document.getElementById(id);

export function mountRetarget(studio) {
  const {player} = studio;
  const runBar = new JobBar($('rt-run-bar'));
  const saveBar = new JobBar($('rt-save-bar'));
  let result = null;

  function say(text, error = false) {
    $('retarget-status').textContent = text;
    $('retarget-status').className = error ? 'error-text' : '';
  }

  function request() {
    const take = studio.take();
    const body = {take: take.id, remove: $('rt-remove').value, scale: $('rt-scale').value,
                  lengths: $('rt-lengths').value};
    if ($('rt-target').value) body.target = $('rt-target').value;
    if ($('rt-source-profile').value && $('rt-target-profile').value) {
      body.profiles = [$('rt-source-profile').value, $('rt-target-profile').value];
    }
    return body;
  }

  function table(rows, head) {
    const t = document.createElement('table');
    t.className = 'rt-table';
    t.innerHTML = `<thead><tr>${head.map(h => `<th>${h}</th>`).join('')}</tr></thead>`;
    const body = document.createElement('tbody');
    for (const row of rows) {
      const tr = document.createElement('tr');
      row.forEach(v => { const td = document.createElement('td'); td.textContent = v ?? '— not mapped'; tr.append(td); });
      if (row[1] === null) tr.className = 'unmapped';
      body.append(tr);
    }
    t.append(body);
    return t;
  }

  async function showMap() {
    say('mapping…');
    $('retarget-panel').dataset.state = 'mapping';
    try {
      const map = await postJSON('/api/retarget/map', request());
      $('rt-map').replaceChildren(table(map.pairs, ['target joint', 'source joint']));
      say(`joint map: ${map.how}; ${map.pairs.length - map.unmapped.length} of ${map.pairs.length} target joints ` +
          `mapped` + (map.unmapped.length ? `; not mapped: ${map.unmapped.join(', ')}` : '') +
          (map.unused.length ? `; source joints unused: ${map.unused.join(', ')}` : ''));
      $('retarget-panel').dataset.state = 'mapped';
      return true;
    } catch (e) {
      $('rt-map').replaceChildren();
      say(e.message, true);
      $('retarget-panel').dataset.state = 'error';
      return false;
    }
  }

  async function run() {
    if (!(await showMap())) return;
    const take = studio.take();
    result = await runBar.run('/api/retarget', request(), 'retargeted');
    if (!result) { $('retarget-panel').dataset.state = 'error'; return; }
    const positions = await getFloats('/api/retarget/positions', {key: result.key});
    const target = {...result, id: `${take.id} (retargeted)`, positions, com: null, comLoaded: Promise.resolve(null)};
    const frame = player.frame;
    player.setTake(target);
    player.setGhost(take, null);
    player.setFrame(frame);
    colourByError(player.figure, result.per_joint_rms_cm);
    const rows = Object.entries(result.per_joint_rms_cm).sort((a, b) => b[1] - a[1])
      .map(([name, v]) => [name, v.toFixed(2)]);
    $('rt-errors').replaceChildren(table(rows, ['target joint', 'RMS error (cm)']));
    runBar.say(`retargeted: ${result.summary} (source: orange ghost; joints green → red by error)`);
    $('retarget-panel').dataset.state = 'done';
  }

  /** The target's joint spheres coloured by their RMS error: green (least) to red (most). */
  function colourByError(figure, errors) {
    const worst = Math.max(1e-9, ...Object.values(errors));
    const colour = new THREE.Color();
    figure.joints.material.color.set(0xffffff);
    figure.take.joint_names.forEach((name, j) => {
      const e = errors[name];
      if (e === undefined) colour.set(0x888888);
      else colour.setHSL(0.33 * (1 - e / worst), 0.85, 0.45);
      figure.joints.setColorAt(j, colour);
    });
    figure.joints.instanceColor.needsUpdate = true;
    player.dirty = true;
  }

  async function save() {
    if (!result) { say('retarget first', true); return; }
    const saved = await saveBar.run('/api/retarget/save', {key: result.key, format: $('rt-format').value}, 'saved');
    if (saved) {
      saveBar.say(`saved ${saved.output}`);
      $('retarget-panel').dataset.saved = saved.id || '';
      await studio.refreshLibrary();
    }
  }

  getJSON('/api/retarget/profiles').then(({profiles}) => {
    for (const id of ['rt-source-profile', 'rt-target-profile']) {
      $(id).append(...profiles.map(p => Object.assign(new Option(p.name, p.name), {title: p.description})));
    }
  }).catch(() => {});
  $('rt-show-map').onclick = showMap;
  $('rt-run').onclick = run;
  $('rt-save').onclick = save;
  return {
    opened: () => { result = null; $('rt-map').replaceChildren(); $('rt-errors').replaceChildren(); say(''); },
    libraryFilled: options => {
      const keep = $('rt-target').value;
      $('rt-target').replaceChildren(new Option('— (this take, joints removed)', ''),
                                     ...options.map(o => new Option(o.text, o.value)));
      $('rt-target').value = keep;
    },
  };
}
