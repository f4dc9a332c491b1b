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

/** What the player needs to draw a take: skeleton and positions (F*J*3, m, Y up). ``comLoaded``
 *  resolves later with the centre of mass (needs the analysis) or null; it sets ``take.com``. */
export async function loadTake(id) {
  const [skeleton, positions] = await Promise.all([getJSON('/api/skeleton', {take: id}),
                                                   getFloats('/api/positions', {take: id})]);
  const take = {id, ...skeleton, positions, com: null};
  take.comLoaded = getFloats('/api/com', {take: id}).catch(() => null).then(com => { take.com = com; return com; });
  return take;
}
