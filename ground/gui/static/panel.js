// The side panel: the UAV list, the draft targets' list, the mission table.
import { command, confirmThen } from './commands.js';
import { colourOf, fixed, formatSeconds, html, notice, phaseOf, targetStateOf, team } from './helpers.js';
import { render, uavAttributes } from './map.js';
import { $, state } from './state.js';
import { updateFilter } from './statuses.js';
import { removeTarget } from './targets.js';

// ---- the side panel -------------------------------------------------------------------------
// The lists are updated in place, row by row (keyed by Piccolo ID and target index), never
// rebuilt: a row or button replaced between a press and its release loses the click, and
// snapshots arrive several times a second. Their clicks are handled once, on the table
// (onUavListClick, onTargetListClick), from the data attributes of what was pressed.
export function keyedRow(body, key, attribute, make) {
  let row = body.querySelector(`tr[${attribute}="${key}"]`);
  if (!row) {
    row = make();
    row.setAttribute(attribute, key);
  }
  return row;
}

export function setText(node, text) {
  const value = String(text);
  if (node.textContent !== value) node.textContent = value;
}

export function setAttributes(node, attributes) {
  for (const [key, value] of Object.entries(attributes)) {
    if (node.getAttribute(key) !== String(value)) node.setAttribute(key, value);
  }
}

// Rows in `order`, each placed only if it is not where it belongs already; the rest go.
export function placeRows(body, rows) {
  rows.forEach((row, position) => {
    if (body.children[position] !== row) body.insertBefore(row, body.children[position] || null);
  });
  while (body.children.length > rows.length) body.lastElementChild.remove();
}

