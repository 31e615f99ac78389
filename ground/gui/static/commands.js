// Commands to the fleet: confirmed, sent with an id, followed until answered.
import { html, missionInFlight, notice, team } from './helpers.js';
import { render, sameTarget } from './map.js';
import { $, state } from './state.js';
import { drawZoneList, zones, zonesToSend } from './zones.js';

// Every command carries an id of this page and press, and stays in the Commands list
// until the ground answers it: pending (waiting for the connection, then received), then
// done or failed. A socket that drops is opened again (connection.js) and every command
// not answered yet is sent again with its id: the ground carries out an id once and
// answers a repeat with its first reply (ground/gui/ledger.py), so a press is never lost
// and never done twice.
const PAGE = `${Date.now().toString(36)}-${Math.random().toString(36).slice(2, 10)}`;
const SHOWN = 8;
const ledger = new Map(); // id -> {id, body, label, state, acked, message, onDone}

export function command(body, label, onDone = null) {
  const id = `${PAGE}-${state.nextId++}`;
  const entry = {
    id, body: { id, ...body }, label, state: 'pending', acked: false, message: '', onDone,
  };
  ledger.set(id, entry);
  transmit(entry);
  drawCommands();
  return entry;
}

function transmit(entry) {
  const ws = state.ws;
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(entry.body));
}

// After a (re)connection: every command not answered yet, again, in the order pressed.
export function resendUnanswered() {
  for (const entry of ledger.values()) if (entry.state === 'pending') transmit(entry);
  drawCommands();
}

export function onAck(message) {
  const entry = ledger.get(message.id);
  if (!entry || entry.acked) return;
  entry.acked = true;
  drawCommands();
}

export function onReply(message) {
  const entry = ledger.get(message.id);
  // A repeat's answer (sent before the socket dropped, and again after): once is enough.
  if (entry && entry.state !== 'pending') return;
  notice(message.message, message.ok);
  if (!entry) return;
  Object.assign(entry, { state: message.ok ? 'done' : 'failed', acked: true, message: message.message });
  if (entry.onDone) entry.onDone(message);
  // Answered commands beyond the list's length are forgotten; pending ones never.
  const answered = [...ledger.values()].filter((e) => e.state !== 'pending');
  for (const old of answered.slice(0, -SHOWN)) ledger.delete(old.id);
  drawCommands();
}

function commandState(entry) {
  if (entry.state !== 'pending') return entry.state;
  if (entry.acked) return 'pending: received by the ground';
  return state.ws && state.ws.readyState === WebSocket.OPEN
    ? 'pending: sent' : 'pending: waiting for the connection';
}

export function drawCommands() {
  const list = $('#command-list');
  if (!list) return;
  const shown = [...ledger.values()].slice(-SHOWN).reverse();
  list.replaceChildren(...shown.map((entry) => {
    const item = html('li', '', {
      'data-command-id': entry.id, 'data-command-state': entry.state, 'data-cmd': entry.body.cmd,
    });
    item.append(html('b', `${entry.label} `), html('span', commandState(entry), { class: 'command-state' }));
    if (entry.message) item.append(html('span', `: ${entry.message}`));
    return item;
  }));
}

