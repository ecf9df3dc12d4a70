// Which rooms the server hosts (from /healthz) and which one to join.

/** The server's room names, sorted; empty when /healthz cannot be read. */
export async function list_rooms(fetch_json = (url) => fetch(url).then((r) => r.json())) {
  try {
    const health = await fetch_json('/healthz');
    return Object.keys(health.rooms ?? {}).sort();
  } catch {
    return [];
  }
}

/** The room asked for (?room=NAME) if the server has it, else "default" if it has that, else its first. */
export function choose_room(rooms, requested) {
  if (requested && (rooms.includes(requested) || rooms.length === 0)) return requested;
  if (rooms.length === 0 || rooms.includes('default')) return 'default';
  return rooms[0];
}
