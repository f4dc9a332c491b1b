// Segmentation editor: the bone-angle signal Q (the detector's own feature, computed by the server)
// on a timeline under the player, the detector's cuts as handles to drag, add and delete, a name
// per segment, jump to / loop a segment, Save (the segments JSON of `usdmotion segment --out`) and
// Export (the clips of `usdmotion segment --export-clips`, a job). The page holds only the cut
// frames and names the user edits; every number is the library's.
import uPlot from 'uplot';
import {getJSON} from './api.js';
import {JobBar, postJSON} from './jobs.js';

const $ = id => document.getElementById(id);
const PARAMS = {kcpd: ['penalty', 'min_length', 'refine'], heuristic: ['param', 'cutoff']};

export class SegmentEditor {
  /** hooks from main.js: {player, seek(frame), setRange([first, last] | null), playToggle(),
   *  refreshLibrary()}. */
  constructor(panel, hooks) {
    Object.assign(this, hooks);
    this.panel = panel;
    this.take = null;
    this.cuts = [];           // sorted frames; cut c starts a segment at frame c
    this.names = [''];        // one per segment
    this.selected = -1;       // index into cuts
    this.undoStack = [];
    this.detector = null;     // the detector options the cuts came from (sent back on Save/Export)
    this.chart = null;
    this.handles = [];
    this.jobBar = new JobBar($('seg-jobs'));
    this.asked = 0;
    this.wire();
  }

  // ------------------------------------------------------------------ take and detector

  /** A take was opened: if the panel is open, show its saved segments or the detector's cuts. */
  setTake(take) {
    this.take = take;
    this.cuts = []; this.names = ['']; this.selected = -1; this.undoStack = []; this.candidates = [];
    this.signal = null;
    if (this.chart) { this.chart.destroy(); this.chart = null; }
    $('seg-timeline').replaceChildren();
    this.showTable();
    if (this.panel.open) this.load();
  }

  async load() {
    const take = this.take, mine = ++this.asked;
    if (!take) return;
    this.say('reading the bone-angle signal…');
    try {
      const [signal, saved] = await Promise.all([
        getJSON('/api/segment/signal', {take: take.id}),
        getJSON('/api/segment/saved', {take: take.id}).catch(e => ({error: e.message}))]);
      if (mine !== this.asked) return;
      this.signal = signal;
      this.draw();
      this.loadLabels();
      if (saved.doc) {
        this.fromDocument(saved.doc);
        this.say(`showing the saved segments ${saved.output}`);
        return;
      }
      await this.run();
      if (saved.error) this.say(`${saved.error} (showing the detector's cuts)`, true);
    } catch (e) {
      if (mine === this.asked) this.say(e.message, true);
    }
  }

  /** The detector options in the form (checked by the server; a bad one is answered with one line). */
  options() {
    const method = $('seg-method').value, num = id => ($(id).value.trim() === '' ? null : Number($(id).value));
    const all = {method, penalty: num('seg-penalty'), min_length: num('seg-min-length'),
                 refine: $('seg-refine').checked, param: num('seg-param'), cutoff: num('seg-cutoff')};
    const keep = ['method', ...PARAMS[method]];
    return Object.fromEntries(Object.entries(all).filter(([k, v]) => keep.includes(k) && (v !== null ||
                                                                                          k === 'penalty')));
  }

  async run() {
    if (!this.take) return;
    const detector = this.options(), body = {take: this.take.id, detector}, mine = ++this.asked;
    this.say(`running ${detector.method}…`);
    let answer;
    try {
      answer = this.signal && this.take.frames > this.signal.job_frames
        ? await this.jobBar.run('/api/segment/detect', body, 'detector done')
        : await postJSON('/api/segment/detect', body);
    } catch (e) {
      if (mine === this.asked) this.say(e.message, true);
      return;
    }
    if (!answer || mine !== this.asked) return;
    this.remember();
    this.detector = detector;
    this.details = new Map((answer.doc.cut_details || []).map(d => [d.frame, d]));
    this.candidates = answer.candidates;
    this.setCuts(answer.doc.cuts, answer.doc.cuts.map(() => '').concat(['']));
    const low = [...this.details.values()].filter(d => d.low_confidence).length;
    this.say(`${detector.method}: ${answer.doc.cuts.length} cuts` +
             (low ? `, ${low} of low confidence (dotted): check them` : ''));
  }