export function confirmThen(text, warning, action) {
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
export function sendWarnings(members, count) {
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

export function sendTargets() {
  const members = team();
  if (!members.length) return notice('no team: click UAVs in the list to select them', false);
  if (!state.targets.length) return notice('no targets: click the map to add some', false);
  const targets = state.targets.map((t) => ({ lat: t.lat, lon: t.lon, alt: t.alt }));
  const sentZones = zonesToSend();
  const objective = $('#objective').value;
  const propose = proposing();
  const proposers = uavProposers();
  if (typeof proposers === 'string') return notice(proposers, false);
  const outside = proposers.filter((id) => !members.includes(id));
  if (outside.length) return notice(`UAV proposer ${outside.join(', ')} is not in the team: select it, or leave it out`, false);
  const by = [propose ? 'the ground' : '', proposers.length ? `UAV ${proposers.join(', ')}` : ''].filter(Boolean);
  const proposed = by.length ? `, ${by.join(' and ')} proposing a plan` : '';
  confirmThen(
    `Send ${targets.length} target(s) to the team of ${members.length} UAV(s): ${members.join(', ')} (objective ${objective}${proposed})?`,
    sendWarnings(members, targets.length).join(' '),
    () => command({
      cmd: 'send', team: members, targets, zones: sentZones, objective, propose, proposers,
    }, `Send ${targets.length} target(s) to ${members.join(', ')}${by.length ? ' (proposed plan)' : ''}`, (reply) => {
      if (reply.ok) sentAsMission(reply.mission, targets, sentZones);
    }),
  );
}

// A proposed plan is scored by the objective's key: the greedy has none.
export function proposing() {
  return $('#objective').value !== 'greedy' && $('#propose').checked;
}

export function onObjectiveChange() {
  const greedy = $('#objective').value === 'greedy';
  $('#propose').disabled = greedy;
  $('#proposers').disabled = greedy;
}

// The UAVs named in "UAV proposers" (`send-targets --proposers`): Piccolo IDs separated by
// commas or spaces, none for the greedy; a string says what is wrong with the field.
export function uavProposers() {
  if ($('#objective').value === 'greedy') return [];
  const words = $('#proposers').value.split(/[\s,]+/).filter(Boolean);
  const ids = [];
  for (const word of words) {
    const id = /^\d+$/.test(word) ? Number(word) : NaN;
    if (!(id >= 1 && id <= 0xFFF0)) return `UAV proposers: "${word}" is not a Piccolo ID (1-65520)`;
    if (!ids.includes(id)) ids.push(id);
  }
  return ids;
}

// The drafts added to the mission in flight, as `ground-cli add-targets` adds them: done
// only once every live UAV of its team acknowledged the new revision.
export function addToMission() {
  const m = state.mission;
  if (!m || m.aborted) return notice('no mission in flight to add targets to', false);
  if (!state.targets.length) return notice('no draft targets: click the map to add some', false);
  const targets = state.targets.map((t) => ({ lat: t.lat, lon: t.lon, alt: t.alt }));
  confirmThen(
    `Add ${targets.length} target(s) to mission ${m.mission} in flight (team ${m.team.join(', ')})?`,
    'They go after its targets (indexes never change) and are handed out to the team\'s queues.',
    () => command({ cmd: 'add-targets', mission: m.mission, targets },
      `Add ${targets.length} target(s) to mission ${m.mission}`, (reply) => {
        if (reply.ok) addedToMission(targets);
      }),
  );
}

function addedToMission(targets) {
  const same = (a, b) => a.length === b.length && a.every((t, i) => sameTarget(t, b[i]));
  if (same(state.targets, targets)) state.targets = [];
  render();
}

export function abortTeam() {
  const m = state.mission;
  if (!m) return notice('no mission to abort', false);
  confirmThen(`Abort mission ${m.mission} for its team ${m.team.join(', ')}?`,
    'Every UAV of the team leaves its target and resumes its course.',
    () => command({ cmd: 'abort', mission: m.mission }, `Abort mission ${m.mission}`));
}

// Drafts sent are a mission now: they leave the draft list (pressing Send again would send
// them twice), unless the operator changed them while the command was on its way. The
// mission's targets are on the map and in the Mission table, with their states.
function sentAsMission(mission, targets, sentZones) {
  if (mission !== null && mission !== undefined) state.ownMissions.add(mission);
  const same = (a, b) => a.length === b.length && a.every((t, i) => sameTarget(t, b[i]));
  if (same(state.targets, targets)) state.targets = [];
  if (JSON.stringify(zonesToSend()) === JSON.stringify(sentZones)) zones.draft = [];
  drawZoneList();
  render();
}
