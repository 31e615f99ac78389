// The Mission Manager's page: a live map of the fleet, targets by click, send, watch, abort.
// Plain JavaScript, no library. The server pushes snapshots on one WebSocket and takes
// commands on it; see ground/gui/server.py for the protocol.
'use strict';

const SVG_NS = 'http://www.w3.org/2000/svg';
const EARTH_RADIUS_M = 6378137;
const ACTIVE_TARGET_STATES = new Set(['pending', 'assigned']);
const MAX_ALERTS = 6;

const state = {
  uavs: [],            // the latest snapshot's UAVs (ground-cli uavs --json + trail, link_lost)
  mission: null,       // the followed mission (send-targets --json + target_states)
  targets: [],         // the operator's target list: {lat, lon, alt}
  excluded: new Set(), // live UAVs the operator took out of the team
  statuses: [],        // {seq, time, uav, text, severity, count}
  alerts: [],
  lastOf: new Map(),
  lastSeq: 0,   // each UAV's latest status entry
  origin: null,        // {lat, lon}: the local east-north frame's origin
  view: null,          // the SVG viewBox in metres {x, y, w, h}
  autoFit: true,
  ws: null,
  nextId: 1,
  seenMission: null,
};

const $ = (selector) => document.querySelector(selector);
const token = new URLSearchParams(location.search).get('token');

function withToken(path) {
  return token ? `${path}${path.includes('?') ? '&' : '?'}token=${encodeURIComponent(token)}` : path;
}

// ---- the local east-north frame ------------------------------------------------------------
function toXY(lat, lon) {
  const o = state.origin;
  const k = Math.PI / 180 * EARTH_RADIUS_M;
  return [(lon - o.lon) * k * Math.cos(o.lat * Math.PI / 180), -(lat - o.lat) * k];
}

function toLatLon(x, y) {
  const o = state.origin;
  const k = Math.PI / 180 * EARTH_RADIUS_M;
  return { lat: o.lat - y / k, lon: o.lon + x / (k * Math.cos(o.lat * Math.PI / 180)) };
}

function clientToMap(clientX, clientY) {
  const svg = $('#map');
  const point = svg.createSVGPoint();
  point.x = clientX;
  point.y = clientY;
  const p = point.matrixTransform(svg.getScreenCTM().inverse());
  return [p.x, p.y];
}