export function newUavRow() {
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

export function abortable(m, u) {
  const done = m && u.mission === m.mission && u.phase === 'aborted';
  return Boolean(m && !m.aborted && !done && m.team.includes(u.id));
}

export function drawUavList() {
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

export function onUavListClick(event) {
  const row = event.target.closest('tr[data-uav]');
  if (!row) return;
  const id = Number(row.getAttribute('data-uav'));
  const u = state.uavs.find((v) => v.id === id);
  if (!u) return;
  if (event.target.closest('[data-opm]')) {
    const on = u.enabled === false;
    command({ cmd: 'opm', uav: id, enabled: on }, `Planning module ${on ? 'on' : 'off'} on UAV ${id}`);
    return;
  }
  if (event.target.closest('[data-abort]')) {
    const m = state.mission;
    if (!abortable(m, u)) return;
    confirmThen(`Abort mission ${m.mission} for UAV ${id} alone?`,
      `UAV ${id} leaves its target and resumes its course; the rest of the team flies on.`,
      () => command({ cmd: 'abort', mission: m.mission, uav: id }, `Abort UAV ${id} (mission ${m.mission})`));
    return;
  }
  if (state.excluded.has(id)) state.excluded.delete(id);
  else state.excluded.add(id);
  render();
}

// Latitude, longitude and altitude are edited in place, as numbers (Enter or leaving the
// field applies it); the range of each is the targets file's (fleet.mission.targets_file).
export const TARGET_FIELDS = {
  lat: { min: -90, max: 90, step: 0.000001, digits: 6 },
  lon: { min: -180, max: 180, step: 0.000001, digits: 6 },
  alt: { min: -500, max: 10000, step: 1, digits: 0 },
};

export function newTargetRow() {
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

export function drawTargetList() {
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

export function onTargetEdit(event) {
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

export function onTargetListClick(event) {
  const button = event.target.closest('[data-delete]');
  if (button) removeTarget(Number(button.getAttribute('data-delete')));
}

// A mission target the operator may still take off the mission: not flown yet, not gone.
const REMOVABLE = new Set(['pending', 'assigned']);

export function newMissionRow() {
  const row = html('tr');
  for (const name of ['index', 'state', 'uav', 'eta']) row.appendChild(html('td', '', { 'data-cell': name }));
  const cell = html('td');
  cell.appendChild(html('button', '✕', {
    type: 'button', 'data-remove-target': '',
    title: 'remove this target from the mission in flight (every live UAV of the team must acknowledge it)',
  }));
  row.appendChild(cell);
  return row;
}

// The mission's table, updated row by row (its remove buttons must survive the pushes).
export function drawMission() {
  const m = state.mission;
  const table = $('#mission-targets');
  if (!m) {
    $('#mission-line').textContent = 'no mission yet';
    $('#agreement').textContent = '';
    $('#proposal').hidden = true;
    $('#proposals').hidden = true;
    table.hidden = true;
    $('#mission-summary').textContent = 'no mission';
    return;
  }
  const n = m.team.length;
  const committed = n - m.missing_assignments.length;
  let agreement = 'pending';
  let agreementClass = '';
  if (m.complete) {
    agreement = m.agreed ? `agreed (digest ${String(m.digest).slice(0, 12)})` : `DISAGREE: ${m.disagreed.join(', ')}`;
    agreementClass = m.agreed ? 'agreed' : 'disagreed';
  }
  const revision = m.revision ? ` revision ${m.revision}` : '';
  const summary = `mission ${m.mission}${revision}${m.aborted ? ' (aborted)' : ''}: team ${m.team.join(', ')}; `
    + `results ${m.results_received}/${n}; committed ${committed}/${n}`;
  setText($('#mission-line'), summary);
  const line = $('#agreement');
  setText(line, `agreement: ${agreement}`);
  if (line.className !== agreementClass) line.className = agreementClass;
  drawProposal(m.proposal);
  drawProposals(m.proposals, m.proposal);
  table.hidden = false;
  const body = table.querySelector('tbody');
  const rows = m.target_states.map((t) => {
    const row = keyedRow(body, t.index, 'data-mission-target', newMissionRow);
    setAttributes(row, { 'data-state': t.state });
    const cell = (name) => row.querySelector(`[data-cell="${name}"]`);
    setText(cell('index'), t.index);
    setText(cell('state'), t.state);
    setText(cell('uav'), t.uav ?? '-');
    setText(cell('eta'), t.eta_s === null || t.eta_s === undefined ? '-' : formatSeconds(t.eta_s));
    const button = row.querySelector('[data-remove-target]');
    setAttributes(button, { 'data-remove-target': t.index });
    // Hidden, not removed: the rows under the pointer keep their layout.
    button.style.visibility = !m.aborted && REMOVABLE.has(t.state) ? 'visible' : 'hidden';
    return row;
  });
  placeRows(body, rows);
  setText($('#mission-summary'), summary);
}

// The ground's Piccolo ID, as a proposer.
const MISSION_MANAGER = 0xFFFE;

// What the UAVs' first plans say of a proposal (the ground's or a UAV's): adopted only when
// their reported digest is the digest of a plan adopted from it.
function verdictText(p) {
  const ids = (uavs) => uavs.join(', ') || 'none';
  if (p.verdict === 'adopted') return `adopted by ${ids(p.adopted_by)} (proposer ${p.proposer}, digest ${p.adopted_digest})`;
  if (p.verdict === 'baseline') return `not adopted: ${ids(p.baseline_by)} kept the baseline (digest ${p.baseline_digest})`;
  const instead = (p.instead || []).map((i) => `${i.proposer === MISSION_MANAGER ? "the ground's" : `UAV ${i.proposer}'s`} adopted by ${ids(i.adopted_by)}`);
  const also = instead.length ? ` (${instead.join('; ')})` : '';
  if (p.verdict === 'other') return `not adopted: ${ids(p.other_by)} took another plan${also}`;
  if (p.verdict === 'mixed') {
    return `adopted by ${ids(p.adopted_by)}, baseline by ${ids(p.baseline_by)}, other plans by ${ids(p.other_by)}${also}`;
  }
  if (p.verdict === 'waiting') return 'no commitment heard yet';
  return '';
}

// The UAVs' checks of a proposal, run by the ground on the team's results: its score
// (last arrival, arrivals summed), or why every UAV refuses it, or why it is not checked.
function checkText(p) {
  if (p.check === 'valid' && p.score) {
    return `last arrival ${formatSeconds(p.score.makespan_s)}, summed ${formatSeconds(p.score.total_s)}`;
  }
  if (p.check === 'refused') return `refused by the UAVs' checks: ${p.problem}`;
  if (p.check === 'unchecked') return `not checked: ${p.problem}`;
  return '';
}

// The ground's proposed plan for the mission (sent with "propose a plan"), and what the
// UAVs' commitments say of it.
function drawProposal(p) {
  const box = $('#proposal');
  if (!p) {
    box.hidden = true;
    return;
  }
  box.hidden = false;
  let text = `proposal: ${p.state}`;
  if (p.reason) text += ` (${p.reason})`;
  if (p.cpu_s !== null && p.cpu_s !== undefined) text += `, ${p.cpu_s.toFixed(2)} s of CPU`;
  const verdict = verdictText(p);
  if (verdict) text += `; ${verdict}`;
  const check = checkText(p);
  if (check) text += `; ${check}`;
  setText(box, text);
  setAttributes(box, { 'data-verdict': p.verdict, 'data-state': p.state });
}

// The list's item keyed `key`, made if it is not there yet (kept across pushes, as rows are).
function keyedItem(list, key) {
  let item = list.querySelector(`li[data-proposal="${key}"]`);
  if (!item) item = html('li', '', { 'data-proposal': key });
  return item;
}

// Every proposal heard for the mission (a UAV's, and the ground's unless this page's own
// line above shows it), each with its proposer, its score and its verdict; the named
// proposers not heard; the plans the UAVs committed to, with their scores.
function drawProposals(all, own) {
  const list = $('#proposals');
  if (!all) {
    list.hidden = true;
    return;
  }
  const rows = [];
  for (const p of all.heard) {
    if (own && own.proposer === p.proposer) continue;
    const row = keyedItem(list, `p${p.proposer}`);
    setText(row, `${p.by}'s proposal: ${[checkText(p), verdictText(p)].filter(Boolean).join('; ')}`);
    setAttributes(row, { 'data-proposer': p.proposer, 'data-verdict': p.verdict, 'data-check': p.check });
    rows.push(row);
  }
  for (const uav of all.not_heard) {
    if (uav === MISSION_MANAGER) continue; // the ground's own: the line above says why
    const row = keyedItem(list, `n${uav}`);
    const declined = (all.declined || []).includes(uav);
    setText(row, declined
      ? `UAV ${uav}: no proposal (its result said it will not propose: not waited for)`
      : `UAV ${uav}: no proposal heard`);
    setAttributes(row, { 'data-proposer': uav, 'data-verdict': 'none' });
    rows.push(row);
  }
  for (const plan of all.plans) {
    const row = keyedItem(list, `d${plan.digest}`);
    setText(row, `committed by ${plan.by.join(', ')}: digest ${plan.digest}, last arrival `
      + `${formatSeconds(plan.score.makespan_s)}, summed ${formatSeconds(plan.score.total_s)}`);
    setAttributes(row, { 'data-plan': plan.digest });
    rows.push(row);
  }
  placeRows(list, rows);
  list.hidden = rows.length === 0;
}

export function onMissionTableClick(event) {
  const button = event.target.closest('[data-remove-target]');
  const m = state.mission;
  if (!button || !m) return;
  const index = Number(button.getAttribute('data-remove-target'));
  confirmThen(`Remove target ${index} from mission ${m.mission} in flight?`,
    'Its holder drops it; it is never flown from then on. Every live UAV of the team must acknowledge it.',
    () => command({ cmd: 'remove-targets', mission: m.mission, indexes: [index] },
      `Remove target ${index} (mission ${m.mission})`));
}