  /** Show a saved segments document (its detector options go into the form). */
  fromDocument(doc) {
    const p = doc.params || {};
    $('seg-method').value = doc.method;
    if (doc.method === 'kcpd') {
      $('seg-penalty').value = p.penalty_scale === undefined && p.penalty !== undefined ? p.penalty : '';
      if (p.min_length_s !== undefined) $('seg-min-length').value = p.min_length_s;
      if (p.refine !== undefined) $('seg-refine').checked = p.refine;
    } else {
      if (p.param !== undefined) $('seg-param').value = p.param;
      if (p.cutoff_hz !== undefined) $('seg-cutoff').value = p.cutoff_hz;
    }
    this.showParams();
    this.detector = this.options();
    this.details = new Map((doc.cut_details || []).map(d => [d.frame, d]));
    this.setCuts(doc.cuts, doc.segments.map(s => s.label || ''));
  }

  async loadLabels() {
    try {
      const {labels} = await getJSON('/api/segment/labels');
      $('seg-labels').replaceChildren(...labels.map(l => new Option(l, l)));
    } catch (e) { /* the names are only suggestions */ }
  }

  // ------------------------------------------------------------------ editing

  remember() {
    this.undoStack.push([[...this.cuts], [...this.names]]);
    if (this.undoStack.length > 100) this.undoStack.shift();
  }

  undo() {
    const last = this.undoStack.pop();
    if (last) { this.setCuts(...last); this.say('undone'); }
  }

  setCuts(cuts, names) {
    this.cuts = [...cuts];
    this.names = names.length === cuts.length + 1 ? [...names] : cuts.map(() => '').concat(['']);
    this.selected = Math.min(this.selected, this.cuts.length - 1);
    this.changed();
  }

  changed() {
    this.placeHandles();
    this.showTable();
    if (this.chart) this.chart.redraw(false);
  }

  /** Add a cut at ``frame``: the segment it falls in is split, the new part unnamed. */
  add(frame) {
    const f = Math.round(frame);
    if (!this.take || f < 1 || f > this.take.frames - 1 || this.cuts.includes(f)) {
      this.say(`a cut needs a frame within 1–${this.take ? this.take.frames - 1 : 0} without one`, true);
      return;
    }
    this.remember();
    const i = this.cuts.filter(c => c < f).length;
    this.cuts.splice(i, 0, f);
    this.names.splice(i + 1, 0, '');
    this.selected = i;
    this.changed();
    this.say(`cut added at frame ${f}`);
  }

  /** Delete cut ``i``: its two segments become one, keeping the first one's name (else the second's). */
  remove(i) {
    if (i < 0 || i >= this.cuts.length) return;
    this.remember();
    const [frame] = this.cuts.splice(i, 1);
    const [second] = this.names.splice(i + 1, 1);
    this.names[i] = this.names[i] || second;
    this.selected = -1;
    this.changed();
    this.say(`cut at frame ${frame} deleted`);
  }

  /** Move cut ``i`` to ``frame``, kept between its neighbours. */
  move(i, frame, record = true) {
    const lo = i > 0 ? this.cuts[i - 1] + 1 : 1;
    const hi = i < this.cuts.length - 1 ? this.cuts[i + 1] - 1 : this.take.frames - 1;
    const f = Math.max(lo, Math.min(hi, Math.round(frame)));
    if (record) this.remember();
    this.cuts[i] = f;
    return f;
  }

  select(i) {
    this.selected = i;
    $('seg-cut-frame').value = i >= 0 ? this.cuts[i] : '';
    $('seg-cut-frame').disabled = $('seg-delete').disabled = $('seg-zoom-cut').disabled = i < 0;
    this.handles.forEach((h, k) => h.classList.toggle('selected', k === i));
  }

  bounds() {
    const starts = [0, ...this.cuts], ends = [...this.cuts.map(c => c - 1), this.take.frames - 1];
    return starts.map((s, i) => [s, ends[i]]);
  }

  // ------------------------------------------------------------------ timeline

