// Plots on the take's timeline (uPlot): one chart per unit, a cursor that follows playback,
// click or drag to seek. A compare take's series are drawn dashed on the same timeline.
// uPlot is imported with the first chart: a take's first frame does not wait for it.
let uPlotLoaded = null;
const loadUPlot = () => uPlotLoaded || (uPlotLoaded = import('uplot').then(module => module.default));

const COLORS = ['#1f5fbf', '#2a9d3a', '#8e44ad', '#c0392b', '#16a085', '#7f8c8d'];

export class Plots {
  constructor(container, onSeek) {
    this.container = container;
    this.onSeek = onSeek;
    this.charts = [];
    this.time = 0;
  }

  /** data: the server's series answer; ghost: the compare take's, ghostMap its frame per frame. */
  async show(data, ghost = null, ghostMap = null, ghostName = 'compare') {
    const uPlot = await loadUPlot();  // calls that awaited it resume in their order: the latest call shows
    this.charts.forEach(c => c.plot.destroy());
    this.charts = [];
    this.container.replaceChildren();
    const byUnit = new Map();
    data.series.forEach((s, i) => {
      if (!byUnit.has(s.unit)) byUnit.set(s.unit, []);
      byUnit.get(s.unit).push({...s, color: COLORS[i % COLORS.length], dash: null});
      const g = ghost && ghost.series.find(o => o.key === s.key && o.joint === s.joint);
      if (g && ghostMap) {
        const values = ghostMap.map(f => g.values[Math.round(f)]);
        byUnit.get(s.unit).push({...g, label: `${g.label} (${ghostName})`, values, color: COLORS[i % COLORS.length],
                                 dash: [6, 4]});
      }
    });
    const width = Math.max(300, this.container.clientWidth - 20);
    for (const [unit, series] of byUnit) {
      const div = document.createElement('div');
      div.className = 'plot';
      div.dataset.unit = unit;
      this.container.append(div);
      const opts = {
        width, height: 150,
        cursor: {x: false, y: false, drag: {x: false, y: false}, points: {show: false}},
        scales: {x: {time: false}},
        axes: [{label: 's'}, {label: unit, size: 60}],
        series: [{label: 'time (s)'}, ...series.map(s => ({label: `${s.label} (${s.unit})`, stroke: s.color,
                                                             width: 1.5, dash: s.dash, spanGaps: false}))],
        legend: {live: false},
        hooks: {draw: [u => this.placeCursor(u)]},
      };
      const plot = new uPlot(opts, [data.time, ...series.map(s => s.values)], div);
      const cursor = document.createElement('div');
      cursor.className = 'plot-cursor';
      plot.over.append(cursor);
      this.seekOn(plot);
      this.charts.push({plot, unit});
    }
    this.setTime(this.time);
  }

  seekOn(plot) {
    let down = false;
    const seek = e => this.onSeek(plot.posToVal(e.offsetX, 'x'));
    plot.over.addEventListener('mousedown', e => { down = true; seek(e); });
    plot.over.addEventListener('mousemove', e => { if (down) seek(e); });
    window.addEventListener('mouseup', () => { down = false; });
  }

  setTime(t) {
    this.time = t;
    this.charts.forEach(c => this.placeCursor(c.plot));
  }

  placeCursor(plot) {
    const cursor = plot.over.querySelector('.plot-cursor');
    if (!cursor) return;
    cursor.style.left = `${plot.valToPos(this.time, 'x')}px`;
    cursor.dataset.time = this.time.toFixed(4);
  }
}
