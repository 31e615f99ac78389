// The Mission Manager's page: a live map of the fleet, targets by click, send, watch, abort.
// Plain JavaScript modules, no library, no build step. The server pushes snapshots on one
// WebSocket and takes commands on it; see ground/gui/server.py for the protocol.
import { abortTeam, addToMission, onObjectiveChange, sendTargets } from './commands.js';
import { connect } from './connection.js';
import { applyView, clientToMap, pixelsPerMetre, toLatLon } from './frame.js';
import { notice } from './helpers.js';
import { render } from './map.js';
import { onMissionTableClick, onTargetEdit, onTargetListClick, onUavListClick } from './panel.js';
import { $, state } from './state.js';
import { drawStatuses } from './statuses.js';
import { addTargetAt, addTargetTyped, loadFile, saveTargets } from './targets.js';
import { addZoneVertexAt, drawZoneList, setUpZones, zones } from './zones.js';

// ---- map interaction ------------------------------------------------------------------------
export function setUpMap() {
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

export function setUpPanel() {
  $('#fit').addEventListener('click', () => { state.autoFit = true; state.view = null; render(); });
  $('#uav-list tbody').addEventListener('click', onUavListClick);
  $('#target-list tbody').addEventListener('click', onTargetListClick);
  $('#target-list tbody').addEventListener('change', onTargetEdit);
  $('#send').addEventListener('click', sendTargets);
  $('#objective').addEventListener('change', onObjectiveChange);
  onObjectiveChange();
  $('#add-to-mission').addEventListener('click', addToMission);
  $('#add-at').addEventListener('submit', addTargetTyped);
  $('#mission-targets tbody').addEventListener('click', onMissionTableClick);
  $('#abort').addEventListener('click', abortTeam);
  $('#clear-targets').addEventListener('click', () => { state.targets = []; render(); });
  $('#mission-to-drafts').addEventListener('click', missionToDrafts);
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

// The followed mission's targets and zones as drafts, to edit and send again (never done
// on its own: a mission is not a draft).
function missionToDrafts() {
  const m = state.mission;
  if (!m) return notice('no mission to copy', false);
  state.targets = m.targets.map((t) => ({ lat: t.lat, lon: t.lon, alt: t.alt }));
  zones.draft = (m.zones || []).map((z) => ({ name: z.name || '', ring: z.ring }));
  drawZoneList();
  notice(`mission ${m.mission}: ${m.targets.length} target(s) copied to the drafts (not sent)`, true);
  render();
}

setUpMap();
setUpPanel();
setUpZones();
connect();
