// Jobs: long work (retarget, render, clip export, detectors) runs on the server; the page starts it
// with a POST that answers {job: id}, then polls /api/jobs/{id} about four times a second.
// runJob() resolves with the job's result, or rejects with its one-line error
// ("usdmotion: error: FILE[:LINE]: message") or with 'cancelled'.

async function answer(response) {
  let body = null;
  try { body = await response.json(); } catch (e) { /* not JSON */ }
  if (!response.ok) throw new Error((body && body.error) || `${response.status} ${response.statusText}`);
  return body;
}

export async function postJSON(url, body) {
  return answer(await fetch(url, {method: 'POST', headers: {'Content-Type': 'application/json'},
                                  body: JSON.stringify(body)}));
}

export async function cancelJob(id) {
  return answer(await fetch(`/api/jobs/${id}`, {method: 'DELETE'}));
}

const sleep = ms => new Promise(resolve => setTimeout(resolve, ms));

/** Start the job of ``url`` with ``body`` and follow it: ``onStart(id)`` once started,
 *  ``onProgress(job)`` on every poll (job: {state, current, total, message}). */
export async function runJob(url, body, {onProgress = () => {}, onStart = () => {}, interval = 250} = {}) {
  const {job: id} = await postJSON(url, body);
  onStart(id);
  for (;;) {
    const job = await answer(await fetch(`/api/jobs/${id}`));
    onProgress(job);
    if (job.state === 'done') return job.result;
    if (job.state === 'failed') throw new Error(job.error);
    if (job.state === 'cancelled') throw new Error('cancelled; no file was kept');
    await sleep(interval);
  }
}

/** A progress bar, a Cancel button and a one-line message in ``container``; ``run(url, body)``
 *  runs one job through it (one at a time) and resolves with its result, or null if it failed
 *  or was cancelled (the message then says why, in red). */
export class JobBar {
  constructor(container) {
    this.el = document.createElement('span');
    this.el.className = 'job-bar';
    this.bar = document.createElement('progress');
    this.bar.max = 1; this.bar.value = 0; this.bar.hidden = true;
    this.cancel = document.createElement('button');
    this.cancel.textContent = 'Cancel'; this.cancel.hidden = true; this.cancel.className = 'job-cancel';
    this.text = document.createElement('span');
    this.text.className = 'job-message';
    this.el.append(this.bar, this.cancel, this.text);
    container.append(this.el);
    this.id = null;
    this.cancel.onclick = () => { if (this.id !== null) cancelJob(this.id).catch(e => this.say(e.message, true)); };
  }

  say(text, error = false) {
    this.text.textContent = text;
    this.text.classList.toggle('error-text', error);
  }

  get busy() { return this.id !== null || this.starting; }

  async run(url, body, done = 'done') {
    this.starting = true;
    this.bar.value = 0; this.bar.removeAttribute('value'); this.bar.hidden = false;
    this.el.dataset.state = 'running';
    this.say('starting…');
    try {
      const result = await runJob(url, body, {
        onStart: id => { this.id = id; this.cancel.hidden = false; this.el.dataset.job = id; },
        onProgress: job => {
          if (job.total) { this.bar.max = job.total; this.bar.value = job.current; }
          this.say(job.total ? `${job.message || job.kind} ${Math.round(job.current)} / ${Math.round(job.total)}`
                             : job.message || job.state);
        }});
      this.el.dataset.state = 'done';
      this.say(done);
      return result;
    } catch (e) {
      this.el.dataset.state = /^cancelled/.test(e.message) ? 'cancelled' : 'failed';
      this.say(e.message, true);
      return null;
    } finally {
      this.id = null; this.starting = false;
      this.bar.hidden = true; this.cancel.hidden = true;
    }
  }
}
