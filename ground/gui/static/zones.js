// No-fly zones on the Mission Manager's page: draw a polygon, load or save GeoJSON, send
// them with the targets; the followed mission's zones and each UAV's planned route around
// them on the map. The server checks every zone (ground/gui/zones_api.py,
// ground/gui/commands.py).
import { clientToMap, toLatLon, toXY } from './frame.js';
import { colourOf, distance, el, html, notice } from './helpers.js';
import { render } from './map.js';
import { $, state, withToken } from './state.js';

export const zones = {
  draft: [],      // the operator's zones: {name, ring: [[lat, lon], ...]} (sent with the targets)
  drawing: null,  // the polygon being drawn: [[lat, lon], ...], or null
};

// The zones shown: the draft, else the followed mission's.
export function shownZones() {
  if (zones.draft.length) return zones.draft;
  return (state.mission && state.mission.zones) || [];
}

export function ringPoints(ring) {
  return ring.map(([lat, lon]) => toXY(lat, lon).join(',')).join(' ');
}

export function drawZones() {
  const layer = $('#layer-zones');
  layer.replaceChildren();
  const missionZones = (state.mission && state.mission.zones) || [];
  shownZones().forEach((zone, index) => {
    el('polygon', {
      class: 'zone', points: ringPoints(zone.ring), 'data-zone-index': index,
      'data-sent': String(!zones.draft.length || missionZones.length > 0),
    }, layer);
  });
  if (zones.drawing && zones.drawing.length) {
    el('polyline', {
      class: 'zone-drawing', points: ringPoints(zones.drawing),
    }, layer);
  }
}

// Each UAV's planned route: from the UAV through its route's turns to its target.
export function drawRoutes() {
  const layer = $('#layer-routes');
  layer.replaceChildren();
  const m = state.mission;
  if (!m) return;
  for (const u of state.uavs) {
    const target = u.target === null ? null : m.targets[u.target];
    if (!u.route || !u.route.length || u.lat === null || !target || u.mission !== m.mission) continue;
    const points = [[u.lat, u.lon], ...u.route, [target.lat, target.lon]];
    el('polyline', {
      class: 'route', points: ringPoints(points), stroke: colourOf(u.id), 'data-uav': u.id,
    }, layer);
  }
}

// Whether a UAV flies a route around zones to its target (its straight line is hidden).
export function routed(u) {
  return Boolean(u.route && u.route.length);
}

// Metres to go from the UAV (map point a) to its target (b): along its route, if it has one.
export function routeLength(u, a, b) {
  if (!routed(u)) return distance(a, b);
  const points = [a, ...u.route.map(([lat, lon]) => toXY(lat, lon)), b];
  let total = 0;
  for (let i = 1; i < points.length; i += 1) total += distance(points[i - 1], points[i]);
  return total;
}

// A click on the map while drawing adds a vertex (true); else it is the targets' (false).
export function addZoneVertexAt(clientX, clientY) {
  if (!zones.drawing || !state.origin) return false;
  const { lat, lon } = toLatLon(...clientToMap(clientX, clientY));
  zones.drawing.push([lat, lon]);
  drawZoneButton();
  render();
  return true;
}

export function drawZoneButton() {
  const button = $('#draw-zone');
  button.textContent = zones.drawing ? `Finish zone (${zones.drawing.length} vertices)` : 'Draw zone';
  button.classList.toggle('primary', Boolean(zones.drawing));
}

export function toggleDrawing() {
  if (!zones.drawing) {
    zones.drawing = [];
    notice('click the map for each vertex of the zone, then Finish zone (Esc: cancel)', true);
  } else if (zones.drawing.length < 3) {
    notice('a zone needs at least 3 vertices: keep clicking the map (Esc: cancel)', false);
    return;
  } else {
    const ring = zones.drawing;
    zones.draft.push({ name: `zone ${zones.draft.length + 1}`, ring: [...ring, ring[0]] });
    zones.drawing = null;
  }
  drawZoneButton();
  drawZoneList();
  render();
}

export function drawZoneList() {
  const list = $('#zone-list');
  list.replaceChildren();
  zones.draft.forEach((zone, index) => {
    const item = html('li', `${zone.name || `zone ${index + 1}`}: ${zone.ring.length - 1} vertices `);
    const remove = html('button', '×', { type: 'button', title: 'delete this zone', 'data-zone-delete': index });
    item.appendChild(remove);
    list.appendChild(item);
  });
}

export async function importZones(file) {
  const response = await fetch(withToken(`api/zones/import?name=${encodeURIComponent(file.name)}`), {
    method: 'POST', body: await file.arrayBuffer(),
  });
  const json = (response.headers.get('content-type') || '').includes('json');
  const answer = json ? await response.json() : { error: `${file.name}: ${response.status}` };
  if (!response.ok) {
    notice(`Zones refused: ${answer.error}`, false);
    return;
  }
  zones.draft = answer.zones;
  notice(`${file.name}: ${answer.zones.length} no-fly zone(s) loaded (not sent)`, true);
  drawZoneList();
  render();
}

export async function saveZones() {
  const response = await fetch(withToken('api/zones/export'), {
    method: 'POST', body: JSON.stringify(shownZones()),
  });
  if (!response.ok) {
    notice(`Save refused: ${(await response.json()).error}`, false);
    return;
  }
  const link = html('a', '', { href: URL.createObjectURL(await response.blob()), download: 'zones.geojson' });
  link.click();
  URL.revokeObjectURL(link.href);
}

// The zones a Send carries: the operator's draft.
export function zonesToSend() {
  return zones.draft.map((z) => ({ name: z.name || '', ring: z.ring }));
}

export function setUpZones() {
  $('#draw-zone').addEventListener('click', toggleDrawing);
  $('#clear-zones').addEventListener('click', () => { zones.draft = []; zones.drawing = null; drawZoneButton(); drawZoneList(); render(); });
  $('#save-zones').addEventListener('click', saveZones);
  $('#load-zones').addEventListener('change', (event) => {
    const file = event.target.files[0];
    if (file) importZones(file);
    event.target.value = '';
  });
  $('#zone-list').addEventListener('click', (event) => {
    const index = event.target.dataset.zoneDelete;
    if (index === undefined) return;
    zones.draft.splice(Number(index), 1);
    drawZoneList();
    render();
  });
  document.addEventListener('keydown', (event) => {
    if (event.key === 'Escape' && zones.drawing) {
      zones.drawing = null;
      drawZoneButton();
      render();
    }
  });
}