  draw() {
    const s = this.signal, el = $('seg-timeline');
    if (this.chart) this.chart.destroy();
    el.replaceChildren();
    const time = s.q.map((_, i) => i / s.fps);
    this.chart = new uPlot({
      width: Math.max(300, el.clientWidth - 16), height: 150,
      cursor: {x: false, y: false, drag: {x: false, y: false}, points: {show: false}},
      scales: {x: {time: false}},
      axes: [{size: 30}, {label: 'Q = ‖θ‖ (deg)', size: 60}],
      series: [{label: 'time (s)'}, {label: 'Q (deg)', stroke: '#9a9a9a', width: 1},
               {label: 'low-passed Q (deg)', stroke: '#1f5fbf', width: 1.5}],
      legend: {show: false},
      hooks: {drawClear: [u => this.shade(u)], setScale: [() => this.placeHandles()]},
    }, [time, s.q, s.filtered], el);
    const over = this.chart.over;
    this.hover = Object.assign(document.createElement('div'), {className: 'seg-hover'});
    this.playhead = Object.assign(document.createElement('div'), {className: 'seg-playhead'});
    over.append(this.hover, this.playhead);
    this.track(over);
    this.placeHandles();
    this.setFrame(this.player.frame);
  }

  /** Alternate segments shaded (canvas, under the curves); the paper's swing candidates as green
   *  ticks at the bottom (places a person may want to cut, ALGORITHMS.md §3). */
  shade(u) {
    if (!this.take) return;
    const ctx = u.ctx, top = u.bbox.top, h = u.bbox.height;
    this.bounds().forEach(([a, b], i) => {
      const x0 = u.valToPos(a / this.take.fps, 'x', true), x1 = u.valToPos((b + 1) / this.take.fps, 'x', true);
      ctx.fillStyle = i % 2 ? 'rgba(0,0,0,0.05)' : 'rgba(0,0,0,0)';
      ctx.fillRect(x0, top, x1 - x0, h);
    });
    ctx.fillStyle = '#2a9d3a';
    for (const c of this.candidates || []) {
      const x = u.valToPos(c / this.take.fps, 'x', true);
      if (x >= u.bbox.left && x <= u.bbox.left + u.bbox.width) ctx.fillRect(x - 1, top + h - 8, 2, 8);
    }
  }

  xOfFrame(f) { return this.chart.valToPos(f / this.take.fps, 'x'); }

  frameAt(x) { return Math.round(this.chart.posToVal(x, 'x') * this.take.fps); }

  /** Cut handles and segment names as elements over the chart (tests find them by data-frame). */
  placeHandles() {
    if (!this.chart || !this.take) return;
    const over = this.chart.over, width = over.clientWidth;
    this.handles.forEach(h => h.remove());
    over.querySelectorAll('.seg-name').forEach(n => n.remove());
    this.handles = this.cuts.map((c, i) => {
      const h = document.createElement('div'), d = this.details && this.details.get(c);
      h.className = 'seg-cut' + (d && d.low_confidence ? ' low' : '') + (i === this.selected ? ' selected' : '');
      h.dataset.index = i; h.dataset.frame = c;
      h.title = `cut at frame ${c}` + (d ? ` · confidence ${d.confidence.toFixed(2)}` : '') + ' · drag to move';
      h.style.left = `${this.xOfFrame(c)}px`;
      h.hidden = this.xOfFrame(c) < 0 || this.xOfFrame(c) > width;
      over.append(h);
      return h;
    });
    this.bounds().forEach(([a, b], i) => {
      if (!this.names[i]) return;
      const n = document.createElement('div');
      const x0 = Math.max(0, this.xOfFrame(a)), x1 = Math.min(width, this.xOfFrame(b));
      if (x1 - x0 < 20) return;
      n.className = 'seg-name'; n.textContent = this.names[i];
      n.style.left = `${x0 + 3}px`; n.style.maxWidth = `${x1 - x0 - 6}px`;
      over.append(n);
    });
    this.select(this.selected);
  }

