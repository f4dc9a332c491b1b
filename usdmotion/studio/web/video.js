// Feedback-video panel: the current view (camera, compare ghost and its time alignment, traces,
// loop range, speed) rendered to MP4 on the server by usdmotion.render, as a job with progress;
// a download link when it is done.
import {JobBar} from './jobs.js';

const $ = id => document.getElementById(id);

export function mountVideo(studio) {
  const {player, state} = studio;
  const bar = new JobBar($('video-bar'));

  /** What the page shows now, as the renderer's options. */
  function view() {
    const take = studio.take();
    const body = {take: take.id, camera: player.cameraMode, speed: state.speed, size: $('video-size').value,
                  style: $('video-style').value, grid: state.grid,
                  traces: [...(state.trace ? [state.trace] : []), ...(state.comTrace ? ['com'] : [])]};
    if (player.range) { body.start = player.range[0]; body.end = player.range[1] + 1; }
    if (state.compare) { body.compare = state.compare; body.align = state.align; body.offset = state.offset; }
    return body;
  }

  async function render() {
    $('video-download').hidden = true;
    const result = await bar.run('/api/video', view(), 'rendered');
    if (result) {
      const link = $('video-download');
      link.href = result.url;
      link.download = result.output.split('/').pop();
      link.textContent = `Download ${result.output} (${result.frames} frames, ${result.size.join('×')})`;
      link.hidden = false;
      $('video-panel').dataset.url = result.url;
    }
  }

  $('video-render').onclick = render;
  return {view};
}