function pixelsPerMetre() {
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

// ---- helpers --------------------------------------------------------------------------------
// Each Piccolo ID its own colour, the same on every page: hues a golden angle apart.
function colourOf(uav) {
  return `hsl(${(uav * 137.508) % 360}, 75%, 38%)`;
}

function el(name, attributes = {}, parent = null) {
  const node = document.createElementNS(SVG_NS, name);
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  if (parent) parent.appendChild(node);
  return node;
}

function html(name, text = '', attributes = {}) {
  const node = document.createElement(name);
  node.textContent = text;
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  return node;
}

function fixed(value, digits) {
  return value === null || value === undefined ? '-' : Number(value).toFixed(digits);
}

function distance(a, b) {
  return Math.hypot(a[0] - b[0], a[1] - b[1]);
}

function formatDistance(m) {
  return m >= 1000 ? `${(m / 1000).toFixed(1)} km` : `${Math.round(m)} m`;
}

function formatSeconds(s) {
  if (!isFinite(s)) return '-';
  return s >= 120 ? `${Math.floor(s / 60)} min ${Math.round(s % 60)} s` : `${Math.round(s)} s`;
}

function clock(seconds) {
  return new Date(seconds * 1000).toTimeString().slice(0, 8);
}

// A notice clears itself: what went well after NOTICE_OK_MS, a refusal after NOTICE_ERROR_MS
// (long enough to read; the status box keeps what the UAVs said).
const NOTICE_OK_MS = 6000;
const NOTICE_ERROR_MS = 15000;
let noticeTimer = null;

function notice(text, ok) {
  const node = $('#notice');
  node.textContent = text;
  node.className = ok ? 'ok' : 'error';
  node.hidden = false;
  clearTimeout(noticeTimer);
  noticeTimer = setTimeout(() => { node.hidden = true; }, ok ? NOTICE_OK_MS : NOTICE_ERROR_MS);
}

function liveIds() {
  return state.uavs.map((u) => u.id);
}

function team() {
  return liveIds().filter((id) => !state.excluded.has(id));
}

function phaseOf(uav) {
  return uav.phase === null || uav.phase === undefined ? 'none' : String(uav.phase);
}

// A target of the list has the mission's state when it is the mission's target at that index.
function targetStateOf(index) {
  const m = state.mission;
  const t = state.targets[index];
  if (m && index < m.targets.length) {
    if (sameTarget(m.targets[index], t) && m.target_states) return m.target_states[index];
  }
  return { index, state: 'draft', uav: null, eta_s: null };
}

function missionInFlight() {
  const m = state.mission;
  if (!m || m.aborted) return false;
  if (!m.complete) return true;
  return (m.target_states || []).some((t) => ACTIVE_TARGET_STATES.has(t.state));
}

// ---- the view box ---------------------------------------------------------------------------
function fitView() {
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

function applyView() {
  const v = state.view;
  if (!v) return;
  $('#map').setAttribute('viewBox', `${v.x} ${v.y} ${v.w} ${v.h}`);
  drawScale();
}

function drawScale() {
  const ppm = pixelsPerMetre();
  if (!ppm || !isFinite(ppm)) return;
  const wanted = 120 / ppm;
  const power = Math.pow(10, Math.floor(Math.log10(wanted)));
  const nice = [1, 2, 5, 10].map((k) => k * power).filter((m) => m <= wanted).pop() || power;
  $('#scale-bar').style.width = `${nice * ppm}px`;
  $('#scale-text').textContent = formatDistance(nice);
}

// ---- drawing --------------------------------------------------------------------------------
function ensureOrigin() {
  if (state.origin) return true;
  const placed = state.uavs.filter((u) => u.lat !== null);
  if (placed.length) {
    state.origin = {
      lat: placed.reduce((s, u) => s + u.lat, 0) / placed.length,
      lon: placed.reduce((s, u) => s + u.lon, 0) / placed.length,
    };
  } else if (state.targets.length) {
    state.origin = { lat: state.targets[0].lat, lon: state.targets[0].lon };
  }
  return state.origin !== null;
}

function render() {
  if (ensureOrigin()) {
    if (state.autoFit || !state.view) fitView();
    applyView();
    drawMap();
  }
  drawUavList();
  drawTargetList();
  drawMission();
}

function drawMap() {
  const scale = 1 / pixelsPerMetre();
  drawZones();
  drawRoutes();
  drawTrails();
  drawAssignments(scale);
  drawTargets(scale);
  drawMissionTargets(scale);
  drawUavs(scale);
}

function uavAttributes(u) {
  return {
    'data-uav': u.id,
    'data-phase': phaseOf(u),
    'data-link': u.link_lost ? 'lost' : 'ok',
    'data-module': u.enabled === false ? 'off' : 'on',
  };
}

function drawTrails() {
  const layer = $('#layer-trails');
  layer.replaceChildren();
  for (const u of state.uavs) {
    if (!u.trail || u.trail.length < 2) continue;
    const points = u.trail.map(([lat, lon]) => toXY(lat, lon).join(',')).join(' ');
    el('polyline', { class: 'trail', points, stroke: colourOf(u.id), ...uavAttributes(u) }, layer);
  }
}

function drawUavs(scale) {
  const layer = $('#layer-uavs');
  layer.replaceChildren();
  const members = new Set(team());
  for (const u of state.uavs) {
    if (u.lat === null) continue;
    const [x, y] = toXY(u.lat, u.lon);
    const g = el('g', {
      class: 'uav',
      transform: `translate(${x},${y}) scale(${scale})`,
      'data-lat': u.lat,
      'data-lon': u.lon,
      'data-heading': u.heading ?? '',
      ...uavAttributes(u),
    }, layer);
    if (members.has(u.id)) el('circle', { class: 'team-ring', r: 17, stroke: colourOf(u.id) }, g);
    const body = el('g', { transform: `rotate(${u.heading ?? 0})` }, g);
    el('path', { class: 'body', d: 'M0,-13 L9,10 L0,5 L-9,10 Z', fill: colourOf(u.id) }, body);
    const label = el('text', { class: 'id', x: 14, y: -6, fill: colourOf(u.id) }, g);
    label.textContent = u.id;
    const flags = [];
    if (u.link_lost) flags.push('LINK LOST');
    if (u.enabled === false) flags.push('OPM OFF');
    if (flags.length) {
      const flag = el('text', { class: 'flag', x: 14, y: 8 }, g);
      flag.textContent = flags.join(' · ');
    }
  }
}

function drawAssignments(scale) {
  const layer = $('#layer-assignments');
  layer.replaceChildren();
  const m = state.mission;
  if (!m || !m.target_states) return;
  const byId = new Map(state.uavs.map((u) => [u.id, u]));
  // Each UAV's tour: its targets still to fly, in queue order (issue 23).
  const tours = new Map();
  for (const t of m.target_states) {
    if (t.uav === null || t.state !== 'assigned') continue;
    if (!tours.has(t.uav)) tours.set(t.uav, []);
    tours.get(t.uav).push(t);
  }
  for (const [uavId, stops] of tours) {
    stops.sort((x, y) => (x.place ?? 0) - (y.place ?? 0));
    const u = byId.get(uavId);
    const first = stops[0];
    const target = m.targets[first.index];
    if (!u || u.lat === null || !target) continue;
    const a = toXY(u.lat, u.lon);
    const b = toXY(target.lat, target.lon);
    el('line', {
      class: 'assignment', x1: a[0], y1: a[1], x2: b[0], y2: b[1], stroke: colourOf(u.id),
      'data-target-index': first.index, 'data-routed': String(routed(u)), ...uavAttributes(u),
    }, layer);
    const togo = routeLength(u, a, b);
    const eta = u.ground_speed ? togo / u.ground_speed : Infinity;
    // Beside the UAV, on the side away from its line (a label half-way along the line
    // would cover a short line's target).
    const east = b[0] > a[0];
    const label = el('text', {
      class: 'assignment-label', fill: colourOf(u.id), x: east ? -16 : 16, y: 24,
      'text-anchor': east ? 'end' : 'start',
      transform: `translate(${a[0]},${a[1]}) scale(${scale})`,
      'data-uav': u.id, 'data-phase': phaseOf(u),
    }, layer);
    label.textContent = `→ ${first.index}: ${formatDistance(togo)}, ETA ${formatSeconds(eta)}`;
    drawTour(layer, scale, u, b, stops.slice(1), m);
  }
}

// The rest of a UAV's queue: a leg to each next target, its predicted arrival beside it.
function drawTour(layer, scale, u, from, stops, m) {
  let a = from;
  for (const t of stops) {
    const target = m.targets[t.index];
    if (!target) continue;
    const b = toXY(target.lat, target.lon);
    el('line', {
      class: 'tour', x1: a[0], y1: a[1], x2: b[0], y2: b[1], stroke: colourOf(u.id),
      'data-target-index': t.index, 'data-place': t.place ?? '', ...uavAttributes(u),
    }, layer);
    const label = el('text', {
      class: 'tour-label', fill: colourOf(u.id), x: 0, y: 30, 'text-anchor': 'middle',
      transform: `translate(${b[0]},${b[1]}) scale(${scale})`,
      'data-uav': u.id, 'data-target-index': t.index,
    }, layer);
    const eta = t.eta_s === null || t.eta_s === undefined ? '-' : formatSeconds(t.eta_s);
    label.textContent = `#${t.place ?? '?'} ETA ${eta}`;
    a = b;
  }
}

function drawTargets(scale) {
  const layer = $('#layer-targets');
  layer.replaceChildren();
  state.targets.forEach((t, index) => {
    const [x, y] = toXY(t.lat, t.lon);
    const s = targetStateOf(index);
    const g = el('g', {
      class: 'target', transform: `translate(${x},${y}) scale(${scale})`,
      'data-target': index, 'data-state': s.state, 'data-assigned': s.uav ?? '',
      'data-lat': t.lat, 'data-lon': t.lon,
    }, layer);
    el('circle', { class: 'hit', r: 12 }, g);
    el('circle', { class: 'ring', r: 13 }, g);
    el('path', { class: 'x', d: 'M-8,-8 L8,8 M-8,8 L8,-8' }, g);
    // Left of the X: a UAV's labels are right of its icon, so one over its target
    // does not cover them.
    const label = el('text', { class: 'index', x: -11, y: -7, 'text-anchor': 'end' }, g);
    label.textContent = index;
    const stateLabel = el('text', { class: 'state', x: -11, y: 16, 'text-anchor': 'end' }, g);
    stateLabel.textContent = s.uav !== null ? `${s.state} (UAV ${s.uav})` : s.state;
    g.addEventListener('pointerdown', (event) => startTargetDrag(event, index));
    g.addEventListener('contextmenu', (event) => {
      event.preventDefault();
      removeTarget(index);
    });
  });
}

// The followed mission's targets when the operator's list is not that mission (a mission
// from another ground arrived while the page held draft targets): drawn beside the
// drafts, read-only, with their states, so what the fleet flies is always on the map.
function drawMissionTargets(scale) {
  const layer = $('#layer-mission-targets');
  layer.replaceChildren();
  const m = state.mission;
  if (!m || !m.target_states || missionIsTheList()) return;
  m.targets.forEach((t, index) => {
    const [x, y] = toXY(t.lat, t.lon);
    const s = m.target_states[index];
    const g = el('g', {
      class: 'target mission-target', transform: `translate(${x},${y}) scale(${scale})`,
      'data-mission-target': index, 'data-state': s.state, 'data-assigned': s.uav ?? '',
    }, layer);
    el('circle', { class: 'ring', r: 13 }, g);
    el('path', { class: 'x', d: 'M-8,-8 L8,8 M-8,8 L8,-8' }, g);
    const label = el('text', { class: 'state', x: -11, y: 16, 'text-anchor': 'end' }, g);
    label.textContent = `M${m.mission}/${index}: ${s.uav !== null ? `${s.state} (UAV ${s.uav})` : s.state}`;
  });
}

function sameTarget(a, b) {
  return Math.abs(a.lat - b.lat) < 1e-9 && Math.abs(a.lon - b.lon) < 1e-9 && Math.abs(a.alt - b.alt) < 1e-6;
}

// Whether the operator's list is the followed mission's targets, one for one.
function missionIsTheList() {
  const m = state.mission;
  return m.targets.length === state.targets.length
    && m.targets.every((t, index) => sameTarget(t, state.targets[index]));
}

// ---- the side panel -------------------------------------------------------------------------
// The lists are updated in place, row by row (keyed by Piccolo ID and target index), never
// rebuilt: a row or button replaced between a press and its release loses the click, and
// snapshots arrive several times a second. Their clicks are handled once, on the table
// (onUavListClick, onTargetListClick), from the data attributes of what was pressed.
function keyedRow(body, key, attribute, make) {
  let row = body.querySelector(`tr[${attribute}="${key}"]`);
  if (!row) {
    row = make();
    row.setAttribute(attribute, key);
  }
  return row;
}

function setText(node, text) {
  const value = String(text);
  if (node.textContent !== value) node.textContent = value;
}

function setAttributes(node, attributes) {
  for (const [key, value] of Object.entries(attributes)) {
    if (node.getAttribute(key) !== String(value)) node.setAttribute(key, value);
  }
}

// Rows in `order`, each placed only if it is not where it belongs already; the rest go.
function placeRows(body, rows) {
  rows.forEach((row, position) => {
    if (body.children[position] !== row) body.insertBefore(row, body.children[position] || null);
  });
  while (body.children.length > rows.length) body.lastElementChild.remove();
}

function newUavRow() {
  const row = html('tr');
  const swatch = html('span', '', { class: 'swatch' });
  const first = html('td');
  first.appendChild(swatch);
  row.appendChild(first);
  for (const name of ['id', 'team', 'phase', 'target', 'alt', 'speed', 'link']) {
    row.appendChild(html('td', '', { 'data-cell': name, ...(name === 'team' ? { class: 'team' } : {}) }));
  }
  const opm = html('td', '', { class: 'opm' });
  opm.appendChild(html('button', '', {
    type: 'button', 'data-opm': '', title: 'turn the onboard planning module on or off',
  }));
  opm.appendChild(html('button', 'abort', {
    type: 'button', 'data-abort': '', title: 'abort this UAV alone; its teammates fly on',
  }));
  row.appendChild(opm);
  return row;
}

function abortable(m, u) {
  const done = m && u.mission === m.mission && u.phase === 'aborted';
  return Boolean(m && !m.aborted && !done && m.team.includes(u.id));
}

function drawUavList() {
  const body = $('#uav-list tbody');
  const members = new Set(team());
  const m = state.mission;
  const rows = state.uavs.map((u) => {
    const row = keyedRow(body, u.id, 'data-uav', newUavRow);
    setAttributes(row, uavAttributes(u));
    row.classList.toggle('in-team', members.has(u.id));
    row.querySelector('.swatch').style.background = colourOf(u.id);
    const cell = (name) => row.querySelector(`[data-cell="${name}"]`);
    setText(cell('id'), u.id);
    setText(cell('team'), members.has(u.id) ? '✓' : '');
    setText(cell('phase'), phaseOf(u));
    setText(cell('target'), u.target ?? '-');
    setText(cell('alt'), fixed(u.alt, 0));
    setText(cell('speed'), fixed(u.ground_speed, 1));
    setText(cell('link'), u.link_lost ? 'LOST' : `${fixed(u.telemetry_age_s, 1)} s`);
    const toggle = row.querySelector('[data-opm]');
    setAttributes(toggle, { 'data-opm': u.id });
    setText(toggle, u.enabled === false ? 'off → on' : 'on → off');
    const stop = row.querySelector('[data-abort]');
    setAttributes(stop, { 'data-abort': u.id });
    // Hidden, not removed, so the layout under the pointer does not shift as missions come;
    // a UAV already aborted in this mission has nothing left to abort.
    stop.style.visibility = abortable(m, u) ? 'visible' : 'hidden';
    return row;
  });
  placeRows(body, rows);
  updateFilter();
}

function onUavListClick(event) {
  const row = event.target.closest('tr[data-uav]');
  if (!row) return;
  const id = Number(row.getAttribute('data-uav'));
  const u = state.uavs.find((v) => v.id === id);
  if (!u) return;
  if (event.target.closest('[data-opm]')) {
    command({ cmd: 'opm', uav: id, enabled: u.enabled === false });
    return;
  }
  if (event.target.closest('[data-abort]')) {
    const m = state.mission;
    if (!abortable(m, u)) return;
    confirmThen(`Abort mission ${m.mission} for UAV ${id} alone?`,
      `UAV ${id} leaves its target and resumes its course; the rest of the team flies on.`,
      () => command({ cmd: 'abort', mission: m.mission, uav: id }));
    return;
  }
  if (state.excluded.has(id)) state.excluded.delete(id);
  else state.excluded.add(id);
  render();
}

// Latitude, longitude and altitude are edited in place, as numbers (Enter or leaving the
// field applies it); the range of each is the targets file's (fleet.mission.targets_file).
const TARGET_FIELDS = {
  lat: { min: -90, max: 90, step: 0.000001, digits: 6 },
  lon: { min: -180, max: 180, step: 0.000001, digits: 6 },
  alt: { min: -500, max: 10000, step: 1, digits: 0 },
};

function newTargetRow() {
  const row = html('tr');
  row.appendChild(html('td', '', { 'data-cell': 'index' }));
  for (const [name, range] of Object.entries(TARGET_FIELDS)) {
    const cell = html('td', '', { 'data-cell': name });
    cell.appendChild(html('input', '', {
      type: 'number', 'data-field': name, min: range.min, max: range.max, step: range.step,
      'aria-label': name,
    }));
    row.appendChild(cell);
  }
  row.appendChild(html('td', '', { class: 'state', 'data-cell': 'state' }));
  const cell = html('td');
  cell.appendChild(html('button', '✕', { type: 'button', title: 'delete this target', 'data-delete': '' }));
  row.appendChild(cell);
  return row;
}

function drawTargetList() {
  const body = $('#target-list tbody');
  const rows = state.targets.map((t, index) => {
    const s = targetStateOf(index);
    const row = keyedRow(body, index, 'data-target-row', newTargetRow);
    const cell = (name) => row.querySelector(`[data-cell="${name}"]`);
    setText(cell('index'), index);
    for (const [name, range] of Object.entries(TARGET_FIELDS)) {
      const input = cell(name).querySelector('input');
      // Never under the operator's fingers: a field being edited keeps what is typed.
      if (document.activeElement !== input) input.value = t[name].toFixed(range.digits);
    }
    setText(cell('state'), s.uav !== null ? `${s.state} (${s.uav})` : s.state);
    setAttributes(cell('state'), { 'data-state': s.state });
    setAttributes(row.querySelector('[data-delete]'), { 'data-delete': index });
    return row;
  });
  placeRows(body, rows);
}

function onTargetEdit(event) {
  const input = event.target.closest('input[data-field]');
  const row = input && input.closest('tr[data-target-row]');
  if (!row) return;
  const index = Number(row.getAttribute('data-target-row'));
  const name = input.getAttribute('data-field');
  const range = TARGET_FIELDS[name];
  const value = Number(input.value);
  if (input.value === '' || !isFinite(value) || value < range.min || value > range.max) {
    notice(`target ${index}: ${name} must be a number in [${range.min}, ${range.max}]`, false);
    input.value = state.targets[index][name].toFixed(range.digits);
    return;
  }
  state.targets[index] = { ...state.targets[index], [name]: value };
  render();
}

function onTargetListClick(event) {
  const button = event.target.closest('[data-delete]');
  if (button) removeTarget(Number(button.getAttribute('data-delete')));
}

function drawMission() {
  const box = $('#mission-progress');
  const m = state.mission;
  if (!m) {
    box.textContent = 'no mission yet';
    $('#mission-summary').textContent = 'no mission';
    return;
  }
  box.replaceChildren();
  const n = m.team.length;
  const committed = n - m.missing_assignments.length;
  let agreement = 'pending';
  let agreementClass = '';
  if (m.complete) {
    agreement = m.agreed ? `agreed (digest ${String(m.digest).slice(0, 12)})` : `DISAGREE: ${m.disagreed.join(', ')}`;
    agreementClass = m.agreed ? 'agreed' : 'disagreed';
  }
  const summary = `mission ${m.mission}${m.aborted ? ' (aborted)' : ''}: team ${m.team.join(', ')}; `
    + `results ${m.results_received}/${n}; committed ${committed}/${n}`;
  box.appendChild(html('div', summary, { id: 'mission-line' }));
  box.appendChild(html('div', `agreement: ${agreement}`, { class: agreementClass, id: 'agreement' }));
  const table = html('table');
  table.appendChild(html('tr')).append(html('th', '#'), html('th', 'state'), html('th', 'UAV'), html('th', 'predicted'));
  for (const t of m.target_states) {
    const row = html('tr', '', { 'data-mission-target': t.index, 'data-state': t.state });
    row.append(html('td', t.index), html('td', t.state), html('td', t.uav ?? '-'),
      html('td', t.eta_s === null ? '-' : formatSeconds(t.eta_s)));
    table.appendChild(row);
  }
  box.appendChild(table);
  $('#mission-summary').textContent = summary;
}

// ---- the status box -------------------------------------------------------------------------
function addStatuses(entries) {
  for (const entry of entries) {
    // The first snapshot's history and the next push can overlap.
    if (entry.seq <= state.lastSeq) continue;
    state.lastSeq = entry.seq;
    const previous = state.lastOf.get(entry.uav);
    // The modules repeat their summary every second: count repeats instead of listing them.
    if (previous && previous.text === entry.text) {
      previous.count += 1;
      previous.time = entry.time;
      continue;
    }
    const kept = { ...entry, count: 1 };
    state.statuses.push(kept);
    state.lastOf.set(entry.uav, kept);
    // A server without pinned alerts of its own: keep the latest warnings and errors.
    if (entry.severity !== 'info' && !state.serverAlerts) {
      state.alerts.push(entry);
      state.alerts = state.alerts.slice(-MAX_ALERTS);
    }
  }
  state.statuses = state.statuses.slice(-1000);
  drawStatuses();
}

function statusItem(entry) {
  const item = html('li', '', { 'data-severity': entry.severity, 'data-uav-status': entry.uav });
  item.append(html('span', `${clock(entry.time)} `, { class: 'time' }));
  const who = html('b', `UAV ${entry.uav} `);
  who.style.color = colourOf(entry.uav);
  item.append(who, html('span', `[${entry.severity}] `), html('span', entry.text));
  if (entry.count > 1) item.append(html('span', ` ×${entry.count}`, { class: 'count' }));
  return item;
}

function drawStatuses() {
  const filter = $('#status-filter').value;
  const keep = (s) => filter === 'all' || String(s.uav) === filter;
  const log = $('#status-log');
  const atBottom = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
  log.replaceChildren(...state.statuses.filter(keep).slice(-300).map(statusItem));
  if (atBottom) log.scrollTop = log.scrollHeight;
  $('#alerts').replaceChildren(...state.alerts.filter(keep).map(statusItem));
}

function updateFilter() {
  const select = $('#status-filter');
  const ids = new Set([...liveIds(), ...state.statuses.map((s) => s.uav)]);
  const have = new Set([...select.options].map((o) => o.value));
  for (const id of [...ids].sort((a, b) => a - b)) {
    if (!have.has(String(id))) select.appendChild(html('option', `UAV ${id}`, { value: String(id) }));
  }
}

// ---- targets: add, drag, delete, load, save -------------------------------------------------
function altitude() {
  const value = Number($('#alt').value);
  return isFinite(value) ? value : 600;
}

function addTargetAt(clientX, clientY) {
  if (!state.origin) return;
  const { lat, lon } = toLatLon(...clientToMap(clientX, clientY));
  state.targets.push({ lat, lon, alt: altitude() });
  render();
}

function removeTarget(index) {
  state.targets.splice(index, 1);
  render();
}

function startTargetDrag(event, index) {
  if (event.button !== 0) return;
  event.stopPropagation();
  const svg = $('#map');
  svg.setPointerCapture(event.pointerId);
  const move = (e) => {
    const { lat, lon } = toLatLon(...clientToMap(e.clientX, e.clientY));
    state.targets[index] = { ...state.targets[index], lat, lon };
    drawMap();
  };
  const up = () => {
    svg.removeEventListener('pointermove', move);
    svg.removeEventListener('pointerup', up);
    render();
  };
  svg.addEventListener('pointermove', move);
  svg.addEventListener('pointerup', up);
}

async function loadFile(file) {
  if (!state.targets.length) return importFile(file);
  confirmThen(`Replace the ${state.targets.length} target(s) on the map with ${file.name}'s?`,
    'The targets on the map are not kept (Save them first to keep them).', () => importFile(file));
}

async function importFile(file) {
  const error = $('#load-error');
  error.hidden = true;
  const response = await fetch(withToken(`api/targets/import?name=${encodeURIComponent(file.name)}`), {
    method: 'POST', body: await file.arrayBuffer(),
  });
  // A refusal by the web server itself (413: over its upload limit) is plain text.
  const json = (response.headers.get('content-type') || '').includes('json');
  const answer = json ? await response.json() : { error: `${file.name}: ${response.status} ${await response.text()}` };
  if (!response.ok) {
    error.textContent = answer.error;
    error.hidden = false;
    notice(`Load refused: ${answer.error}`, false);
    return;
  }
  state.targets = answer.targets;
  state.autoFit = true;
  state.view = null;
  notice(`${file.name}: ${answer.targets.length} targets loaded (not sent)`, true);
  render();
}

async function saveTargets(format) {
  const response = await fetch(withToken(`api/targets/export?format=${format}`), {
    method: 'POST', body: JSON.stringify(state.targets),
  });
  if (!response.ok) {
    notice(`Save refused: ${(await response.json()).error}`, false);
    return;
  }
  const link = html('a', '', { href: URL.createObjectURL(await response.blob()), download: `targets.${format}` });
  link.click();
  URL.revokeObjectURL(link.href);
}

// ---- commands -------------------------------------------------------------------------------
function command(body) {
  if (!state.ws || state.ws.readyState !== WebSocket.OPEN) {
    notice('not connected to the ground: nothing sent', false);
    return;
  }
  state.ws.send(JSON.stringify({ id: state.nextId++, ...body }));
}

function confirmThen(text, warning, action) {
  $('#confirm-text').textContent = text;
  $('#confirm-warning').textContent = warning;
  $('#confirm').hidden = false;
  const close = () => {
    $('#confirm').hidden = true;
    $('#confirm-ok').onclick = null;
    $('#confirm-cancel').onclick = null;
  };
  $('#confirm-ok').onclick = () => { close(); action(); };
  $('#confirm-cancel').onclick = close;
}

// What the operator should know before sending: a mission it replaces, targets no UAV will
// fly, team UAVs that will take no part.
function sendWarnings(members, count) {
  const warnings = [];
  if (missionInFlight()) warnings.push(`Mission ${state.mission.mission} is in flight: this mission replaces it.`);
  if (count > members.length) {
    warnings.push(`${count} targets for ${members.length} UAV(s): each UAV queues several and flies them in turn.`);
  }
  const off = state.uavs.filter((u) => members.includes(u.id) && u.enabled === false).map((u) => u.id);
  if (off.length) warnings.push(`Module off on UAV ${off.join(', ')}: it takes no part.`);
  const lost = state.uavs.filter((u) => members.includes(u.id) && u.link_lost).map((u) => u.id);
  if (lost.length) warnings.push(`Autopilot link lost on UAV ${lost.join(', ')}: it cannot fly.`);
  return warnings;
}

function sendTargets() {
  const members = team();
  if (!members.length) return notice('no team: click UAVs in the list to select them', false);
  if (!state.targets.length) return notice('no targets: click the map to add some', false);
  const targets = state.targets.map((t) => ({ lat: t.lat, lon: t.lon, alt: t.alt }));
  confirmThen(
    `Send ${targets.length} target(s) to the team of ${members.length} UAV(s): ${members.join(', ')} (objective ${$('#objective').value})?`,
    sendWarnings(members, targets.length).join(' '),
    () => command({
      cmd: 'send', team: members, targets, zones: zonesToSend(), objective: $('#objective').value,
    }),
  );
}

function abortTeam() {
  const m = state.mission;
  if (!m) return notice('no mission to abort', false);
  confirmThen(`Abort mission ${m.mission} for its team ${m.team.join(', ')}?`,
    'Every UAV of the team leaves its target and resumes its course.',
    () => command({ cmd: 'abort', mission: m.mission }));
}

// ---- the connection -------------------------------------------------------------------------
function onSnapshot(snapshot) {
  state.uavs = snapshot.uavs;
  state.mission = snapshot.mission;
  const m = snapshot.mission;
  if (m && m.mission !== state.seenMission) {
    state.seenMission = m.mission;
    // A page opened during a mission (or a mission from another ground) shows its targets.
    if (!state.targets.length) state.targets = m.targets.map((t) => ({ ...t }));
    else if (!missionIsTheList()) notice(`mission ${m.mission} (${m.targets.length} targets) from elsewhere is drawn beside your draft`, true);
  }
  // The server pins each UAV's warnings and errors until that UAV says they cleared.
  if (Array.isArray(snapshot.alerts)) {
    state.serverAlerts = true;
    state.alerts = snapshot.alerts.slice().reverse();
  }
  addStatuses(snapshot.statuses);
  render();
}

function connect() {
  const url = new URL(withToken('ws'), location.href);
  url.protocol = location.protocol === 'https:' ? 'wss:' : 'ws:';
  // This run's session token, which only the page the server served holds.
  const session = document.querySelector('meta[name="fleet-session"]');
  if (session) url.searchParams.set('session', session.content);
  const ws = new WebSocket(url);
  state.ws = ws;
  const connection = $('#connection');
  ws.onopen = () => {
    connection.dataset.state = 'open';
    connection.textContent = 'connected';
    // The server replays its status history to every new connection.
    Object.assign(state, { statuses: [], alerts: [], lastOf: new Map(), lastSeq: 0 });
  };
  ws.onclose = () => {
    connection.dataset.state = 'closed';
    connection.textContent = 'disconnected: retrying';
    setTimeout(connect, 1000);
  };
  ws.onmessage = (event) => {
    const message = JSON.parse(event.data);
    if (message.type === 'snapshot') onSnapshot(message);
    else if (message.type === 'reply') notice(message.message, message.ok);
  };
}

// ---- map interaction ------------------------------------------------------------------------
function setUpMap() {
  const svg = $('#map');
  let press = null;
  svg.addEventListener('pointerdown', (event) => {
    if (event.button !== 0 || !state.view) return;
    press = { x: event.clientX, y: event.clientY, view: { ...state.view }, moved: false };
    svg.setPointerCapture(event.pointerId);
  });
  svg.addEventListener('pointermove', (event) => {
    if (state.origin) {
      const { lat, lon } = toLatLon(...clientToMap(event.clientX, event.clientY));
      $('#cursor').textContent = `${lat.toFixed(5)}, ${lon.toFixed(5)}`;
    }
    if (!press) return;
    const dx = event.clientX - press.x;
    const dy = event.clientY - press.y;
    if (!press.moved && Math.hypot(dx, dy) < 5) return;
    press.moved = true;
    svg.classList.add('panning');
    const ppm = pixelsPerMetre();
    state.autoFit = false;
    state.view = { ...press.view, x: press.view.x - dx / ppm, y: press.view.y - dy / ppm };
    applyView();
  });
  svg.addEventListener('pointerup', (event) => {
    if (press && !press.moved && !addZoneVertexAt(event.clientX, event.clientY)) {
      addTargetAt(event.clientX, event.clientY);
    }
    press = null;
    svg.classList.remove('panning');
    render();
  });
  svg.addEventListener('wheel', (event) => {
    event.preventDefault();
    if (!state.view) return;
    const [mx, my] = clientToMap(event.clientX, event.clientY);
    const k = event.deltaY > 0 ? 1.25 : 0.8;
    const v = state.view;
    state.autoFit = false;
    state.view = { x: mx - (mx - v.x) * k, y: my - (my - v.y) * k, w: v.w * k, h: v.h * k };
    render();
  }, { passive: false });
  new ResizeObserver(() => render()).observe(svg);
}

function setUpPanel() {
  $('#fit').addEventListener('click', () => { state.autoFit = true; state.view = null; render(); });
  $('#uav-list tbody').addEventListener('click', onUavListClick);
  $('#target-list tbody').addEventListener('click', onTargetListClick);
  $('#target-list tbody').addEventListener('change', onTargetEdit);
  $('#send').addEventListener('click', sendTargets);
  $('#abort').addEventListener('click', abortTeam);
  $('#clear-targets').addEventListener('click', () => { state.targets = []; render(); });
  $('#status-filter').addEventListener('change', drawStatuses);
  $('#load-file').addEventListener('change', (event) => {
    const file = event.target.files[0];
    if (file) loadFile(file);
    event.target.value = '';
  });
  for (const button of document.querySelectorAll('[data-save]')) {
    button.addEventListener('click', () => saveTargets(button.dataset.save));
  }
  const panel = $('#targets-panel');
  panel.addEventListener('dragover', (event) => { event.preventDefault(); panel.classList.add('dropping'); });
  panel.addEventListener('dragleave', () => panel.classList.remove('dropping'));
  panel.addEventListener('drop', (event) => {
    event.preventDefault();
    panel.classList.remove('dropping');
    const file = event.dataTransfer.files[0];
    if (file) loadFile(file);
  });
}

setUpMap();
setUpPanel();
setUpZones();
connect();
