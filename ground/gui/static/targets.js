// The draft targets: add, drag, delete, load, save.
import { confirmThen } from './commands.js';
import { clientToMap, toLatLon } from './frame.js';
import { html, notice } from './helpers.js';
import { drawMap, render } from './map.js';
import { $, state, withToken } from './state.js';

// ---- targets: add, drag, delete, load, save -------------------------------------------------
export function altitude() {
  const value = Number($('#alt').value);
  return isFinite(value) ? value : 600;
}

export function addTargetAt(clientX, clientY) {
  if (!state.origin) return;
  const { lat, lon } = toLatLon(...clientToMap(clientX, clientY));
  state.targets.push({ lat, lon, alt: altitude() });
  render();
}

// A draft typed as "lat, lon" (degrees), at the altitude of new targets.
export function addTargetTyped(event) {
  event.preventDefault();
  const field = $('#add-at-text');
  const parts = field.value.split(/[\s,;]+/).filter(Boolean).map(Number);
  const [lat, lon] = parts;
  if (parts.length !== 2 || !parts.every(isFinite) || Math.abs(lat) > 90 || Math.abs(lon) > 180) {
    return notice(`"${field.value}": type a latitude and a longitude in degrees, e.g. 35.705, -120.76`, false);
  }
  state.targets.push({ lat, lon, alt: altitude() });
  field.value = '';
  render();
}

export function removeTarget(index) {
  state.targets.splice(index, 1);
  render();
}

export function startTargetDrag(event, index) {
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

export async function loadFile(file) {
  if (!state.targets.length) return importFile(file);
  confirmThen(`Replace the ${state.targets.length} target(s) on the map with ${file.name}'s?`,
    'The targets on the map are not kept (Save them first to keep them).', () => importFile(file));
}

export async function importFile(file) {
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

export async function saveTargets(format) {
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
