// Colours, elements, formats, the notice, and what the snapshot says of the team.
import { $, ACTIVE_TARGET_STATES, state, SVG_NS } from './state.js';

// ---- helpers --------------------------------------------------------------------------------
// Each Piccolo ID its own colour, the same on every page: hues a golden angle apart.
export function colourOf(uav) {
  return `hsl(${(uav * 137.508) % 360}, 75%, 38%)`;
}

export function el(name, attributes = {}, parent = null) {
  const node = document.createElementNS(SVG_NS, name);
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  if (parent) parent.appendChild(node);
  return node;
}

export function html(name, text = '', attributes = {}) {
  const node = document.createElement(name);
  node.textContent = text;
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  return node;
}

export function fixed(value, digits) {
  return value === null || value === undefined ? '-' : Number(value).toFixed(digits);
}

export function distance(a, b) {
  return Math.hypot(a[0] - b[0], a[1] - b[1]);
}

export function formatDistance(m) {
  return m >= 1000 ? `${(m / 1000).toFixed(1)} km` : `${Math.round(m)} m`;
}

export function formatSeconds(s) {
  if (!isFinite(s)) return '-';
  return s >= 120 ? `${Math.floor(s / 60)} min ${Math.round(s % 60)} s` : `${Math.round(s)} s`;
}

export function clock(seconds) {
  return new Date(seconds * 1000).toTimeString().slice(0, 8);
}

// A notice clears itself: what went well after NOTICE_OK_MS, a refusal after NOTICE_ERROR_MS
// (long enough to read; the status box keeps what the UAVs said).
export const NOTICE_OK_MS = 6000;
export const NOTICE_ERROR_MS = 15000;
export let noticeTimer = null;

export function notice(text, ok) {
  const node = $('#notice');
  node.textContent = text;
  node.className = ok ? 'ok' : 'error';
  node.hidden = false;
  clearTimeout(noticeTimer);
  noticeTimer = setTimeout(() => { node.hidden = true; }, ok ? NOTICE_OK_MS : NOTICE_ERROR_MS);
}

export function liveIds() {
  return state.uavs.map((u) => u.id);
}

export function team() {
  return liveIds().filter((id) => !state.excluded.has(id));
}

export function phaseOf(uav) {
  return uav.phase === null || uav.phase === undefined ? 'none' : String(uav.phase);
}

// The operator's list holds drafts only: a target sent is the mission's, shown apart.
export function targetStateOf(index) {
  return { index, state: 'draft', uav: null, eta_s: null };
}

export function missionInFlight() {
  const m = state.mission;
  if (!m || m.aborted) return false;
  if (!m.complete) return true;
  return (m.target_states || []).some((t) => ACTIVE_TARGET_STATES.has(t.state));
}
