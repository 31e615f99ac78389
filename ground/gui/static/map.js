// Drawing the map: trails, UAVs, assignment lines and tours, the operator's draft
// targets and the followed mission's targets.
import { applyView, fitView, pixelsPerMetre, toXY } from './frame.js';
import { colourOf, el, formatDistance, formatSeconds, phaseOf, targetStateOf, team } from './helpers.js';
import { drawMission, drawTargetList, drawUavList } from './panel.js';
import { $, state } from './state.js';
import { removeTarget, startTargetDrag } from './targets.js';
import { drawRoutes, drawZones, routed, routeLength } from './zones.js';

// ---- drawing --------------------------------------------------------------------------------
export function ensureOrigin() {
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

export function render() {
  if (ensureOrigin()) {
    if (state.autoFit || !state.view) fitView();
    applyView();
    drawMap();
  }
  drawUavList();
  drawTargetList();
  drawMission();
}

export function drawMap() {
  const scale = 1 / pixelsPerMetre();
  drawZones();
  drawRoutes();
  drawTrails();
  drawAssignments(scale);
  drawTargets(scale);
  drawMissionTargets(scale);
  drawUavs(scale);
}

export function uavAttributes(u) {
  return {
    'data-uav': u.id,
    'data-phase': phaseOf(u),
    'data-link': u.link_lost ? 'lost' : 'ok',
    'data-module': u.enabled === false ? 'off' : 'on',
  };
}

export function drawTrails() {
  const layer = $('#layer-trails');
  layer.replaceChildren();
  for (const u of state.uavs) {
    if (!u.trail || u.trail.length < 2) continue;
    const points = u.trail.map(([lat, lon]) => toXY(lat, lon).join(',')).join(' ');
    el('polyline', { class: 'trail', points, stroke: colourOf(u.id), ...uavAttributes(u) }, layer);
  }
}

export function drawUavs(scale) {
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

export function drawAssignments(scale) {
  const layer = $('#layer-assignments');
  layer.replaceChildren();
  const m = state.mission;
  if (!m || !m.target_states) return;
  const byId = new Map(state.uavs.map((u) => [u.id, u]));
  // Each UAV's tour: its targets still to fly, in queue order.
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
export function drawTour(layer, scale, u, from, stops, m) {
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

export function drawTargets(scale) {
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
    stateLabel.textContent = 'draft';
    g.addEventListener('pointerdown', (event) => startTargetDrag(event, index));
    g.addEventListener('contextmenu', (event) => {
      event.preventDefault();
      removeTarget(index);
    });
  });
}

// The followed mission's targets, read-only, with their states: what the fleet flies is
// always on the map, drawn apart from the operator's drafts (solid, with the mission's
// number; drafts are dashed and grey).
export function drawMissionTargets(scale) {
  const layer = $('#layer-mission-targets');
  layer.replaceChildren();
  const m = state.mission;
  if (!m || !m.target_states) return;
  m.targets.forEach((t, index) => {
    const [x, y] = toXY(t.lat, t.lon);
    const s = m.target_states[index];
    const g = el('g', {
      class: 'target mission-target', transform: `translate(${x},${y}) scale(${scale})`,
      'data-mission-target': index, 'data-state': s.state, 'data-assigned': s.uav ?? '',
      'data-mission': m.mission, 'data-lat': t.lat, 'data-lon': t.lon,
    }, layer);
    el('circle', { class: 'ring', r: 13 }, g);
    el('path', { class: 'x', d: 'M-8,-8 L8,8 M-8,8 L8,-8' }, g);
    const number = el('text', { class: 'index', x: -11, y: -7, 'text-anchor': 'end' }, g);
    number.textContent = `M${m.mission}/${index}`;
    const label = el('text', { class: 'state', x: -11, y: 16, 'text-anchor': 'end' }, g);
    label.textContent = s.uav !== null ? `${s.state} (UAV ${s.uav})` : s.state;
  });
}

export function sameTarget(a, b) {
  return Math.abs(a.lat - b.lat) < 1e-9 && Math.abs(a.lon - b.lon) < 1e-9 && Math.abs(a.alt - b.alt) < 1e-6;
}
