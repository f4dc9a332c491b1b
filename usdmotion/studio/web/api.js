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

/** Everything the player needs for one take: skeleton, positions (F*J*3, m, Y up), centre of mass or null. */
export async function loadTake(id) {
  const [skeleton, positions] = await Promise.all([getJSON('/api/skeleton', {take: id}),
                                                   getFloats('/api/positions', {take: id})]);
  const com = await getFloats('/api/com', {take: id}).catch(() => null);
  return {id, ...skeleton, positions, com};
}