  /** Drag a handle (the body shows the frame under the pointer), click to seek, double-click to add,
   *  hover to preview, wheel to zoom. */
  track(over) {
    let drag = null;
    const xOf = e => e.clientX - over.getBoundingClientRect().left;
    over.addEventListener('mousedown', e => {
      const h = e.target.closest('.seg-cut');
      if (h) {
        e.preventDefault();
        this.player.play(false);
        const i = +h.dataset.index;
        this.select(i);
        this.remember();
        drag = {i, from: this.cuts[i]};
      } else {
        this.seek(this.frameAt(xOf(e)));
      }
    });
    window.addEventListener('mousemove', e => {
      if (!drag) return;
      const f = this.move(drag.i, this.frameAt(xOf(e)), false);
      this.handles[drag.i].style.left = `${this.xOfFrame(f)}px`;
      this.handles[drag.i].dataset.frame = f;
      $('seg-cut-frame').value = f;
      this.preview(f);
    });
    window.addEventListener('mouseup', () => {
      if (!drag) return;
      const {i, from} = drag;
      drag = null;
      if (this.cuts[i] === from) this.undoStack.pop();
      else this.say(`cut moved from frame ${from} to ${this.cuts[i]}`);
      this.changed();
      this.seek(this.cuts[i]);
    });
    over.addEventListener('mousemove', e => {
      if (drag) return;
      const f = Math.max(0, Math.min(this.take.frames - 1, this.frameAt(xOf(e))));
      this.hover.style.left = `${this.xOfFrame(f)}px`;
      this.hover.hidden = false;
      this.hover.dataset.label = `${f}`;
      if (!this.player.playing) this.preview(f);
    });
    over.addEventListener('mouseleave', () => {
      this.hover.hidden = true;
      if (!drag && !this.player.playing) this.player.setFrame(this.player.frame);  // back to the playhead
    });
    over.addEventListener('dblclick', e => this.add(this.frameAt(xOf(e))));
    over.addEventListener('wheel', e => {
      e.preventDefault();
      const u = this.chart, t = u.posToVal(xOf(e), 'x'), k = e.deltaY > 0 ? 1.25 : 0.8;
      const lo = u.scales.x.min, hi = u.scales.x.max, end = (this.take.frames - 1) / this.take.fps;
      const span = Math.min(end, Math.max(20 / this.take.fps, (hi - lo) * k));
      const min = Math.max(0, Math.min(end - span, t - (t - lo) * span / (hi - lo)));
      this.zoom(min, min + span);
    }, {passive: false});
  }

  zoom(min, max) { this.chart.setScale('x', {min, max}); }

  /** Show frame ``f`` on the body (and ghost) without moving the playhead. */
  preview(f) {
    const p = this.player;
    if (!p.figure) return;
    p.figure.setFrame(f);
    if (p.ghost) p.ghost.setFrame(p.ghostMap ? p.ghostMap[f] : f);
    p.dirty = true;
  }

  /** The player moved: the timeline's playhead follows. */
  setFrame(frame) {
    if (!this.chart || !this.take) return;
    this.playhead.style.left = `${this.xOfFrame(frame)}px`;
    this.playhead.dataset.frame = frame;
  }

  // ------------------------------------------------------------------ segment table, save, export

  showTable() {
    const rows = this.take ? this.bounds().map(([a, b], i) => {
      const tr = document.createElement('tr');
      tr.dataset.index = i;
      const name = Object.assign(document.createElement('input'), {value: this.names[i] || '', className: 'seg-label',
        placeholder: 'name (e.g. walk)', maxLength: 200});
      name.setAttribute('list', 'seg-labels');
      name.setAttribute('aria-label', `name of segment ${i}`);
      name.addEventListener('input', () => { this.names[i] = name.value; this.placeHandles(); });
      const button = (text, title, fn) => Object.assign(document.createElement('button'), {textContent: text, title,
                                                                                           onclick: fn});
      const d = i > 0 && this.details ? this.details.get(a) : null;  // the detector's word on the cut at a
      const cells = [i, a, b, ((b - a + 1) / this.take.fps).toFixed(2),
                     d ? `${d.confidence.toFixed(2)}${d.low_confidence ? ' check' : ''}` : ''].map(v =>
        Object.assign(document.createElement('td'), {textContent: v}));
      const td = c => { const t = document.createElement('td'); t.append(c); return t; };
      tr.append(...cells, td(name),
        td(button('▶', 'jump to its first frame', () => { this.seek(a); this.zoomTo(a, b); })),
        td(button('⟳', 'play it in a loop', () => this.loop(a, b))));
      return tr;
    }) : [];
    $('seg-table').querySelector('tbody').replaceChildren(...rows);
  }

