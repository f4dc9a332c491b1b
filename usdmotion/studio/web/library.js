// Library view: the take list appears at once, metadata fills in (batches of ids), filter and sort.
import {getJSON} from './api.js';

const BATCH = 40;

export class LibraryView {
  constructor(table, filter, status, onOpen) {
    this.body = table.querySelector('tbody');
    this.filter = filter;
    this.status = status;
    this.onOpen = onOpen;
    this.takes = [];
    this.sortKey = 'name';
    this.sortDir = 1;
    this.rows = new Map();  // id -> <tr> of the takes shown
    filter.addEventListener('input', () => this.render());
    table.querySelectorAll('th[data-sort]').forEach(th => th.addEventListener('click', () => {
      this.sortDir = this.sortKey === th.dataset.sort ? -this.sortDir : 1;
      this.sortKey = th.dataset.sort;
      this.render();
    }));
  }

  async load() {
    const answer = await getJSON('/api/takes');
    this.takes = answer.takes.map(t => ({...t, meta: null}));
    this.render();
    return answer;
  }

  /** Metadata in batches (the server reads each file once, cached by path and mtime). */
  async fill() {
    for (let i = 0; i < this.takes.length; i += BATCH) {
      const batch = this.takes.slice(i, i + BATCH);
      const {meta} = await getJSON('/api/meta', batch.map(t => ['id', t.id]));
      batch.forEach(t => {  // replace just these rows: thousands of takes must not re-render per batch
        t.meta = meta[t.id];
        const old = this.rows.get(t.id);
        if (old) { const tr = this.row(t); old.replaceWith(tr); this.rows.set(t.id, tr); }
      });
      this.showStatus(this.rows.size);
    }
    this.render();  // sorted by the metadata now known
  }

  readable() { return this.takes.filter(t => t.meta && !t.meta.error); }

  render() {
    const words = this.filter.value.toLowerCase().split(/\s+/).filter(Boolean);
    const shown = this.takes.filter(t => words.every(w => t.name.toLowerCase().includes(w)));
    const key = this.sortKey;
    const value = t => key === 'name' ? t.name : (t.meta && !t.meta.error ? t.meta[key] : null);
    shown.sort((a, b) => {
      const va = value(a), vb = value(b);
      if (va === vb) return a.name.localeCompare(b.name);
      if (va === null || va === undefined) return 1;
      if (vb === null || vb === undefined) return -1;
      return (va < vb ? -1 : 1) * this.sortDir;
    });
    this.rows = new Map(shown.map(t => [t.id, this.row(t)]));
    this.body.replaceChildren(...this.rows.values());
    this.showStatus(shown.length);
  }

  showStatus(shown) {
    const done = this.takes.filter(t => t.meta).length;
    const failed = this.takes.filter(t => t.meta && t.meta.error).length;
    this.status.textContent = `${shown} of ${this.takes.length} takes` +
      (done < this.takes.length ? ` · reading ${done}/${this.takes.length}` : '') +
      (failed ? ` · ${failed} could not be read` : '');
  }

  row(t) {
    const tr = document.createElement('tr');
    tr.dataset.id = t.id;
    const cell = (text, cls) => { const td = document.createElement('td'); td.textContent = text;
      if (cls) td.className = cls; return td; };
    tr.append(cell(t.name));
    if (!t.meta) {
      tr.className = 'take pending';
      tr.append(cell('…'));
    } else if (t.meta.error) {
      tr.className = 'failed';
      const td = cell(t.meta.error, 'error');
      td.colSpan = 5;
      tr.append(td);
    } else {
      const m = t.meta;
      tr.className = 'take';
      tr.append(cell(m.joints), cell(m.frames), cell(+m.fps.toFixed(3)), cell(m.duration_s.toFixed(2)), cell(m.rig));
    }
    if (t.id === this.selectedId) tr.classList.add('selected');
    if (!t.meta || !t.meta.error) tr.addEventListener('click', () => this.onOpen(t.id));
    return tr;
  }

  select(id) {
    this.selectedId = id;
    this.body.querySelectorAll('tr').forEach(tr => tr.classList.toggle('selected', tr.dataset.id === id));
  }
}
