// The WebSocket to the ground.
import { drawCommands, onAck, onReply, resendUnanswered } from './commands.js';
import { notice } from './helpers.js';
import { render } from './map.js';
import { $, state, withToken } from './state.js';
import { addStatuses } from './statuses.js';

// The followed mission is the latest the fleet has (the server follows it): drawn and
// listed as the mission, never copied into the operator's drafts.
export function onSnapshot(snapshot) {
  state.uavs = snapshot.uavs;
  state.mission = snapshot.mission;
  const m = snapshot.mission;
  if (m && m.mission !== state.seenMission) {
    state.seenMission = m.mission;
    if (!state.ownMissions.has(m.mission)) {
      notice(`following mission ${m.mission} (${m.targets.length} targets), sent by another ground`, true);
    }
  }
  // The server pins each UAV's warnings and errors until that UAV says they cleared.
  if (Array.isArray(snapshot.alerts)) {
    state.serverAlerts = true;
    state.alerts = snapshot.alerts.slice().reverse();
  }
  addStatuses(snapshot.statuses);
  render();
}

export function connect() {
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
    resendUnanswered();
  };
  ws.onclose = () => {
    if (state.ws !== ws) return;
    connection.dataset.state = 'closed';
    connection.textContent = 'disconnected: retrying';
    state.reconnects += 1;
    drawCommands();
    setTimeout(connect, 1000);
  };
  ws.onmessage = (event) => {
    const message = JSON.parse(event.data);
    if (message.type === 'snapshot') onSnapshot(message);
    else if (message.type === 'ack') onAck(message);
    else if (message.type === 'reply') onReply(message);
  };
}

// For tests and scripts: drop the socket as a loaded box does (the page opens it again and
// sends again what was not answered), and how often it dropped.
window.fleetPage = {
  dropConnection() {
    if (state.ws) state.ws.close();
  },
  reconnects: () => state.reconnects,
};