  zoomTo(a, b) {
    if (!this.chart) return;
    const pad = Math.max(1, (b - a) * 0.1);
    this.zoom(Math.max(0, (a - pad) / this.take.fps), Math.min(this.take.frames - 1, b + pad) / this.take.fps);
  }

  loop(a, b) {
    this.setRange([a, b]);
    this.seek(a);
    if (!this.player.playing) this.playToggle();
  }

  body(extra = {}) {
    return {take: this.take.id, detector: this.detector || this.options(), cuts: this.cuts,
            labels: this.names.map(n => n.trim()), ...extra};
  }

  async save() {
    if (!this.take) return;
    try {
      const answer = await postJSON('/api/segment/save', this.body());
      $('seg-output').textContent = `saved ${answer.output}`;
      $('seg-output').dataset.output = answer.output;
      this.say(`saved ${this.cuts.length + 1} segments`);
      this.loadLabels();
    } catch (e) {
      this.say(e.message, true);
    }
  }

  async exportClips() {
    if (!this.take || this.jobBar.busy) return;
    const fmt = $('seg-format').value;
    const result = await this.jobBar.run('/api/segment/export', this.body({format: fmt}),
                                         `${this.cuts.length + 1} clips written`);
    if (result) {
      $('seg-output').textContent = `clips in ${result.folder}`;
      $('seg-output').dataset.output = result.folder;
      this.refreshLibrary();  // the clips are takes of the output folder's root
    }
  }

  say(text, error = false) {
    $('seg-status').textContent = text;
    $('seg-status').className = error ? 'error-text' : '';
  }

  showParams() {
    const method = $('seg-method').value;
    this.panel.querySelectorAll('[data-for]').forEach(el => { el.hidden = el.dataset.for !== method; });
  }

  wire() {
    this.panel.addEventListener('toggle', () => { if (this.panel.open && this.take && !this.chart) this.load(); });
    $('seg-method').onchange = () => this.showParams();
    $('seg-run').onclick = () => this.run();
    $('seg-add').onclick = () => this.add(this.player.frame);
    $('seg-delete').onclick = () => this.remove(this.selected);
    $('seg-undo').onclick = () => this.undo();
    $('seg-zoom-all').onclick = () => this.chart && this.zoom(0, (this.take.frames - 1) / this.take.fps);
    $('seg-zoom-cut').onclick = () => {
      if (this.selected < 0) return;
      const c = this.cuts[this.selected], r = Math.round(this.take.fps);  // ±1 s: a frame is a few pixels
      this.zoom(Math.max(0, c - r) / this.take.fps, Math.min(this.take.frames - 1, c + r) / this.take.fps);
    };
    $('seg-cut-frame').onchange = e => {
      if (this.selected < 0 || e.target.value === '') return;
      const from = this.cuts[this.selected], f = this.move(this.selected, +e.target.value);
      this.changed();
      this.seek(f);
      this.say(f === +e.target.value ? `cut moved from frame ${from} to ${f}`
                                     : `cut kept between its neighbours: frame ${f}`, f !== +e.target.value);
    };
    $('seg-save').onclick = () => this.save();
    $('seg-export').onclick = () => this.exportClips();
    window.addEventListener('keydown', e => {
      if (!this.panel.open || e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT') return;
      if ((e.key === 'Delete' || e.key === 'Backspace') && this.selected >= 0) {
        e.preventDefault();
        this.remove(this.selected);
      }
      if (e.key === 'z' && (e.ctrlKey || e.metaKey)) { e.preventDefault(); this.undo(); }
      if ((e.key === ',' || e.key === '.' || e.key === '<' || e.key === '>') && this.selected >= 0) {
        e.preventDefault();  // nudge the selected cut a frame (with shift: ten)
        const step = (e.key === ',' || e.key === '<' ? -1 : 1) * (e.shiftKey ? 10 : 1);
        const f = this.move(this.selected, this.cuts[this.selected] + step);
        this.changed();
        this.seek(f);
      }
    });
    new ResizeObserver(() => {
      if (this.chart) { this.chart.setSize({width: Math.max(300, $('seg-timeline').clientWidth - 16), height: 150});
                        this.placeHandles(); }
    }).observe($('seg-timeline'));
    this.showParams();
  }
}
