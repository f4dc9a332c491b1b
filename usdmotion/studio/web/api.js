// Thin fetch helpers for the studio's API (every number comes from the Python library).

async function check(response) {
  if (response.ok) return response;
  let message = `${response.status} ${response.statusText}`;
  try { message = (await response.json()).error || message; } catch (e) { /* not JSON */ }
  throw new Error(message);
}

export async function getJSON(path, params = {}) {
  const query = new URLSearchParams(params).toString();
  return (await check(await fetch(query ? `${path}?${query}` : path))).json();
}

export async function getFloats(path, params) {
  const response = await check(await fetch(`${path}?${new URLSearchParams(params)}`));
  return new Float32Array(await response.arrayBuffer());
}

export async function getBytes(path, params) {
  const response = await check(await fetch(`${path}?${new URLSearchParams(params)}`));
  return response.arrayBuffer();
}

/** ``/api/<what>?take=id``: the response index.html already asked for (a linked take, once), or a new fetch. */
function takeResponse(what, id) {
  const early = window.early && window.early.take === id ? window.early.responses : {};
  const response = early[what] || fetch(`/api/${what}?${new URLSearchParams({take: id})}`);
  delete early[what];
  return response;
}

/** The take's skinned body: GLB bytes from the server (built once per take, then cached). */
export async function takeGlb(id) {
  return (await check(await takeResponse('glb', id))).arrayBuffer();
}

/** What the player needs to draw a take: skeleton and positions (F*J*3, m, Y up). ``comLoaded``
 *  (asked for on first use: it needs the analysis) resolves with the centre of mass or null and sets
 *  ``take.com``. */
export async function loadTake(id) {
  const [skeleton, positions] = await Promise.all([
    takeResponse('skeleton', id).then(check).then(r => r.json()),
    takeResponse('positions', id).then(check).then(async r => new Float32Array(await r.arrayBuffer()))]);
  const take = {id, ...skeleton, positions, com: null};
  let com = null;
  Object.defineProperty(take, 'comLoaded', {get: () => com || (com = getFloats('/api/com', {take: id})
    .catch(() => null).then(values => { take.com = values; return values; }))});
  return take;
}
