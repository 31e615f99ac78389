// The status box: what the UAVs said, repeats counted, warnings kept in view.
import { clock, colourOf, html, liveIds } from './helpers.js';
import { $, state } from './state.js';

// ---- the status box -------------------------------------------------------------------------
export function addStatuses(entries) {
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

export function statusItem(entry) {
  const item = html('li', '', { 'data-severity': entry.severity, 'data-uav-status': entry.uav });
  item.append(html('span', `${clock(entry.time)} `, { class: 'time' }));
  const who = html('b', `UAV ${entry.uav} `);
  who.style.color = colourOf(entry.uav);
  item.append(who, html('span', `[${entry.severity}] `), html('span', entry.text));
  if (entry.count > 1) item.append(html('span', ` ×${entry.count}`, { class: 'count' }));
  return item;
}

export function drawStatuses() {
  const filter = $('#status-filter').value;
  const keep = (s) => filter === 'all' || String(s.uav) === filter;
  const log = $('#status-log');
  const atBottom = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
  log.replaceChildren(...state.statuses.filter(keep).slice(-300).map(statusItem));
  if (atBottom) log.scrollTop = log.scrollHeight;
  $('#alerts').replaceChildren(...state.alerts.filter(keep).map(statusItem));
}

export function updateFilter() {
  const select = $('#status-filter');
  const ids = new Set([...liveIds(), ...state.statuses.map((s) => s.uav)]);
  const have = new Set([...select.options].map((o) => o.value));
  for (const id of [...ids].sort((a, b) => a - b)) {
    if (!have.has(String(id))) select.appendChild(html('option', `UAV ${id}`, { value: String(id) }));
  }
}
