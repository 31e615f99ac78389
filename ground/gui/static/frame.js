// The local east-north frame the map is drawn in, and the view box over it.
import { formatDistance } from './helpers.js';
import { $, EARTH_RADIUS_M, state } from './state.js';

// ---- the local east-north frame ------------------------------------------------------------
export function toXY(lat, lon) {
  const o = state.origin;
  const k = Math.PI / 180 * EARTH_RADIUS_M;
  return [(lon - o.lon) * k * Math.cos(o.lat * Math.PI / 180), -(lat - o.lat) * k];
}

export function toLatLon(x, y) {
  const o = state.origin;
  const k = Math.PI / 180 * EARTH_RADIUS_M;
  return { lat: o.lat - y / k, lon: o.lon + x / (k * Math.cos(o.lat * Math.PI / 180)) };
}

export function clientToMap(clientX, clientY) {
  const svg = $('#map');
  const point = svg.createSVGPoint();
  point.x = clientX;
  point.y = clientY;
  const p = point.matrixTransform(svg.getScreenCTM().inverse());
  return [p.x, p.y];
}

export function pixelsPerMetre() {
  return $('#map').getScreenCTM().a;
}

// For tests and scripts: where a position is on screen, and back.
window.fleetMap = {
  toClient(lat, lon) {
    const [x, y] = toXY(lat, lon);
    const svg = $('#map');
    const point = svg.createSVGPoint();
    point.x = x;
    point.y = y;
    const p = point.matrixTransform(svg.getScreenCTM());
    return { x: p.x, y: p.y };
  },
  toLatLon(clientX, clientY) {
    return toLatLon(...clientToMap(clientX, clientY));
  },
};

// ---- the view box ---------------------------------------------------------------------------
export function fitView() {
  const points = [];
  for (const u of state.uavs) if (u.lat !== null) points.push(toXY(u.lat, u.lon));
  for (const t of state.targets) points.push(toXY(t.lat, t.lon));
  if (!points.length) return;
  const xs = points.map((p) => p[0]);
  const ys = points.map((p) => p[1]);
  const minSize = 2000;
  let w = Math.max(Math.max(...xs) - Math.min(...xs), minSize) * 1.3;
  let h = Math.max(Math.max(...ys) - Math.min(...ys), minSize) * 1.3;
  const cx = (Math.max(...xs) + Math.min(...xs)) / 2;
  const cy = (Math.max(...ys) + Math.min(...ys)) / 2;
  const v = state.view;
  // Refit only when something left the view or the view is far too large: a map that
  // follows every telemetry step jitters under the operator's pointer.
  const inside = v && points.every(([x, y]) => x > v.x && x < v.x + v.w && y > v.y && y < v.y + v.h);
  if (inside && v.w < 3 * w && v.h < 3 * h) return;
  state.view = { x: cx - w / 2, y: cy - h / 2, w, h };
}

export function applyView() {
  const v = state.view;
  if (!v) return;
  $('#map').setAttribute('viewBox', `${v.x} ${v.y} ${v.w} ${v.h}`);
  drawScale();
}

export function drawScale() {
  const ppm = pixelsPerMetre();
  if (!ppm || !isFinite(ppm)) return;
  const wanted = 120 / ppm;
  const power = Math.pow(10, Math.floor(Math.log10(wanted)));
  const nice = [1, 2, 5, 10].map((k) => k * power).filter((m) => m <= wanted).pop() || power;
  $('#scale-bar').style.width = `${nice * ppm}px`;
  $('#scale-text').textContent = formatDistance(nice);
}
